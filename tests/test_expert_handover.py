"""expert_handover (round 67): a lost expert draws its next particles around the other's recognised estimate."""
import dataclasses

import numpy as np
import pytest

from nrmlc import NRMLCTracker
from nrmlc.data import SyntheticSequence, SyntheticSpec


def _pair(handover: float) -> NRMLCTracker:
    sequence = SyntheticSequence(SyntheticSpec(name="h", seed=2, n_frames=3))
    tracker = NRMLCTracker(seed=0, n_particles=40, expert_handover=handover)
    tracker.init(sequence.raw_frame(0), sequence.init_box)
    tracker.update(sequence.raw_frame(1))
    return tracker


@pytest.mark.parametrize("lost_error, moves", [(0.6, True), (0.4, False)])
def test_the_lost_expert_takes_the_recognised_estimate(lost_error, moves):
    tracker = _pair(0.5)
    partner = tracker.partner
    moved = partner.last.state + np.array([3.0, -2.0, 0.1, 0.0, 0.0, 0.0])
    recognised = dataclasses.replace(partner.last, state=moved, error_positive=0.01, occluded=False)
    lost = dataclasses.replace(tracker.last, error_positive=lost_error)
    own_state = tracker.state.copy()
    tracker._hand_over(lost, recognised)
    if moves:
        np.testing.assert_array_equal(tracker.state, moved)
        assert tracker.particles is None and partner.particles is not None
    else:
        np.testing.assert_array_equal(tracker.state, own_state)


def test_an_occluded_estimate_gives_nothing_and_the_other_way_round_works():
    tracker = _pair(0.5)
    partner_state = tracker.partner.state.copy()
    occluded = dataclasses.replace(tracker.last, error_positive=0.01, occluded=True)
    lost = dataclasses.replace(tracker.partner.last, error_positive=1.0)
    tracker._hand_over(occluded, lost)
    np.testing.assert_array_equal(tracker.partner.state, partner_state)
    clear = dataclasses.replace(occluded, occluded=False, state=occluded.state + 1.0)
    tracker._hand_over(clear, lost)
    np.testing.assert_array_equal(tracker.partner.state, clear.state)


def test_off_by_default():
    assert NRMLCTracker(seed=0).params.expert_handover == 1.0
