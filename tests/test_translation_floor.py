"""translation_floor: the relative translation noise is at least this many image pixels."""
import numpy as np

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec


def _spread(floor: float, size_scale: float) -> tuple[float, float]:
    """(std of the diffused centres, 2 template px) in image px for the target scaled by size_scale."""
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=2))
    tracker = NRMLCTracker(seed=0, n_particles=20, translation_floor=floor)
    tracker.init(sequence.raw_frame(0), sequence.init_box)
    states = np.tile(tracker.state, (20000, 1))
    states[:, 2] *= size_scale
    centre = states[:, 0:2].copy()
    moved = tracker.diffuse(states)
    size = tracker.state[2] * size_scale * np.sqrt(0.5 * (1.0 + tracker.state[4] ** 2))
    return float(np.std(moved[:, 0:2] - centre)), float(2.0 * size)  # 2 template px


def test_a_small_target_gets_the_floor_and_a_large_one_its_relative_noise():
    spread, relative = _spread(0.0, 0.1)
    assert abs(spread - relative) < 0.05 * relative           # off: 2 template px
    spread, relative = _spread(6.0, 0.1)
    assert relative < 6.0 and abs(spread - 6.0) < 0.3           # small target: the floor
    spread_large, relative_large = _spread(6.0, 4.0)
    assert relative_large > 6.0 and abs(spread_large - relative_large) < 0.05 * relative_large


def test_the_floor_is_the_lineages_4_px_by_default_and_off_in_the_paper_preset():
    assert TrackerParams().translation_floor == 4.0 and TrackerParams.paper().translation_floor == 0.0


def test_translation_sigmas_per_axis_against_a_naive_oracle():
    sizes = np.array([0.5, 1.0, 3.0, 10.0])
    params = TrackerParams(motion_sigmas=(2.0, 0.0, 0.01, 0.0, 0.005, 0.0), translation_floor=4.0)
    expected = np.array([[max(2.0 * s, 4.0), 0.0] for s in sizes])  # no noise on y: the floor adds none
    np.testing.assert_array_equal(params.translation_sigmas(sizes), expected)
    np.testing.assert_array_equal(params.replace(translation_floor=0.0).translation_sigmas(sizes),
                                  np.array([[2.0 * s, 0.0] for s in sizes]))
    np.testing.assert_array_equal(params.replace(translation_noise="pixels").translation_sigmas(sizes),
                                  np.tile([2.0, 0.0], (4, 1)))
