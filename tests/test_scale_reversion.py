"""scale_reversion (round 65): particles' log scale moves toward the last recognised estimate's."""
import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec

NO_NOISE = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def _tracker(reversion: float) -> NRMLCTracker:
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=3))
    tracker = NRMLCTracker(seed=0, n_particles=30, motion_sigmas=NO_NOISE, translation_floor=0.0,
                           propagation="best", scale_reversion=reversion, second_expert="off")
    tracker.init(sequence.raw_frame(0), sequence.init_box)
    return tracker


@pytest.mark.parametrize("reversion", [0.0, 0.25, 1.0])
def test_particles_close_the_given_share_of_the_log_scale_gap(reversion):
    tracker = _tracker(reversion)
    reference = tracker.scale_reference
    assert reference == tracker.state[2]
    tracker.state[2] = reference * 0.5  # a box shrunk to half the recognised scale
    states = tracker.sample_particles()
    expected = np.log(0.5) * (1.0 - reversion)  # naive oracle in log scale
    np.testing.assert_allclose(np.log(states[:, 2] / reference), expected, atol=1e-12)


def test_the_reference_follows_recognised_estimates_only():
    tracker = _tracker(0.1)
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=3))
    tracker.update(sequence.raw_frame(1))
    recognised = not tracker.last.occluded and tracker.last.error_positive < tracker.params.update_error_threshold
    assert recognised  # the synthetic target is recognised on its second frame
    assert tracker.scale_reference == tracker.state[2]
    before = tracker.scale_reference
    tracker.params = tracker.params.replace(update_error_threshold=0.0)  # nothing is recognised now
    tracker.state[2] *= 0.9
    tracker.update(sequence.raw_frame(2))
    assert tracker.scale_reference == before


def test_off_in_the_paper_preset_and_by_default():
    assert TrackerParams.paper().scale_reversion == 0.0 and TrackerParams().scale_reversion == 0.0


def test_the_lost_gate_holds_the_anchor_until_the_average_error_reaches_it():
    tracker = _tracker(0.5)
    tracker.params = tracker.params.replace(scale_reversion_lost=0.4)
    reference = tracker.scale_reference
    tracker.state[2] = reference * 0.5
    tracker.error_average = 0.39  # below the gate: no anchor
    np.testing.assert_allclose(tracker.sample_particles()[:, 2], reference * 0.5, rtol=1e-12)
    tracker.error_average = 0.4  # at the gate: the anchor moves half the log gap
    np.testing.assert_allclose(np.log(tracker.sample_particles()[:, 2] / reference), np.log(0.5) * 0.5, atol=1e-12)


def test_the_average_error_follows_eps_pos_with_the_lost_memory():
    from nrmlc.tracker.algorithm import LOST_MEMORY
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=4))
    tracker = _tracker(0.0)
    expected = 0.0
    for index in range(1, 4):
        tracker.update(sequence.raw_frame(index))
        expected = LOST_MEMORY * expected + (1 - LOST_MEMORY) * tracker.last.error_positive
        assert tracker.error_average == pytest.approx(expected, abs=1e-15)
    assert expected > 0


def test_a_looser_reference_threshold_moves_the_reference_where_the_gate_does_not():
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=3))
    strict = _tracker(0.1)
    strict.params = strict.params.replace(update_error_threshold=1e-9)
    loose = _tracker(0.1)
    loose.params = loose.params.replace(update_error_threshold=1e-9, scale_reference_threshold=1.0)
    for tracker in (strict, loose):
        tracker.update(sequence.raw_frame(1))
    assert not strict.last.occluded and strict.scale_reference_frame == 0
    assert loose.scale_reference_frame == 1 and loose.scale_reference == loose.state[2]
