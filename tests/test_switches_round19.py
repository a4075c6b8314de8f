"""Round 19's switches: colour features, the scale held while lost, the scale prior while held."""
import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.tracker.redetect import REDETECT_TRIGGER


def test_colour_planes_are_scaled_as_the_gray_frame():
    from nrmlc.data.image import as_colour_planes

    image = np.random.default_rng(0).integers(0, 256, (6, 7, 3), dtype=np.uint8)
    blue, green, red = as_colour_planes(image)
    np.testing.assert_allclose(red, image[:, :, 2] / 255.0, atol=1e-7)
    assert blue.dtype == np.float32 and blue.flags.c_contiguous
    gray = image[:, :, 0]
    for plane in as_colour_planes(gray):
        np.testing.assert_allclose(plane, gray / 255.0, atol=1e-7)


def test_a_colour_patch_is_four_unit_planes_side_by_side(sequence):
    tracker = NRMLCTracker(seed=0, n_particles=50, features="colour")
    image = np.stack([sequence.raw_frame(0)] * 3, axis=2) if sequence.raw_frame(0).ndim == 2 else sequence.raw_frame(0)
    tracker.init(image, sequence.init_box)
    states = np.tile(tracker.state, (5, 1))
    patches = tracker.patches(tracker._frame(image), states)
    size = tracker.params.patch_size ** 2
    assert patches.shape == (5, 4 * size)
    np.testing.assert_allclose(np.linalg.norm(patches, axis=1), 1.0, rtol=1e-5)
    gray = NRMLCTracker(seed=0, n_particles=50)
    gray.init(image, sequence.init_box)
    # a gray scene: every plane is the gray patch, at half its norm
    np.testing.assert_allclose(patches[:, :size] * 2, gray.patches(gray._frame(image), states), atol=1e-5)
    np.testing.assert_allclose(patches[:, size:2 * size], patches[:, :size], atol=1e-5)


def test_the_switches_are_off_in_the_default_and_the_paper_preset():
    for params in (TrackerParams(), TrackerParams.paper()):
        assert params.features == "gray" and params.hold_scale_when_lost is False and params.held_scale_prior == 0


@pytest.fixture(scope="module")
def sequence():
    return SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=12))


@pytest.mark.parametrize("features", ["colour", "gradient"])
def test_other_features_track_a_sequence(sequence, features):
    from nrmlc.tracker import track_sequence

    run = track_sequence(sequence, TrackerParams(n_particles=100, features=features), seed=0)
    assert run.boxes.shape == (len(sequence), 4) and np.all(np.isfinite(run.boxes))
    assert run.diagnostics["error_positive"][1:].max() <= 4.0


def test_the_gradient_plane_is_the_sobel_magnitude():
    from nrmlc.data.image import gradient_magnitude

    frame = np.zeros((9, 9), np.float32)
    frame[:, 5:] = 1.0  # a vertical edge: |dx| = 4 (Sobel's weights 1, 2, 1) beside it, 0 elsewhere
    magnitude = gradient_magnitude(frame)
    np.testing.assert_allclose(magnitude[:, 4:6], 4.0)
    np.testing.assert_allclose(magnitude[:, :3], 0.0)


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
