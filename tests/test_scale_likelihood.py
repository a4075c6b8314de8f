"""experiments.paper.scale_likelihood: the probe leaves tracking alone, the measures count what they say."""
from __future__ import annotations

import json

import numpy as np
import pytest

from experiments.paper import scale_likelihood
from experiments.grid import Context, run_script
from experiments.paper.scale_likelihood import SCALES, ScaleProfile, profile_measures
from nrmlc.data import SyntheticSequence, SyntheticSpec, synthetic_suite
from nrmlc.workbench.run_cache import RunCache
from nrmlc.tracker import track_sequence
from nrmlc.tracker.params import TrackerParams

PARAMS = TrackerParams(n_particles=80)
UNIT = SCALES.index(1.0)


def test_probing_the_scales_leaves_the_boxes_unchanged():
    sequence = SyntheticSequence(SyntheticSpec(name="probe", seed=5, n_frames=25))
    profile = ScaleProfile(sequence, PARAMS, seed=2).execute()
    plain = track_sequence(sequence, PARAMS, seed=2)
    np.testing.assert_array_equal(profile["boxes"], plain.boxes)
    assert profile["frames"].tolist() == list(range(1, 25))
    assert profile["error_positive"].shape == profile["error_negative"].shape == (24, len(SCALES))


def _profile(margins, frames, on_target):
    """A hand-made profile: eps_neg - eps_pos = ``margins``; boxes on or off the truth."""
    frames = np.asarray(frames)
    truth = np.tile([10.0, 10.0, 20.0, 40.0], (frames.max() + 1, 1))
    boxes = truth.copy()
    boxes[frames[~np.asarray(on_target)], 0] += 100.0  # IoU 0: not counted
    boxes[:, 2:] *= 1.2  # the tracker's box 1.2 times the truth's side (IoU 0.69: on target)
    boxes[frames[~np.asarray(on_target)], 2:] = truth[0, 2:]
    margins = np.asarray(margins, dtype=np.float64)
    return {"boxes": boxes, "frames": frames, "error_positive": np.zeros_like(margins),
            "error_negative": margins}, truth


def test_profile_measures_count_shares_margins_and_periods():
    smaller = np.zeros(len(SCALES))
    smaller[UNIT - 1] = 0.3  # 0.9 wins
    truth_wins = np.zeros(len(SCALES))
    truth_wins[UNIT] = 0.2
    frames = [5, 6, 7, 40, 41]
    profile, truth = _profile([smaller, truth_wins, smaller, truth_wins, smaller], frames,
                              [True, True, False, True, True])
    out = profile_measures(profile, truth)
    early, later = out["early"], out["later"]
    assert early["frames"] == 2 and later["frames"] == 2  # frame 7 is off the target
    assert early["smaller"] == pytest.approx(0.5) and early["truth"] == pytest.approx(0.5)
    assert early["larger"] == 0.0
    assert early["margin"][UNIT] == 0.0
    assert early["margin"][UNIT - 1] == pytest.approx((0.3 + (0.0 - 0.2)) / 2)
    # The hand-made profile puts the whole margin in eps_neg (eps_pos = 0).
    assert early["error_negative"] == pytest.approx(early["margin"]) and early["error_positive"] == [0.0] * len(SCALES)
    assert out["tracked_scale"] == pytest.approx(1.2)


def test_profile_measures_without_a_counted_frame():
    profile, truth = _profile([np.zeros(len(SCALES))], [3], [False])
    out = profile_measures(profile, truth)
    assert out["early"] == {"frames": 0} and out["later"] == {"frames": 0}
    assert out["tracked_scale"] is None


def test_script_writes_its_outputs(tmp_path):
    sequences = synthetic_suite(n_frames=40, size=(120, 160), n_sequences=2)
    context = Context(figures_dir=tmp_path / "figures", cache=RunCache(tmp_path / "runs"), jobs=1, seeds=(0,),
                      sweep_seeds=(0,), _sequences=sequences, base_params=PARAMS)
    out = run_script(scale_likelihood, context)
    assert out["figures"] == ["scale_likelihood.png"] and out["markdown"].startswith("### ")
    assert (tmp_path / "figures" / "scale_likelihood.png").stat().st_size > 0
    data = json.loads((tmp_path / "figures" / "scale_likelihood.json").read_text())
    assert [row["sequence"] for row in data["sequences"]] == [s.name for s in sequences]
    later = data["summary"]["later"]
    assert later["frames"] > 0 and sum(later["best_share"]) == pytest.approx(1.0)


def test_summary_correlates_the_lean_with_the_drift():
    def row(larger, smaller, scale):
        zeros = [0.0] * len(SCALES)
        later = {"frames": 30, "margin": zeros, "error_positive": zeros, "error_negative": zeros, "best_share": zeros,
                 "smaller": smaller, "truth": 1 - larger - smaller, "larger": larger}
        return {"early": {"frames": 0}, "later": later, "tracked_scale": scale}

    leaning = scale_likelihood.summary([row(0.6, 0.1, 1.2), row(0.1, 0.7, 0.8), row(0.3, 0.3, 1.0)])
    assert leaning["lean_and_drift"]["later"] == {"sequences": 3, "pearson_r": pytest.approx(1.0, abs=0.02)}
    assert leaning["lean_and_drift"]["early"] == {"sequences": 0, "pearson_r": None}
    assert leaning["later"]["smaller_beats_truth"] == 1
    against = scale_likelihood.summary([row(0.6, 0.1, 0.8), row(0.1, 0.7, 1.2), row(0.3, 0.3, 1.0)])
    assert against["lean_and_drift"]["later"]["pearson_r"] == pytest.approx(-1.0, abs=0.02)
    assert scale_likelihood.summary([row(0.6, 0.1, 1.2)])["lean_and_drift"]["later"]["pearson_r"] is None
