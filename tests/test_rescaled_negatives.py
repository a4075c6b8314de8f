"""shrunk_negatives and grown_negatives: shares of the negatives are boxes inside the target, or
holding it with a ring of background (round 22)."""
import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.errors import ParameterError
from nrmlc.tracker.templates import GROWN_NEGATIVE_SCALES, SHRUNK_NEGATIVE_SCALES, rescale_negatives


def test_rescale_negatives_replaces_the_last_rows_with_boxes_about_the_target():
    rng = np.random.default_rng(0)
    target = np.array([50.0, 40.0, 1.5, 0.0, 0.8, 0.0])
    others = np.tile(target, (10, 1))
    others[:, 0] += 100.0  # far away: easy to tell apart from the rescaled rows
    states = rescale_negatives(rng, others.copy(), target, 0.3, 0.2, 1.0)
    np.testing.assert_array_equal(states[:5], others[:5])
    for rows, (low, high) in ((states[7:], SHRUNK_NEGATIVE_SCALES), (states[5:7], GROWN_NEGATIVE_SCALES)):
        assert np.all(np.abs(rows[:, 0:2] - target[0:2]) < 6.0)  # 6 sigma of the 1 px jitter
        assert np.all((rows[:, 2] >= low * target[2]) & (rows[:, 2] <= high * target[2]))
        np.testing.assert_array_equal(rows[:, 3:], np.tile(target[3:], (len(rows), 1)))
    np.testing.assert_array_equal(rescale_negatives(rng, others.copy(), target, 0.04, 0.0, 1.0), others)  # rounds to 0


def _tracker(**changes) -> NRMLCTracker:
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=2))
    tracker = NRMLCTracker(seed=0, n_particles=30, **changes)
    tracker.init(sequence.raw_frame(0), sequence.init_box)
    return tracker


def test_the_negatives_change_only_where_switched_on():
    off, on = _tracker(), _tracker(shrunk_negatives=0.1, grown_negatives=0.1)
    n_rescaled = 2 * int(round(0.1 * TrackerParams().n_negative))
    rescaled, kept = on.negative_templates[-n_rescaled:], on.negative_templates[:-n_rescaled]
    # The other negatives are drawn as without the switches (the generator's draws come after).
    np.testing.assert_array_equal(kept, off.negative_templates[:-n_rescaled])
    assert not np.allclose(rescaled, off.negative_templates[-n_rescaled:])
    np.testing.assert_array_equal(on.positive_templates, off.positive_templates)


def test_off_by_default_and_in_the_paper_preset_and_the_shares_are_checked():
    for params in (TrackerParams(), TrackerParams.paper()):
        assert params.shrunk_negatives == 0.0 and params.grown_negatives == 0.0
    with pytest.raises(ParameterError, match="grown_negatives"):
        TrackerParams(shrunk_negatives=0.6, grown_negatives=0.5)
