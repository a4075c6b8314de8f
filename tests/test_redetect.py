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
from nrmlc.workbench.metrics import overlaps
from nrmlc.testing.scenes import jump_scene
from nrmlc.tracker.records import NO_POSITIVE_ERROR as REDETECT_TRIGGER
from nrmlc.tracker.redetect import needs_search

from experiments.instrumented import RecordingTracker

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
    tracker = RecordingTracker(seed=1, params=params)
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


def test_the_trigger_is_a_threshold_on_the_best_candidates_eps_pos():
    strict = TrackerParams.paper(redetect_count=300)
    assert strict.redetect_trigger == REDETECT_TRIGGER
    assert needs_search(strict, 1.0) and not needs_search(strict, 0.5)
    assert needs_search(TrackerParams(), 0.5) and not needs_search(TrackerParams(), 0.1)
    weak = TrackerParams(redetect_trigger=0.15)
    assert needs_search(weak, 0.15) and needs_search(weak, 0.2) and not needs_search(weak, 0.149)
    assert not needs_search(TrackerParams(redetect_count=0, redetect_trigger=0.15), 1.0)


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


def _searched_frame(frame_index: int, **changes):
    """A tracker one frame into the jump scene, the particles of frame ``frame_index`` and their
    coding, and a ``search(best_error)`` that runs the search as if the particles' best had that
    eps_pos*: returns (all states, their coding)."""
    import dataclasses

    from nrmlc.tracker.algorithm import as_gray_frame
    from nrmlc.tracker.redetect import search
    frames, truth = jump_scene(jump_frame=JUMP_FRAME)
    tracker = NRMLCTracker(seed=1, params=TrackerParams(n_particles=200, redetect_count=300, redetect_trigger=0.15,
                                                        redetect_accept=1.0, **changes))
    tracker.init(frames[0], truth[0])
    tracker.update(frames[1])
    states = tracker.sample_particles()
    frame = as_gray_frame(frames[frame_index])
    coding = tracker.encode(tracker.patches(frame, states))

    def searched(best_error: float):
        marked = dataclasses.replace(coding, error_positive=np.full_like(coding.error_positive, best_error))
        return search(tracker, frame, states, marked)
    return tracker, searched


def test_a_weakly_recognised_frame_counts_only_nearby_search_candidates():
    from nrmlc.geometry import state_to_box
    tracker, searched = _searched_frame(2, redetect_weak_radius=0.3, redetect_weak_accept=1.0)
    box = state_to_box(tracker.state, tracker.params.patch_size)
    reach = 0.3 * np.sqrt(box[2] * box[3])
    for best_error, limited in ((0.5, True), (1.0, False)):
        all_states, coded = searched(best_error)
        distance = np.hypot(*(all_states[200:, :2] - tracker.state[:2]).T)
        counted = np.isfinite(coded.log_confidence[200:])
        expected = coded.error_positive[200:] < 1.0
        if limited:
            expected &= distance <= reach
        assert np.array_equal(counted, expected)
        assert counted.any() and (distance[counted] > reach).any() != limited


def test_a_weakly_recognised_frame_takes_only_a_find_recognised_under_the_weak_acceptance():
    _, searched = _searched_frame(JUMP_FRAME, redetect_weak_radius=100.0, redetect_weak_accept=0.5)
    for best_error, weak in ((0.5, True), (1.0, False)):
        _, coded = searched(best_error)
        error = coded.error_positive[200:]
        counted = np.isfinite(coded.log_confidence[200:])
        assert np.array_equal(counted, error < (0.5 if weak else 1.0))
        assert ((error >= 0.5) & (error < 1.0)).any() and (error < 0.5).any()
