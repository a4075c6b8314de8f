"""What an expert sees (nrmlc.tracker.eyes) and the gradient-orientation cells kernel."""
from __future__ import annotations

import math

import numpy as np
import pytest

from nrmlc import TrackerParams
from nrmlc.data.image import as_gray_frame
from nrmlc.errors import ParameterError
from nrmlc.kernels.gradient_cells import ORIENTATION_ERROR, gradient_cells, unsigned_orientation
from nrmlc.tracker.algorithm import NRMLCTracker
from nrmlc.tracker.eyes import ERROR_SCALE


def reference_gradient_cells(patch: np.ndarray, side: int, cell: int, bins: int) -> np.ndarray:
    """The oracle: one (side * side,) patch's cells, float64, written from the definition."""
    image = patch.reshape(side, side).astype(np.float64)
    histograms = np.zeros((side // cell, side // cell, bins))
    for row in range(side // cell * cell):
        for col in range(side // cell * cell):
            left, right = max(col - 1, 0), min(col + 1, side - 1)
            up, down = max(row - 1, 0), min(row + 1, side - 1)
            gx = (image[row, right] - image[row, left]) / (right - left)
            gy = (image[down, col] - image[up, col]) / (down - up)
            magnitude = math.hypot(gx, gy)
            if magnitude == 0:
                continue
            angle = math.atan2(gy, gx) % math.pi
            position = angle / (math.pi / bins) - 0.5
            low = math.floor(position)
            share = position - low
            histograms[row // cell, col // cell, low % bins] += magnitude * (1 - share)
            histograms[row // cell, col // cell, (low + 1) % bins] += magnitude * share
    vector = np.sqrt(histograms.ravel())
    norm = np.linalg.norm(vector)
    return vector / norm if norm > 1e-12 else np.full(vector.shape, 1 / math.sqrt(vector.size))


@pytest.mark.parametrize("side, cell, bins", [(32, 4, 9), (12, 3, 6), (10, 5, 4)])
def test_gradient_cells_match_the_reference(side, cell, bins):
    rng = np.random.default_rng(side)
    patches = rng.random((7, side * side)).astype(np.float32)
    patches[3] = 0.5  # flat: the flat unit vector
    patches[4] = np.tile(np.arange(side, dtype=np.float32), side)  # one orientation: bin edges split evenly
    features = gradient_cells(patches, side, cell, bins)
    assert features.shape == (7, (side // cell) ** 2 * bins) and features.dtype == np.float32
    expected = np.stack([reference_gradient_cells(p, side, cell, bins) for p in patches])
    np.testing.assert_allclose(features, expected, atol=2e-6)
    np.testing.assert_allclose(np.linalg.norm(features, axis=1), 1, atol=1e-6)


def test_gradient_cells_do_not_depend_on_the_thread_count():
    import numba

    patches = np.random.default_rng(2).random((37, 32 * 32)).astype(np.float32)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        alone = gradient_cells(patches, 32)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(gradient_cells(patches, 32), alone)


def test_unsigned_orientation_is_atan2_modulo_pi():
    rng = np.random.default_rng(1)
    gradients = rng.normal(size=(20_000, 2)) * rng.choice([1e-6, 1.0, 1e3], size=(20_000, 1))
    axes = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, 1), (1, -1), (-1, -1), (0, -0.0), (-2, -0.0), (1, 1e-300)]
    for gx, gy in np.vstack([gradients, axes]):
        orientation = unsigned_orientation(gx, gy)
        assert 0 <= orientation <= math.pi
        distance = abs(orientation - math.atan2(gy, gx) % math.pi)
        assert min(distance, math.pi - distance) <= ORIENTATION_ERROR, (gx, gy)


def test_gradient_cells_ignore_the_patch_s_level_and_gain():
    rng = np.random.default_rng(0)
    patch = rng.random((1, 32 * 32)).astype(np.float32)
    np.testing.assert_allclose(gradient_cells(3 * patch + 2, 32), gradient_cells(patch, 32), atol=2e-6)


@pytest.mark.parametrize("call, name", [
    (lambda: gradient_cells(np.zeros((2, 30), np.float32), 5), "patches must have"),
    (lambda: gradient_cells(np.zeros((2, 36), np.float32), 6, 4), "multiple of cell"),
    (lambda: gradient_cells(np.zeros((2, 16)), 4), "patches must have dtype float32"),
    (lambda: gradient_cells(np.zeros((2, 16), np.float32), 4, 1, 1), "bins"),
])
def test_gradient_cells_refuse_bad_input_in_one_line(call, name):
    with pytest.raises(ParameterError, match=name):
        call()


def _frame(rng):
    return (rng.random((60, 80, 3)) * 255).astype(np.uint8)


@pytest.mark.parametrize("eyes", ["gradient"])
def test_an_expert_with_other_eyes_codes_its_own_templates_in_gray_units(eyes, monkeypatch):
    """Its templates are vectors of its own eyes; it has no generative term; its errors are its
    own space's divided by the eye's scale."""
    rng = np.random.default_rng(2)
    image = _frame(rng)
    tracker = NRMLCTracker(0, TrackerParams(second_expert="off", eyes=eyes, n_particles=40))
    tracker.init(image, np.array([20.0, 15.0, 24.0, 20.0]))
    assert tracker.generative is None
    assert tracker.templates.shape[1] == 576
    tracker.update(image)
    candidates = tracker.patches(as_gray_frame(image), tracker.particles[:5])
    scaled = tracker.encode(candidates)
    monkeypatch.setitem(ERROR_SCALE, eyes, 1.0)
    raw = tracker.encode(candidates)
    assert np.all(raw.error_positive > 0)
    monkeypatch.undo()
    np.testing.assert_allclose(scaled.error_positive, raw.error_positive / ERROR_SCALE[eyes], rtol=1e-12)
    np.testing.assert_allclose(scaled.error_negative, raw.error_negative / ERROR_SCALE[eyes], rtol=1e-12)


def test_eyes_need_a_patch_that_fits():
    with pytest.raises(ParameterError, match="patch_size"):
        TrackerParams(eyes="gradient", patch_size=30, generative_weight=0.0)
