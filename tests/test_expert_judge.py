"""expert_judge (round 69): each expert's estimate judged also on the other expert's templates."""
import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec


def test_own_by_default_and_one_tracker_in_the_paper_preset():
    assert TrackerParams().expert_judge == "own"
    assert TrackerParams.paper().second_expert == "off"


def test_positive_errors_are_those_of_encode():
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=2, n_frames=3))
    tracker = NRMLCTracker(seed=0, n_particles=40, second_expert="off")
    tracker.init(sequence.raw_frame(0), sequence.init_box)
    tracker.update(sequence.raw_frame(1))
    patches = tracker.patches(tracker.levelled_frame, tracker.particles[:7])
    np.testing.assert_array_equal(tracker.positive_errors(patches), tracker.encode(patches).error_positive)


def test_cross_averages_each_estimates_own_and_other_templates_error():
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=4, n_frames=8))
    cross = NRMLCTracker(seed=1, n_particles=60, expert_judge="cross")
    own = NRMLCTracker(seed=1, n_particles=60)
    for tracker in (cross, own):
        tracker.init(sequence.raw_frame(0), sequence.init_box)
    memory = cross.params.expert_memory
    average = np.zeros(2)
    moved = False
    for index in range(1, 8):
        before = own.expert_errors.copy()
        for tracker in (cross, own):
            tracker.update(sequence.raw_frame(index))
        partner = cross.partner
        # The choice changes only what is reported: the experts' estimates are those of the plain pair.
        np.testing.assert_array_equal(cross.state, own.state)
        np.testing.assert_array_equal(partner.state, own.partner.state)
        self_errors = (own.expert_errors - memory * before) / (1 - memory)  # each on its own templates
        patches = cross.patches(cross.levelled_frame, np.stack([cross.state, partner.state]))
        other = np.array([partner.encode(patches[:1]).error_positive[0],  # naive oracle: the full coding
                          cross.encode(patches[1:]).error_positive[0]])
        average = memory * average + (1 - memory) * 0.5 * (self_errors + other)
        np.testing.assert_allclose(cross.expert_errors, average, rtol=0, atol=1e-9)
        assert cross.last.expert == int(average[1] < average[0])
        moved |= not np.allclose(cross.expert_errors, own.expert_errors)
    assert moved  # the other templates' terms moved the averages on this sequence
