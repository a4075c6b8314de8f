"""Round 23's scale anchors: the scale held for the first frames of a loss, a prior on the size while held."""
import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.runner import SWITCHES_ADDED_LATER, params_for_key


@pytest.fixture(scope="module")
def sequence():
    return SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=12))


def _tracker(sequence, **changes):
    tracker = NRMLCTracker(seed=0, n_particles=100, **changes)
    tracker.init(sequence.frame(0), sequence.init_box)
    tracker.update(sequence.frame(1))
    return tracker


def test_the_switches_are_off_in_the_default_and_the_paper_preset_and_out_of_the_run_key():
    for params in (TrackerParams(), TrackerParams.paper()):
        assert params.held_scale_prior == 0.0 and params.hold_scale_lost_frames == 0
        assert not {"held_scale_prior", "held_scale_prior_side", "hold_scale_lost_frames"} & set(params_for_key(params))
    assert params_for_key(TrackerParams(hold_scale_lost_frames=10))["hold_scale_lost_frames"] == 10
    for name in ("held_scale_prior", "held_scale_prior_side", "hold_scale_lost_frames"):
        assert getattr(TrackerParams(), name) == SWITCHES_ADDED_LATER[name]


@pytest.mark.parametrize("lost_frames, held", [(0, False), (1, True), (10, True), (11, False)])
def test_the_scale_is_held_on_the_first_frames_of_a_loss_only(sequence, lost_frames, held):
    tracker = _tracker(sequence, hold_scale_lost_frames=10)
    tracker.lost_frames = lost_frames
    states = np.tile(tracker.state, (200, 1))
    diffused = tracker.diffuse(states.copy())
    assert np.array_equal(diffused[:, [2, 4]], states[:, [2, 4]]) == held
    assert not np.allclose(diffused[:, :2], states[:, :2])  # translation noise either way


def test_the_lost_frames_count_the_consecutive_estimates_at_the_trigger(sequence):
    from nrmlc.tracker.redetect import REDETECT_TRIGGER

    tracker = _tracker(sequence)
    noise = np.random.default_rng(0).random(sequence.frame(0).shape).astype(np.float32) * 255
    frames = [sequence.frame(2), noise, noise, noise, sequence.frame(3), noise]
    expected, seen = 0, []
    for frame in frames:
        tracker.update(frame)
        expected = expected + 1 if tracker.last.error_positive >= REDETECT_TRIGGER else 0
        assert tracker.lost_frames == expected
        seen.append(expected)
    assert max(seen) >= 2  # the frames of noise are a loss: the count is exercised


@pytest.mark.parametrize("side", ["both", "below"])
@pytest.mark.parametrize("held", [True, False])
def test_the_scale_prior_acts_only_after_a_held_frame_and_on_its_side(sequence, held, side):
    tracker = _tracker(sequence, held_scale_prior=0.2, held_scale_prior_side=side)
    tracker.last.error_positive = 0.0 if held else tracker.params.update_error_threshold
    states = np.tile(tracker.state, (3, 1))
    states[:, 2] = tracker.initial_box[2] / tracker.params.patch_size * np.array([1.0, 0.8, 1.25])
    states[:, 4] = tracker.initial_box[3] / tracker.initial_box[2]  # the first box's aspect: prior 0 at row 0
    coding = tracker.encode(tracker.patches(sequence.frame(1), states))
    shifted = tracker._with_scale_prior(coding, states).log_confidence - coding.log_confidence
    if not held:
        np.testing.assert_array_equal(shifted, 0.0)
        return
    penalty = -0.5 * (np.log([1.0, 0.8, 1.25]) / 0.2) ** 2
    if side == "below":
        penalty[2] = 0.0  # growth is not penalised
    np.testing.assert_allclose(shifted, penalty, atol=1e-9)
