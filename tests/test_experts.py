"""The pair of experts (``second_expert``, nrmlc.tracker.experts.ExpertPair)."""
from __future__ import annotations

import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.errors import ParameterError
from nrmlc.geometry import box_iou
from nrmlc.workbench.metrics import overlaps
from nrmlc.tracker.experts import ExpertPair, blend_experts, experts_output, held_size, make_tracker
from nrmlc.tracker.loop import track_sequence

# No floor: on a small synthetic target the floor makes the two motion models the same 4 px.
# One tracker unless a test names its second expert; the output the chosen expert's box unless a
# test names the blend or the held size.
SETTINGS = dict(n_particles=120, redetect_count=60, translation_floor=0.0, second_expert="off",
                expert_blend_iou=1.0, unrecognised_size_share=0.0)
#: What the default's second expert sees.
PARTNER_EYES = TrackerParams().partner_eyes


@pytest.fixture(scope="module")
def sequence():
    return SyntheticSequence(SyntheticSpec(name="e", seed=1, n_frames=30))


def _run(sequence, seed=0, **changes):
    return track_sequence(sequence, TrackerParams(**{**SETTINGS, **changes}), seed=seed)


@pytest.mark.parametrize("kind, memory", [("every_frame", 0.0), ("every_frame", 0.95)])
def test_the_output_is_the_expert_with_the_lower_average_error(sequence, kind, memory):
    """The oracle: the two experts run apart as single trackers, and the output chosen frame by
    frame from their boxes by the running average of eps_pos*."""
    pair = _run(sequence, second_expert=kind, expert_memory=memory)
    own = _run(sequence)
    partner = _run(sequence, update_interval=1, eyes=PARTNER_EYES)
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


def _chosen(errors, memory):
    average, chosen = np.zeros(2), [0]
    for row in errors[1:]:
        average = memory * average + (1 - memory) * row
        chosen.append(int(average[1] < average[0]))
    return np.array(chosen)


@pytest.mark.parametrize("min_iou", [0.5, 0.85])
def test_where_the_experts_agree_the_output_is_their_blend(sequence, min_iou):
    """The oracle: the two experts run apart; on each frame whose two boxes overlap at IoU >=
    min_iou, the centre is the mean of theirs and the size their geometric mean, weighted by the
    other's eps_pos*; elsewhere the chosen one's box."""
    pair = _run(sequence, second_expert="every_frame", expert_blend_iou=min_iou)
    own, partner = _run(sequence), _run(sequence, update_interval=1, eyes=PARTNER_EYES)
    errors = np.stack([own.diagnostics["error_positive"], partner.diagnostics["error_positive"]], axis=1)
    chosen = _chosen(errors, 0.95)
    expected = np.where(chosen[:, None] == 1, partner.boxes, own.boxes)
    iou = overlaps(own.boxes, partner.boxes)
    blended = (iou >= min_iou) & (np.arange(len(iou)) > 0)
    assert blended.any() and (min_iou < 0.8 or not blended[1:].all())  # at 0.85 some frames are not blended
    weight = errors[:, 0] / errors.sum(axis=1)  # the partner's
    centres = (1 - weight)[:, None] * (own.boxes[:, :2] + own.boxes[:, 2:] / 2) + \
        weight[:, None] * (partner.boxes[:, :2] + partner.boxes[:, 2:] / 2)
    sizes = own.boxes[:, 2:] ** (1 - weight)[:, None] * partner.boxes[:, 2:] ** weight[:, None]
    expected[blended] = np.concatenate([centres - sizes / 2, sizes], axis=1)[blended]
    np.testing.assert_allclose(pair.boxes, expected, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(pair.boxes[~blended], expected[~blended])  # the choice, to the bit
    np.testing.assert_array_equal(pair.diagnostics["expert"][1:], chosen[1:])
    np.testing.assert_allclose(pair.states[blended][:, [0, 1, 2, 4]],
                               np.stack([centres[:, 0] - 1, centres[:, 1] - 1, sizes[:, 0] / 32,
                                         sizes[:, 1] / sizes[:, 0]], axis=1)[blended], atol=1e-9)


def test_the_blend_weighs_the_better_recognised_expert_more():
    boxes = np.array([[10.0, 20.0, 40.0, 20.0], [14.0, 20.0, 10.0, 20.0]])
    np.testing.assert_allclose(blend_experts(boxes, np.array([0.0, 0.3]), 0.0), boxes[0])  # own exact
    np.testing.assert_allclose(blend_experts(boxes, np.array([0.3, 0.0]), 0.0), boxes[1])
    # Both exact: one half each; centres (30, 30) and (19, 30), sizes 40 x 20 and 10 x 20.
    np.testing.assert_allclose(blend_experts(boxes, np.array([0.0, 0.0]), 0.0), [14.5, 20.0, 20.0, 20.0])
    # eps_pos* 0.1 and 0.3: the partner's weight 0.25.
    np.testing.assert_allclose(blend_experts(boxes, np.array([0.1, 0.3]), 0.25)[[0, 2]],
                               [27.25 - 40 ** 0.75 * 10 ** 0.25 / 2, 40 ** 0.75 * 10 ** 0.25])
    assert blend_experts(boxes, np.array([0.1, 0.1]), 0.9) is None  # IoU 0.25 < 0.9
    assert blend_experts(boxes, np.array([0.1, 0.1]), 1.0) is None  # 1: never, even for one box
    assert blend_experts(boxes[[0, 0]], np.array([0.1, 0.1]), 1.0) is None


@pytest.mark.parametrize("share", [0.7, 1.0])
def test_where_neither_expert_recognises_the_size_moves_toward_the_last_recognised(sequence, share):
    """The oracle: the two experts run apart; on a frame where both eps_pos* reach the gate, the
    output keeps the blend's (or the choice's) centre and its log size moves ``share`` of the way
    to that of the last output whose frame was recognised. The gate is set inside this
    short sequence's range of eps_pos* so that both kinds of frame occur."""
    own, partner = _run(sequence), _run(sequence, update_interval=1, eyes=PARTNER_EYES)
    errors = np.stack([own.diagnostics["error_positive"], partner.diagnostics["error_positive"]], axis=1)
    gate = float(np.median(errors[1:].min(axis=1)))
    pair = _run(sequence, second_expert="every_frame", expert_blend_iou=0.5, unrecognised_size_share=share,
                unrecognised_gate=gate)
    blend = _run(sequence, second_expert="every_frame", expert_blend_iou=0.5)  # the output without the held size
    recognised = errors.min(axis=1) < gate
    assert recognised[1:].any() and not recognised[1:].all()
    reference = np.log(blend.boxes[0, 2:])
    expected = blend.boxes.copy()
    for index in range(1, len(expected)):
        log_size = np.log(blend.boxes[index, 2:])
        if recognised[index]:
            reference = log_size
            continue
        size = np.exp((1 - share) * log_size + share * reference)
        centre = blend.boxes[index, :2] + blend.boxes[index, 2:] / 2
        expected[index] = np.concatenate([centre - size / 2, size])
    np.testing.assert_allclose(pair.boxes, expected, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(pair.boxes[recognised], blend.boxes[recognised])  # to the bit
    assert np.abs(pair.boxes[~recognised][:, 2:] - blend.boxes[~recognised][:, 2:]).max() > 0.01
    np.testing.assert_allclose(pair.states[~recognised][:, [0, 1, 2]],
                               np.stack([pair.boxes[:, 0] + pair.boxes[:, 2] / 2 - 1,
                                         pair.boxes[:, 1] + pair.boxes[:, 3] / 2 - 1,
                                         pair.boxes[:, 2] / 32], axis=1)[~recognised], atol=1e-9)


def test_the_held_size_keeps_the_centre():
    box = np.array([10.0, 20.0, 40.0, 10.0])  # centre (30, 25)
    recognised = np.log([20.0, 40.0])
    np.testing.assert_allclose(held_size(box, recognised, 0.0), box)  # the tracker skips it at 0
    np.testing.assert_allclose(held_size(box, recognised, 1.0), [20.0, 5.0, 20.0, 40.0])
    width = (40.0 * 20.0) ** 0.5  # the geometric means: width sqrt(40 * 20), height sqrt(10 * 40) = 20
    np.testing.assert_allclose(held_size(box, recognised, 0.5), [30 - width / 2, 15.0, width, 20.0])


def test_the_experts_output_reports_the_choice_the_blend_or_the_held_size():
    apart = np.array([[0.0, 0.0, 10.0, 10.0], [50.0, 50.0, 20.0, 20.0]])  # IoU 0: no blend
    last = np.log([40.0, 40.0])
    params = TrackerParams(expert_blend_iou=0.5, unrecognised_gate=0.15, unrecognised_size_share=0.5)
    box, size, moved = experts_output(apart, np.array([0.3, 0.1]), 1, last, params)
    assert not moved and np.array_equal(box, apart[1])  # recognised: the chosen box, its size remembered
    np.testing.assert_allclose(size, np.log([20.0, 20.0]))
    box, size, moved = experts_output(apart, np.array([0.3, 0.2]), 0, last, params)
    assert moved and np.array_equal(size, last)  # neither recognises: held half way, centre kept
    np.testing.assert_allclose(box, [5.0 - 10.0, 5.0 - 10.0, 20.0, 20.0])
    box, size, moved = experts_output(apart, np.array([0.3, 0.2]), 0, last, params.replace(unrecognised_size_share=0.0))
    assert not moved and np.array_equal(box, apart[0]) and np.array_equal(size, last)
    close = np.array([[0.0, 0.0, 10.0, 10.0], [1.0, 0.0, 10.0, 10.0]])  # IoU 9/11: the blend
    box, size, moved = experts_output(close, np.array([0.1, 0.1]), 0, last, params)
    assert moved
    np.testing.assert_allclose(box, [0.5, 0.0, 10.0, 10.0], atol=1e-12)


def test_the_tracker_s_iou_is_the_metrics_one():
    rng = np.random.default_rng(0)
    for _ in range(200):
        a, b = rng.uniform(0, 50, 4) + [0, 0, 0.5, 0.5], rng.uniform(0, 50, 4) + [0, 0, 0.5, 0.5]
        assert box_iou(a, b) == pytest.approx(float(overlaps(a, b)), abs=1e-15)


def test_make_tracker_builds_one_expert_or_a_pair_and_the_partner_learns_every_frame():
    assert type(make_tracker(second_expert="off")) is NRMLCTracker
    pair = make_tracker()
    assert type(pair) is ExpertPair and all(type(expert) is NRMLCTracker for expert in pair.experts)
    assert TrackerParams.paper().second_expert == "off" and TrackerParams.paper().unrecognised_size_share == 0
    params = TrackerParams(second_expert="every_frame")
    assert params.estimated_bytes() == 2 * TrackerParams(second_expert="off").estimated_bytes()
    assert params.partner_params() == TrackerParams(update_interval=1, second_expert="off", eyes="gradient")
    assert pair.experts[1].params == pair.params.partner_params() and pair.experts[0].params == pair.params
    with pytest.raises(ParameterError, match="second_expert"):
        ExpertPair(seed=0, second_expert="off")


def test_move_to_moves_both_experts(sequence):
    from experiments.instrumented import move_to

    tracker = make_tracker(seed=0, **{**SETTINGS, "second_expert": "every_frame"})
    tracker.init(sequence.frame(0), sequence.init_box)
    tracker.update(sequence.frame(1))
    box = np.array([20.0, 15.0, 18.0, 14.0])
    move_to(tracker, box)
    np.testing.assert_array_equal(tracker.experts[0].state, tracker.experts[1].state)
    np.testing.assert_array_equal(tracker.recognised_log_size, np.log(box[2:]))


@pytest.mark.parametrize("changes, name", [(dict(second_expert="twin"), "second_expert"),
                                           (dict(expert_memory=1.0), "expert_memory"),
                                           (dict(expert_memory=-0.1), "expert_memory"),
                                           (dict(unrecognised_size_share=1.5), "unrecognised_size_share"),
                                           (dict(unrecognised_gate=0.0), "unrecognised_gate")])
def test_bad_values_name_the_parameter(changes, name):
    with pytest.raises(ParameterError, match=name):
        TrackerParams(**changes)


@pytest.mark.parametrize("eyes", ["gradient", "gray"])
def test_a_partner_with_other_eyes_is_its_single_run_chosen_offline(sequence, eyes):
    """The study's method (rounds 80-81): a pair whose partner sees otherwise is, to the bit, its
    two experts run alone and chosen offline (experiments.development.expert_choice), though the
    pair warps both experts' particles in one pass."""
    from experiments.development.expert_choice import chosen_boxes

    pair = _run(sequence, second_expert="every_frame", partner_eyes=eyes, expert_memory=0.0,
                expert_blend_iou=0.5, unrecognised_size_share=0.7)
    own = _run(sequence)
    partner = _run(sequence, update_interval=1, eyes=eyes)
    boxes, chosen = chosen_boxes(own, partner, 0.0, 0.5, 0.7, 0.15)
    assert chosen[1:].sum() > 0 and not np.array_equal(own.boxes, partner.boxes)
    np.testing.assert_array_equal(pair.boxes, boxes)
    np.testing.assert_array_equal(pair.diagnostics["expert"][1:], chosen[1:])
