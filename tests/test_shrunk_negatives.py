"""shrunk_negatives: a share of the negatives are boxes inside the target (round 22)."""
import numpy as np

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.tracker.templates import SHRUNK_NEGATIVE_SCALES, shrink_states


def test_shrink_states_replaces_the_last_rows_with_boxes_inside_the_target():
    rng = np.random.default_rng(0)
    target = np.array([50.0, 40.0, 1.5, 0.0, 0.8, 0.0])
    others = np.tile(target, (10, 1))
    others[:, 0] += 100.0  # far away: easy to tell apart from the shrunk rows
    states = shrink_states(rng, others.copy(), target, 0.3, 1.0)
    np.testing.assert_array_equal(states[:7], others[:7])
    shrunk = states[7:]
    assert np.all(np.abs(shrunk[:, 0:2] - target[0:2]) < 6.0)  # 6 sigma of the 1 px jitter
    low, high = SHRUNK_NEGATIVE_SCALES
    assert np.all((shrunk[:, 2] >= low * target[2]) & (shrunk[:, 2] <= high * target[2]))
    np.testing.assert_array_equal(shrunk[:, 3:], np.tile(target[3:], (3, 1)))
    np.testing.assert_array_equal(shrink_states(rng, others.copy(), target, 0.04, 1.0), others)  # rounds to 0


def _tracker(share: float) -> NRMLCTracker:
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=2))
    tracker = NRMLCTracker(seed=0, n_particles=30, shrunk_negatives=share)
    tracker.init(sequence.raw_frame(0), sequence.init_box)
    return tracker


def test_the_negatives_hold_the_targets_inside_only_when_switched_on():
    off, on = _tracker(0.0), _tracker(0.2)
    n_shrunk = int(round(0.2 * TrackerParams().n_negative))
    shrunk, kept = on.negative_templates[-n_shrunk:], on.negative_templates[:-n_shrunk]
    # The first n - n_shrunk negatives are drawn as without the switch (same generator state).
    np.testing.assert_array_equal(kept, off.negative_templates[:-n_shrunk])
    assert not np.allclose(shrunk, off.negative_templates[-n_shrunk:])


def test_off_by_default_and_in_the_paper_preset():
    assert TrackerParams().shrunk_negatives == 0.0 and TrackerParams.paper().shrunk_negatives == 0.0
