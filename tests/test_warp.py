import cv2
import numba
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from nrmlc.errors import ParameterError
from nrmlc.geometry import affine_for_opencv, box_to_state, state_to_affine
from nrmlc.kernels.warp import warp_patches
from nrmlc.testing.reference import warp_patches_reference


def _frame(height=60, width=80, seed=0):
    rng = np.random.default_rng(seed)
    return rng.random((height, width)).astype(np.float32)


def _opencv_patches(frame, affines, patch_size=32):
    out = []
    for opencv_matrix in affine_for_opencv(affines, patch_size):
        patch = cv2.warpAffine(frame, opencv_matrix, (patch_size, patch_size),
                               flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)
        vector = patch.astype(np.float64).ravel()
        out.append(vector / np.linalg.norm(vector))
    return np.array(out)


def test_matches_opencv_on_its_interpolation_grid():
    # OpenCV quantises sample positions to 1/32 px (INTER_TAB_SIZE); on that grid its
    # bilinear weights are exact, so both implementations must agree to float32 precision.
    rng = np.random.default_rng(1)
    frame = _frame(120, 160)
    affines = []
    while len(affines) < 40:
        linear = rng.integers(-40, 41, size=(2, 2)) / 32.0
        if np.linalg.det(linear) <= 0.05:
            continue
        offset = rng.integers(5 * 32, 100 * 32, size=2) / 32.0
        opencv_matrix = np.concatenate([linear, offset[:, None]], axis=1)
        centre = 15.5
        # invert affine_for_opencv: t = offset + A @ [c, c]
        affines.append(np.concatenate([linear, (offset + linear @ [centre, centre])[:, None]], axis=1))
        assert np.allclose(affine_for_opencv(affines[-1]), opencv_matrix)
    affines = np.ascontiguousarray(affines)
    ours = warp_patches(frame, affines)
    np.testing.assert_allclose(ours, _opencv_patches(frame, affines), atol=1e-4)


def test_close_to_opencv_off_grid():
    # Off the grid OpenCV's 1/32 px quantisation bounds the difference by about
    # (1/64 px) x (largest pixel step) before normalisation.
    frame = cv2.GaussianBlur(_frame(120, 160), (0, 0), 2.0)
    rng = np.random.default_rng(2)
    states = np.tile(box_to_state(np.array([40.0, 30.0, 50.0, 40.0])), (30, 1))
    states[:, :2] += rng.normal(0, 5, (30, 2))
    states[:, 3] = rng.normal(0, 0.3, 30)
    affines = np.ascontiguousarray(state_to_affine(states))
    step = max(np.abs(np.diff(frame, axis=0)).max(), np.abs(np.diff(frame, axis=1)).max())
    ours = warp_patches(frame, affines)
    theirs = _opencv_patches(frame, affines)
    assert np.abs(ours - theirs).max() < step / 32 / np.sqrt(1024) * 4


def test_unit_norm_and_mean_statistic():
    patches = warp_patches(_frame(), np.ascontiguousarray(state_to_affine(
        np.tile(box_to_state(np.array([10.0, 10.0, 40.0, 30.0])), (10, 1)))))
    np.testing.assert_allclose(np.linalg.norm(patches, axis=1), 1.0, rtol=1e-5)
    # non-negative unit vectors of length 1024 have mean <= 1/32 (flat patch)
    assert np.all(patches.mean(axis=1) <= 1 / 32 + 1e-6)


def test_zero_norm_patch_becomes_flat():
    frame = np.zeros((40, 40), np.float32)
    patches = warp_patches(frame, np.ascontiguousarray(state_to_affine(box_to_state(np.array([[5.0, 5.0, 20.0, 20.0]])))))
    np.testing.assert_allclose(patches, 1 / 32)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-150, 250), st.floats(-150, 250), st.floats(0.05, 4),
                          st.floats(-np.pi, np.pi), st.floats(0.2, 5), st.floats(-0.7, 0.7)),
                min_size=1, max_size=8))
def test_matches_reference_including_outside_the_frame(states):
    # Centres range far outside the 60x80 frame: partly and wholly outside targets.
    frame = _frame()
    affines = np.ascontiguousarray(state_to_affine(np.array(states)))
    np.testing.assert_allclose(warp_patches(frame, affines), warp_patches_reference(frame, affines), atol=2e-6)


def _both_paths(frame, affines, patch_size=32):
    """The kernel's output with the axis-aligned fast path allowed and forbidden."""
    from nrmlc.kernels.warp import _warp_patches

    out = []
    for allow in (True, False):
        n = affines.shape[0]
        patches = np.empty((n, patch_size * patch_size), np.float32)
        _warp_patches(frame, affines, patch_size, allow, np.empty((n, patch_size), np.uint64),
                      np.empty((n, patch_size)), np.empty((n, patch_size)), patches)
        out.append(patches)
    return out


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(-150, 250), st.floats(-150, 250), st.floats(0.05, 4), st.floats(0.2, 5)),
                min_size=1, max_size=8),
       st.integers(2, 90), st.integers(2, 90))
def test_axis_aligned_fast_path_matches_reference_and_general_path(states, height, width):
    # rotation = skew = 0 (the tracker's usual case) takes the separable fast path;
    # tiny frames (down to 2x2) and targets far outside exercise the clamping.
    frame = _frame(height, width)
    states = np.array([(cx, cy, s, 0.0, a, 0.0) for cx, cy, s, a in states])
    affines = np.ascontiguousarray(state_to_affine(states))
    assert np.all(affines[:, 0, 1] == 0) and np.all(affines[:, 1, 0] == 0)
    fast, general = _both_paths(frame, affines)
    np.testing.assert_allclose(fast, warp_patches_reference(frame, affines), atol=2e-6)
    # Same per-sample arithmetic; only the summation order of the norm differs.
    np.testing.assert_allclose(fast, general, rtol=3e-7, atol=1e-9)
    np.testing.assert_array_equal(warp_patches(frame, affines), fast)


def test_wholly_outside_target_replicates_the_border():
    frame = _frame()
    affines = np.ascontiguousarray(state_to_affine(box_to_state(np.array([[500.0, 500.0, 20.0, 20.0]]))))
    # every sample clamps to the bottom-right pixel: a flat patch
    np.testing.assert_allclose(warp_patches(frame, affines), 1 / 32, rtol=1e-5)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2,
    reason="NUMBA_NUM_THREADS is 1 here (a single core): one thread against one compares nothing")
def test_same_bits_with_one_or_two_threads():
    frame = _frame()
    states = np.tile(box_to_state(np.array([10.0, 10.0, 40.0, 30.0])), (64, 1))
    states[:, :2] += np.random.default_rng(0).normal(0, 3, (64, 2))
    affines = np.ascontiguousarray(state_to_affine(states))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = warp_patches(frame, affines)
        numba.set_num_threads(2)
        two = warp_patches(frame, affines)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(one, two)


@pytest.mark.parametrize("frame, affines, message", [
    (np.zeros((10, 10), np.float64), np.zeros((1, 2, 3)), "float32"),
    (np.zeros((10, 10), np.float32), np.zeros((1, 3, 3)), "shape"),
    (np.zeros((10, 10), np.float32)[:, ::2], np.zeros((1, 2, 3)), "contiguous"),
    (np.zeros((10, 10), np.float32), np.full((1, 2, 3), np.nan), "NaN"),
])
def test_bad_inputs_are_named(frame, affines, message):
    with pytest.raises(ParameterError, match=message):
        warp_patches(frame, affines)


