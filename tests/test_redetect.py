"""Re-detection (``redetect_count``): when it runs, which of its candidates count, and that it
recovers a jump the motion model cannot follow; bit-identical across thread counts."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.metrics import overlaps
from nrmlc.testing.scenes import jump_scene
from nrmlc.tracker.redetect import REDETECT_TRIGGER, needs_search, quiet_find_kept, quiet_search

REPO_ROOT = Path(__file__).resolve().parent.parent
JUMP_FRAME = 4


def _track(seed: int, **changes) -> tuple[np.ndarray, list]:
    """IoU per frame of the jump scene, and the tracker's FrameResult per frame (None for frame 0)."""
    frames, truth = jump_scene(jump_frame=JUMP_FRAME)
    tracker = NRMLCTracker(seed=seed, **changes)
    tracker.init(frames[0], truth[0])
    boxes, results = [truth[0]], [None]
    for frame in frames[1:]:
        boxes.append(tracker.update(frame))
        results.append(tracker.last)
    return overlaps(np.array(boxes), truth), results


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_redetection_recovers_a_jump_the_motion_model_cannot_follow(seed):
    # Without the pixel floor: its 4 px reach this small scene's jump in a frame or two.
    with_search, results = _track(seed, translation_floor=0.0)
    without, plain_results = _track(seed, redetect_count=0, translation_floor=0.0)
    # Without it the cloud is still crawling towards the target a frame after the jump.
    assert without[JUMP_FRAME:JUMP_FRAME + 2].max() < 0.55
    assert not any(r.redetect_searched for r in plain_results[1:])
    # With it the target is found again at once, and kept.
    assert with_search[JUMP_FRAME + 1:].min() > 0.85
    redetected = [i for i, r in enumerate(results) if r is not None and r.redetected]
    assert redetected and redetected[0] in (JUMP_FRAME, JUMP_FRAME + 1)
    # Before the jump the positives hold the target: no search (test below: what triggers it).
    assert not any(r.redetect_searched for r in results[1:JUMP_FRAME])


def test_only_confident_redetection_candidates_carry_weight():
    frames, truth = jump_scene(jump_frame=JUMP_FRAME)
    params = TrackerParams(n_particles=200, redetect_count=150, redetect_accept=0.3)
    tracker = NRMLCTracker(seed=1, params=params)
    tracker.init(frames[0], truth[0])
    for frame in frames[1:JUMP_FRAME + 1]:
        tracker.update(frame)
    assert tracker.last.redetect_searched
    coded = tracker.last_coding
    assert len(coded) == len(tracker.particles) == 350
    # The frame's own particles: their best has no positive in its code, so it triggered.
    local = coded.log_confidence[:200]
    assert coded.error_positive[int(np.argmax(local))] >= REDETECT_TRIGGER
    extra_error = coded.error_positive[200:]
    extra_log = coded.log_confidence[200:]
    assert np.all(np.isneginf(extra_log[extra_error >= 0.3]))
    assert np.all(np.isfinite(extra_log[extra_error < 0.3]))
    # The next frame resamples n_particles from all 350; the refused ones have no weight.
    weights = np.exp(tracker.log_weights - tracker.log_weights.max())
    assert np.all(weights[200:][extra_error >= 0.3] == 0) and weights[:200].sum() > 0
    assert tracker.sample_particles().shape == (200, 6)


def test_the_negative_trigger_also_searches_where_the_best_looks_like_the_negatives():
    plain, negative = TrackerParams(), TrackerParams(redetect_trigger="negative")
    assert plain.redetect_trigger == "no_positive"
    # A captured box: the positives take part (eps_pos* 0.45) but the negatives code it better.
    assert not needs_search(plain, 0.45, 0.2) and needs_search(negative, 0.45, 0.2)
    # A recognised target, and a frame whose code uses no positive: the same under both.
    assert not needs_search(negative, 0.05, 0.9) and not needs_search(plain, 0.05, 0.9)
    assert needs_search(plain, 1.0, 1.0) and needs_search(negative, 1.0, 1.0)
    assert not needs_search(TrackerParams(redetect_trigger="negative", redetect_count=0), 0.45, 0.2)
    after = TrackerParams(redetect_trigger="negative_after_recognised")
    # Only a sudden loss: the frame before was recognised (eps_pos* under the update threshold).
    assert needs_search(after, 0.45, 0.2, previous_error_positive=0.02)
    assert not needs_search(after, 0.45, 0.2, previous_error_positive=0.4)
    assert needs_search(after, 1.0, 1.0, previous_error_positive=0.4)
    quiet = TrackerParams(redetect_trigger="negative_after_recognised_quiet")
    assert needs_search(quiet, 0.45, 0.2, previous_error_positive=0.02)
    assert not needs_search(quiet, 0.45, 0.2, previous_error_positive=0.4)
    # Quiet only where the default's trigger would not have searched.
    assert quiet_search(quiet, 0.45) and not quiet_search(quiet, 1.0) and not quiet_search(after, 0.45)
    strict = TrackerParams(redetect_trigger="negative_after_recognised_quiet_strict")
    assert quiet_search(strict, 0.45) and not quiet_search(strict, 1.0)
    # The strict form keeps only a find recognised as well as a result that joins the positives.
    assert quiet_find_kept(quiet, 0.23) and not quiet_find_kept(strict, 0.23)
    assert quiet_find_kept(strict, 0.05)


def test_paper_preset_has_no_redetection():
    assert TrackerParams.paper().redetect_count == 0
    assert TrackerParams().redetect_count > 0


_CHILD = r"""
import sys
from nrmlc.config import set_threads
n_threads = set_threads(int(sys.argv[1]))
import numpy as np
from nrmlc import NRMLCTracker
from nrmlc.testing.scenes import jump_scene
frames, truth = jump_scene()
tracker = NRMLCTracker(seed=2, n_negative=150)  # 150 negatives: this scene then has frames that search
tracker.init(frames[0], truth[0])
boxes, searched = [], 0
for frame in frames[1:]:
    boxes.append(tracker.update(frame))
    searched += tracker.last.redetect_searched
print(n_threads, searched, np.array(boxes).tobytes().hex())
"""


def test_redetection_is_bit_identical_with_one_or_two_threads():
    outputs = []
    for n_threads in (1, 2):
        env = dict(os.environ, NUMBA_NUM_THREADS=str(n_threads), OPENBLAS_NUM_THREADS=str(n_threads),
                   OMP_NUM_THREADS=str(n_threads))
        run = subprocess.run([sys.executable, "-c", _CHILD, str(n_threads)], env=env, cwd=str(REPO_ROOT),
                             capture_output=True, text=True, check=True, timeout=600)
        outputs.append(run.stdout.split())
    assert [o[0] for o in outputs] == ["1", "2"]
    assert int(outputs[0][1]) > 0  # the search ran
    assert outputs[0][2] == outputs[1][2]


def test_the_whole_frame_search_joins_only_after_the_target_went_unrecognised():
    frames, truth = jump_scene(jump_frame=JUMP_FRAME)
    params = TrackerParams(n_particles=200, redetect_count=150, redetect_global=40, redetect_global_after=0)
    tracker = NRMLCTracker(seed=1, params=params)
    tracker.init(frames[0], truth[0])
    for frame in frames[1:JUMP_FRAME + 1]:
        tracker.update(frame)
    assert tracker.last.redetect_searched
    # redetect_global_after = 0: the search of the jump frame carries the whole-frame candidates.
    assert len(tracker.last_coding) == 200 + 150 + 40
    later = NRMLCTracker(seed=1, params=params.replace(redetect_global_after=1000))
    later.init(frames[0], truth[0])
    for frame in frames[1:JUMP_FRAME + 1]:
        later.update(frame)
    assert later.last.redetect_searched and len(later.last_coding) == 200 + 150
