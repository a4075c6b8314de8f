"""Round 19's two switches: the frame without its local brightness, the scale held while lost."""
import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.tracker.illumination import remove_local_mean
from nrmlc.tracker.redetect import REDETECT_TRIGGER


def _reference_local_mean(frame, side):
    """The mean over a side x side box about each pixel, the border reflected (OpenCV's
    BORDER_REFLECT: ...cba|abc...), by explicit summation."""
    half = side // 2
    padded = np.pad(frame.astype(np.float64), half, mode="symmetric")
    out = np.empty(frame.shape)
    for row in range(frame.shape[0]):
        for col in range(frame.shape[1]):
            out[row, col] = padded[row:row + side, col:col + side].mean()
    return out


@pytest.mark.parametrize("window, size", [(1.0, 5.0), (3.0, 3.0), (0.1, 4.0)])
def test_remove_local_mean_matches_the_explicit_box_mean(window, size):
    frame = np.random.default_rng(0).random((17, 23)).astype(np.float32)
    side = max(3, int(round(window * size)) | 1)
    expected = frame - _reference_local_mean(frame, side)
    np.testing.assert_allclose(remove_local_mean(frame, window, size), expected, atol=2e-6)


def test_an_added_brightness_cancels_and_the_contrast_stays():
    rng = np.random.default_rng(1)
    frame = rng.random((40, 50)).astype(np.float32)
    brighter = frame + np.float32(0.3)
    np.testing.assert_allclose(remove_local_mean(brighter, 3.0, 8.0), remove_local_mean(frame, 3.0, 8.0), atol=1e-5)
    # a bright square on a dark ground keeps a positive mean inside: its contrast is not thrown away
    square = np.zeros((60, 60), np.float32)
    square[25:35, 25:35] = 1.0
    assert remove_local_mean(square, 3.0, 10.0)[25:35, 25:35].mean() > 0.5


def test_the_switches_are_off_in_the_default_and_the_paper_preset():
    for params in (TrackerParams(), TrackerParams.paper()):
        assert params.illumination_window == 0.0 and params.hold_scale_when_lost is False


@pytest.fixture(scope="module")
def sequence():
    return SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=12))


def test_illumination_window_tracks_and_changes_the_boxes(sequence):
    boxes = {}
    for window in (0.0, 3.0):
        tracker = NRMLCTracker(seed=0, n_particles=100, illumination_window=window)
        tracker.init(sequence.frame(0), sequence.init_box)
        boxes[window] = np.array([tracker.update(sequence.frame(i)) for i in range(1, len(sequence))])
    assert np.all(np.isfinite(boxes[3.0]))
    assert not np.array_equal(boxes[0.0], boxes[3.0])


@pytest.mark.parametrize("lost", [True, False])
def test_the_scale_is_held_only_while_the_target_is_not_recognised(sequence, lost):
    tracker = NRMLCTracker(seed=0, n_particles=100, hold_scale_when_lost=True)
    tracker.init(sequence.frame(0), sequence.init_box)
    tracker.update(sequence.frame(1))
    tracker.last.error_positive = REDETECT_TRIGGER if lost else 0.0
    states = np.tile(tracker.state, (200, 1))
    diffused = tracker.diffuse(states.copy())
    held = np.allclose(diffused[:, [2, 4]], states[:, [2, 4]], rtol=0, atol=0)
    assert held == lost
    assert not np.allclose(diffused[:, :2], states[:, :2])  # translation noise either way


@pytest.mark.parametrize("held", [True, False])
def test_the_scale_prior_acts_only_after_a_held_frame(sequence, held):
    tracker = NRMLCTracker(seed=0, n_particles=100, held_scale_prior=0.2)
    tracker.init(sequence.frame(0), sequence.init_box)
    tracker.update(sequence.frame(1))
    tracker.last.error_positive = 0.0 if held else tracker.params.update_error_threshold
    states = np.tile(tracker.state, (3, 1))
    states[:, 2] = tracker.state[2] * np.array([1.0, 0.8, 1.25])
    states[:, 4] = 1.0
    states[0, 2] = tracker.initial_box[2] / tracker.params.patch_size  # the first box's width ...
    states[:, 4] = tracker.initial_box[3] / tracker.initial_box[2]    # ... and aspect: prior 0 there
    coding = tracker.encode(tracker.patches(sequence.frame(1), states))
    shifted = tracker._with_scale_prior(coding, states).log_confidence - coding.log_confidence
    if held:
        ratio = states[1:, 2] / states[0, 2]
        np.testing.assert_allclose(shifted, np.r_[0.0, -0.5 * (np.log(ratio) / 0.2) ** 2], atol=1e-12)
    else:
        np.testing.assert_array_equal(shifted, 0.0)


def test_an_added_switch_stays_out_of_the_run_key_while_off():
    from nrmlc.runner import params_for_key
    from nrmlc.tracker.params import ADDED_SWITCHES_OFF

    default = params_for_key(TrackerParams())
    assert not set(ADDED_SWITCHES_OFF) & set(default)
    assert params_for_key(TrackerParams(held_scale_prior=0.3))["held_scale_prior"] == 0.3
    for name, off in ADDED_SWITCHES_OFF.items():
        assert getattr(TrackerParams(), name) == off
