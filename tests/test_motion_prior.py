"""motion_prior: a Gaussian on the candidate's displacement from the previous estimate in log h."""
import numpy as np

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec


def _tracker(**overrides) -> NRMLCTracker:
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=2))
    tracker = NRMLCTracker(seed=0, n_particles=20, **overrides)
    tracker.init(sequence.raw_frame(0), sequence.init_box)
    return tracker


def test_off_by_default_and_in_the_paper_preset():
    assert TrackerParams().motion_prior == 0.0 and TrackerParams.paper().motion_prior == 0.0


def test_log_prior_against_a_naive_oracle():
    tracker = _tracker(motion_prior=3.0)
    state = tracker.state
    size = state[2] * np.sqrt(0.5 * (1.0 + state[4] ** 2))
    sigma_x, sigma_y = 3.0 * tracker.params.translation_sigmas(np.array([size]))[0]
    states = np.tile(state, (4, 1))
    states[1, 0] += sigma_x
    states[2, 1] -= 2 * sigma_y
    states[3, 0:2] += (sigma_x, sigma_y)
    np.testing.assert_allclose(tracker._log_motion_prior(states), [0.0, -0.5, -2.0, -1.0], atol=1e-12)


def test_an_axis_without_motion_noise_gets_no_prior():
    tracker = _tracker(motion_prior=3.0, motion_sigmas=(2.0, 0.0, 0.01, 0.0, 0.005, 0.0))
    states = np.tile(tracker.state, (2, 1))
    states[1, 1] += 10.0
    np.testing.assert_array_equal(tracker._log_motion_prior(states), [0.0, 0.0])


def test_the_same_patch_farther_away_is_less_confident_and_off_changes_nothing():
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=2))
    frame = sequence.raw_frame(1).astype(np.float32)
    on, off = _tracker(motion_prior=3.0), _tracker()
    states = np.tile(on.state, (3, 1))
    states[:, 0] += [0.0, 10.0, 30.0]
    patches = on.patches(frame, np.tile(on.state, (3, 1)))  # one patch, three places
    with_prior = on.encode(patches, states).log_confidence
    assert with_prior[0] > with_prior[1] > with_prior[2]
    np.testing.assert_array_equal(off.encode(patches, states).log_confidence, off.encode(patches).log_confidence)
