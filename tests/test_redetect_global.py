"""redetect_global: candidates over the whole frame once the target has not been recognised."""
import numpy as np

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.metrics import overlaps
from nrmlc.tracker.redetect import global_states


def _scene(target_at: tuple[int, int], rng_seed: int = 0) -> np.ndarray:
    """A 240x320 gray frame: smooth noise, and a 30x30 checkered target at ``target_at`` (x, y)."""
    rng = np.random.default_rng(rng_seed)
    coarse = rng.uniform(60, 120, (12, 16))
    frame = np.kron(coarse, np.ones((20, 20))).astype(np.float32)
    x, y = target_at
    tile = np.kron(np.array([[1, 0, 1], [0, 1, 0], [1, 0, 1]]), np.ones((10, 10)))
    frame[y:y + 30, x:x + 30] = 20 + 215 * tile
    return frame


def test_off_by_default_and_in_the_paper_preset():
    assert TrackerParams().redetect_global == 0 and TrackerParams.paper().redetect_global == 0


def test_global_states_cover_the_frame_at_the_recognised_shape():
    tracker = NRMLCTracker(seed=0, n_particles=20, redetect_global=500)
    tracker.init(_scene((40, 40)), (41, 41, 30, 30))
    tracker.recognised_state = tracker.state.copy()
    tracker.recognised_state[2] *= 1.5
    states = global_states(tracker, 500)
    assert states.shape == (500, 6)
    assert states[:, 0].min() >= 0 and states[:, 0].max() <= 319 and states[:, 1].max() <= 239
    assert states[:, 0].std() > 60 and states[:, 1].std() > 45          # spread over the frame
    np.testing.assert_allclose(np.median(states[:, 2]), tracker.recognised_state[2], rtol=0.02)


def _track_a_jump(**overrides) -> float:
    """Mean overlap over 25 frames after the target jumps from (40, 40) to (250, 170)."""
    tracker = NRMLCTracker(seed=1, n_particles=100, redetect_global_after=0, **overrides)
    tracker.init(_scene((40, 40)), (41, 41, 30, 30))
    boxes = [tracker.update(_scene((250, 170))) for _ in range(25)]
    truth = np.tile([251.0, 171.0, 30.0, 30.0], (25, 1))
    return float(overlaps(np.array(boxes), truth)[10:].mean())


def test_a_target_that_jumped_out_of_reach_is_found_only_with_the_global_search():
    assert _track_a_jump() < 0.1
    assert _track_a_jump(redetect_global=300) > 0.5
