"""A second expert beside the tracker (``second_expert``, NRMLCTracker._output_of_the_experts)."""
from __future__ import annotations

import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.errors import ParameterError
from nrmlc.tracker.loop import track_sequence
from nrmlc.tracker.params import LINEAGE_MOTION_SIGMAS

# No floor: on a small synthetic target the floor makes the two motion models the same 4 px.
# One tracker unless a test names its second expert (the default has one since round 64).
SETTINGS = dict(n_particles=120, redetect_count=60, translation_floor=0.0, second_expert="off")


@pytest.fixture(scope="module")
def sequence():
    return SyntheticSequence(SyntheticSpec(name="e", seed=1, n_frames=30))


def _run(sequence, seed=0, **changes):
    return track_sequence(sequence, TrackerParams(**{**SETTINGS, **changes}), seed=seed)


@pytest.mark.parametrize("kind, memory", [("lineage_noise", 0.0), ("lineage_noise", 0.95), ("every_frame", 0.95)])
def test_the_output_is_the_expert_with_the_lower_average_error(sequence, kind, memory):
    """The oracle: the two experts run apart as single trackers, and the output chosen frame by
    frame from their boxes by the running average of eps_pos*."""
    pair = _run(sequence, second_expert=kind, expert_memory=memory)
    own = _run(sequence)
    partner = _run(sequence, **(dict(update_interval=1) if kind == "every_frame" else
                                dict(translation_noise="pixels", motion_sigmas=LINEAGE_MOTION_SIGMAS)))
    errors = np.stack([own.diagnostics["error_positive"], partner.diagnostics["error_positive"]], axis=1)
    average, chosen = np.zeros(2), [0]
    for row in errors[1:]:
        average = memory * average + (1 - memory) * row
        chosen.append(int(average[1] < average[0]))
    chosen = np.array(chosen)
    assert 0 < chosen[1:].sum() < len(chosen) - 1  # both experts are output on some frames
    expected = np.where(chosen[:, None] == 1, partner.boxes, own.boxes)
    np.testing.assert_array_equal(pair.boxes, expected)
    np.testing.assert_array_equal(pair.diagnostics["expert"][1:], chosen[1:])
    np.testing.assert_array_equal(pair.states, np.where(chosen[:, None] == 1, partner.states, own.states))
    np.testing.assert_array_equal(pair.diagnostics["error_positive"][1:],
                                  errors[np.arange(len(errors)), chosen][1:])


@pytest.mark.parametrize("gate", [0.02, 0.03])
def test_recency_outputs_the_expert_recognised_on_the_later_frame(gate):
    """The oracle: ``expert_choice = 'recency'`` from the two experts' single runs, the last frame
    each estimate was under the update gate compared, the average's choice where it is the same."""
    sequence = SyntheticSequence(SyntheticSpec(name="e", seed=2, n_frames=30))  # both experts fall off the gate
    changes = dict(update_error_threshold=gate)
    pair = _run(sequence, second_expert="every_frame", expert_choice="recency", **changes)
    own, partner = _run(sequence, **changes), _run(sequence, update_interval=1, **changes)
    errors = np.stack([own.diagnostics["error_positive"], partner.diagnostics["error_positive"]], axis=1)
    average, last, by_average, chosen = np.zeros(2), np.zeros(2), [0], [0]
    for frame, row in enumerate(errors[1:], start=1):
        average = 0.95 * average + 0.05 * row
        last[row < gate] = frame
        by_average.append(int(average[1] < average[0]))
        chosen.append(by_average[-1] if last[0] == last[1] else int(last[1] > last[0]))
    chosen = np.array(chosen)
    assert np.any(chosen != np.array(by_average))  # the rule decides some frame
    np.testing.assert_array_equal(pair.boxes, np.where(chosen[:, None] == 1, partner.boxes, own.boxes))
    np.testing.assert_array_equal(pair.diagnostics["expert"][1:], chosen[1:])


def test_off_is_one_tracker_and_the_partner_has_the_lineage_motion():
    assert NRMLCTracker(seed=0, second_expert="off").partner is None
    assert NRMLCTracker(seed=0).partner is not None  # the default's (round 64); the paper's has none
    assert TrackerParams.paper().second_expert == "off"
    params = TrackerParams(second_expert="lineage_noise")
    partner = params.partner_params()
    assert partner.second_expert == "off" and partner.translation_noise == "pixels"
    assert partner.motion_sigmas == LINEAGE_MOTION_SIGMAS
    assert partner.replace(translation_noise="relative", motion_sigmas=params.motion_sigmas,
                           second_expert="lineage_noise") == params
    assert params.estimated_bytes() == 2 * TrackerParams(second_expert="off").estimated_bytes()
    learner = TrackerParams(second_expert="every_frame").partner_params()
    assert learner == TrackerParams(update_interval=1, second_expert="off")


def test_move_to_moves_both_experts(sequence):
    tracker = NRMLCTracker(seed=0, **{**SETTINGS, "second_expert": "lineage_noise"})
    tracker.init(sequence.frame(0), sequence.init_box)
    tracker.update(sequence.frame(1))
    box = np.array([20.0, 15.0, 18.0, 14.0])
    tracker.move_to(box)
    np.testing.assert_array_equal(tracker.state, tracker.partner.state)


@pytest.mark.parametrize("changes, name", [(dict(second_expert="twin"), "second_expert"),
                                           (dict(expert_memory=1.0), "expert_memory"),
                                           (dict(expert_memory=-0.1), "expert_memory"),
                                           (dict(expert_choice="latest"), "expert_choice")])
def test_bad_values_name_the_parameter(changes, name):
    with pytest.raises(ParameterError, match=name):
        TrackerParams(**changes)
