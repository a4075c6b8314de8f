"""The kernels' argument checks, each refusal with its exact message (docs/research/mutation.md).

Written against the mutants of ``nrmlc/kernels/checks.py``: every check's message (matched
whole), each bound at and just beyond its edge, and the values the checks return.
"""
import re

import numpy as np
import pytest

from nrmlc.errors import ParameterError
from nrmlc.kernels.checks import (check_array, check_finite, check_flag, check_indices, check_int, check_length,
                                  check_nonnegative_real)


def refused(message):
    return pytest.raises(ParameterError, match=f"^{re.escape(message)}$")


def test_check_array_accepts_an_allowed_c_contiguous_array():
    good = np.zeros((3, 4), dtype=np.float32)
    assert check_array("x", good, np.float32, 2) is None
    assert check_array("x", good, "float32", 2) is None
    assert check_array("x", good, (np.float64, np.float32), 2) is None
    assert check_array("x", good, [np.float32], 2) is None
    assert check_array("x", np.zeros(5, dtype=np.int64), (np.dtype(np.int64),), 1) is None


def test_check_array_refusals_name_the_argument():
    with refused("x must be a numpy array, got list"):
        check_array("x", [[1.0]], np.float64, 2)
    with refused("x must have dtype float32, got float64"):
        check_array("x", np.zeros((2, 2)), np.float32, 2)
    with refused("x must have dtype float32 or float64, got int64"):
        check_array("x", np.zeros((2, 2), dtype=np.int64), (np.float32, np.float64), 2)
    with refused("x must have dtype int64, got int32"):
        check_array("x", np.zeros(2, dtype=np.int32), [np.int64], 1)
    with refused("x must be 2-D, got shape (3,)"):
        check_array("x", np.zeros(3), np.float64, 2)
    with refused("x must be 1-D, got shape (1, 3)"):
        check_array("x", np.zeros((1, 3)), np.float64, 1)
    with refused("x must be C-contiguous"):
        check_array("x", np.zeros((3, 4))[:, ::2], np.float64, 2)
    with refused("x must be C-contiguous"):
        check_array("x", np.asfortranarray(np.zeros((3, 4))), np.float64, 2)


def test_check_length_names_rows_or_entries():
    assert check_length("w", np.zeros((4, 2)), 4, "dots has 4 rows") is None
    with refused("w has 3 rows, dots has 4 rows"):
        check_length("w", np.zeros((3, 2)), 4, "dots has 4 rows")
    with refused("w has 5 entries, dots has 4 rows"):
        check_length("w", np.zeros(5), 4, "dots has 4 rows")


def test_check_int_bounds_and_types():
    assert check_int("n", 1, 1) == 1
    assert check_int("n", 10**12, 1) == 10**12  # no upper bound without maximum
    assert check_int("n", 5, 1, 5) == 5  # both edges are in
    value = check_int("n", np.int64(3), 0, 5)
    assert value == 3 and type(value) is int
    with refused("n must be >= 1, got 0"):
        check_int("n", 0, 1)
    with refused("n must be >= 1, <= 5, got 6"):
        check_int("n", 6, 1, 5)
    with refused("n must be >= 1, <= 5, got 0"):
        check_int("n", 0, 1, 5)
    with refused("n must be an integer, got True"):
        check_int("n", True, 0)
    with refused(f"n must be an integer, got {np.bool_(False)!r}"):
        check_int("n", np.bool_(False), 0)
    with refused("n must be an integer, got 1.5"):
        check_int("n", 1.5, 0)
    with refused("n must be an integer, got '3'"):
        check_int("n", "3", 0)


def test_check_nonnegative_real():
    value = check_nonnegative_real("r", 0)
    assert value == 0.0 and type(value) is float  # zero is in
    value = check_nonnegative_real("r", np.float32(0.5))
    assert value == 0.5 and type(value) is float
    assert check_nonnegative_real("r", 1e300) == 1e300
    with refused("r must be finite and >= 0, got -1e-300"):
        check_nonnegative_real("r", -1e-300)
    with refused("r must be finite and >= 0, got inf"):
        check_nonnegative_real("r", float("inf"))
    with refused("r must be finite and >= 0, got nan"):
        check_nonnegative_real("r", float("nan"))
    with refused("r must be a real number, got False"):
        check_nonnegative_real("r", False)
    with refused(f"r must be a real number, got {np.bool_(True)!r}"):
        check_nonnegative_real("r", np.bool_(True))
    with refused("r must be a real number, got '1'"):
        check_nonnegative_real("r", "1")
    with refused("r must be a real number, got (1+0j)"):
        check_nonnegative_real("r", 1 + 0j)


def test_check_flag():
    assert check_flag("f", True) is True
    assert check_flag("f", np.bool_(False)) is False  # a python bool back
    with refused("f must be a bool, got 1"):
        check_flag("f", 1)
    with refused("f must be a bool, got None"):
        check_flag("f", None)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_check_finite(bad):
    assert check_finite("a", np.array([0.0, -1e308, 1e308])) is None
    with refused("a contains NaN or infinite values"):
        check_finite("a", np.array([0.0, bad, 1.0]))


def test_check_indices_edges():
    assert check_indices("i", np.array([0, 4, 2]), 5) is None  # 0 and upper - 1 are in
    assert check_indices("i", np.zeros(0, dtype=np.int64), 0) is None  # nothing to check
    with refused("i must lie in [0, 5)"):
        check_indices("i", np.array([0, 5]), 5)
    with refused("i must lie in [0, 5)"):
        check_indices("i", np.array([-1, 4]), 5)
    with refused("i must lie in [0, 5)"):
        check_indices("i", np.array([[1, 2], [3, 7]]), 5)


# -- warp.py: warp_patches' wrapper ---------------------------------------------------------------

def _frame(height=12, width=16):
    return np.arange(height * width, dtype=np.float32).reshape(height, width) % 7 + 1


def _affines(n=2):
    return np.tile(np.array([[1.0, 0.0, 6.0], [0.0, 1.0, 5.0]]), (n, 1, 1))


def test_warp_patches_output():
    from nrmlc.kernels.warp import warp_patches

    patches = warp_patches(_frame(), _affines(3))
    assert patches.shape == (3, 32 * 32) and patches.dtype == np.float32  # the default patch size is 32
    np.testing.assert_allclose(np.linalg.norm(patches, axis=1), 1.0, rtol=1e-6)
    small = warp_patches(_frame(), _affines(1), 2)  # the smallest grid: 2 x 2
    assert small.shape == (1, 4)
    assert warp_patches(_frame(), np.zeros((0, 2, 3)), 4).shape == (0, 16)
    # a frame of one row (or one column) is a frame: every sample is that row's
    row = warp_patches(np.ones((1, 5), np.float32), _affines(1), 4)
    np.testing.assert_allclose(row, 0.25, rtol=1e-6)
    column = warp_patches(np.ones((5, 1), np.float32), _affines(1), 4)
    np.testing.assert_allclose(column, 0.25, rtol=1e-6)


@pytest.mark.parametrize("frame, affines, patch_size, message", [
    (np.zeros((4, 4)), _affines(), 4, "frame must have dtype float32, got float64"),
    (np.zeros(4, np.float32), _affines(), 4, "frame must be 2-D, got shape (4,)"),
    (np.zeros((0, 5), np.float32), _affines(), 4, "frame must be non-empty, got shape (0, 5)"),
    (np.zeros((5, 0), np.float32), _affines(), 4, "frame must be non-empty, got shape (5, 0)"),
    (_frame(), _affines().astype(np.float32), 4, "affines must have dtype float64, got float32"),
    (_frame(), np.zeros((2, 3)), 4, "affines must be 3-D, got shape (2, 3)"),
    (_frame(), np.zeros((1, 3, 3)), 4, "affines must have shape (n_particles, 2, 3), got (1, 3, 3)"),
    (_frame(), np.zeros((1, 2, 2)), 4, "affines must have shape (n_particles, 2, 3), got (1, 2, 2)"),
    (_frame(), np.full((1, 2, 3), np.inf), 4, "affines contains NaN or infinite values"),
    (np.full((4, 4), np.nan, np.float32), _affines(), 4, "frame contains NaN or infinite values"),
    (_frame(), _affines(), 1, "patch_size must be >= 2, got 1"),
    (_frame(), _affines(), True, "patch_size must be an integer, got True"),
])
def test_warp_patches_refusals(frame, affines, patch_size, message):
    from nrmlc.kernels.warp import warp_patches

    with refused(message):
        warp_patches(frame, affines, patch_size)


# -- distance.py: the public wrappers' refusals -----------------------------------------------------

def _unit(n, dim=4, dtype=np.float64):
    rows = np.random.default_rng(n).standard_normal((n, dim))
    return np.ascontiguousarray(rows / np.linalg.norm(rows, axis=1, keepdims=True), dtype=dtype)


@pytest.mark.parametrize("candidates, templates, message", [
    ([[1.0]], _unit(2), "candidates must be a numpy array, got list"),
    (_unit(2), np.zeros((2, 4), np.int64), "templates must have dtype float32 or float64, got int64"),
    (_unit(2, dtype=np.float32), _unit(2), "templates dtype float64 differs from candidates dtype float32"),
    (_unit(2, 4), _unit(2, 3), "templates have dim 3, candidates have dim 4"),
])
def test_candidate_template_dots_refusals(candidates, templates, message):
    from nrmlc.kernels.distance import candidate_template_dots

    with refused(message):
        candidate_template_dots(candidates, templates)


def test_float32_dots_are_the_float32_product_cast_exactly():
    """float32 patches are multiplied in float32 (sgemm) and cast, in one call per block of 128
    rows: exactly ``(c @ t.T).astype(float64)`` for up to 128 candidates, not a float64 product."""
    from threadpoolctl import threadpool_limits

    from nrmlc.kernels.distance import candidate_template_dots

    rng = np.random.default_rng(5)
    candidates = rng.standard_normal((100, 64)).astype(np.float32)
    templates = rng.standard_normal((30, 64)).astype(np.float32)
    dots = candidate_template_dots(candidates, templates)
    assert dots.dtype == np.float64
    with threadpool_limits(1, "blas"):
        expected = (candidates @ templates.T).astype(np.float64)
    np.testing.assert_array_equal(dots, expected)
    wide = candidates.astype(np.float64) @ templates.astype(np.float64).T
    assert not np.array_equal(dots, wide)  # the test can tell the two apart


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_dots_come_from_fixed_blocks_of_128_rows(dtype):
    """Each block of 128 candidates is one BLAS call, whatever the number of candidates or
    threads: OpenBLAS gives a row other bits in a call of another size (on this machine 184 of
    450 rows differ between one call and 128-row calls), so the blocks are part of the result."""
    from threadpoolctl import threadpool_limits

    from nrmlc.kernels.distance import candidate_template_dots

    rng = np.random.default_rng(1)
    candidates = rng.standard_normal((300, 1024)).astype(dtype)
    templates = rng.standard_normal((60, 1024)).astype(dtype)
    with threadpool_limits(1, "blas"):  # as the kernel runs its products (BLAS rounding follows its threads)
        expected = np.vstack([candidates[start:start + 128] @ templates.T for start in (0, 128, 256)])
    np.testing.assert_array_equal(candidate_template_dots(candidates, templates), expected.astype(np.float64))


def test_squared_norms_refusal_and_output():
    from nrmlc.kernels.distance import squared_norms

    with refused("vectors must be 2-D, got shape (3,)"):
        squared_norms(np.ones(3))
    norms = squared_norms(np.array([[3.0, 4.0], [1.0, 1.0]], np.float32))
    assert norms.dtype == np.float64 and norms.tolist() == [25.0, 2.0]


@pytest.mark.parametrize("changes, message", [
    (dict(dots=np.zeros((2, 3), np.float32)), "dots must have dtype float64, got float32"),
    (dict(candidate_sq_norms=np.ones(2, np.float32)), "candidate_sq_norms must have dtype float64, got float32"),
    (dict(template_sq_norms=np.ones((1, 3))), "template_sq_norms must be 1-D, got shape (1, 3)"),
    (dict(candidate_sq_norms=np.ones(3)), "candidate_sq_norms has 3 entries, dots has 2 rows"),
    (dict(template_sq_norms=np.ones(4)), "template_sq_norms has 4 entries, dots has 3 columns"),
    (dict(k=4), "k must be >= 1, <= 3, got 4"),
    (dict(k=0), "k must be >= 1, <= 3, got 0"),
])
def test_nearest_templates_refusals(changes, message):
    from nrmlc.kernels.distance import nearest_templates

    arguments = dict(dots=np.zeros((2, 3)), candidate_sq_norms=np.ones(2), template_sq_norms=np.ones(3), k=2)
    with refused(message):
        nearest_templates(**{**arguments, **changes})


@pytest.mark.parametrize("previous, kept, message", [
    (np.eye(3), None, "template_gram: pass previous and kept together, or neither"),
    (None, np.zeros(3, np.int64), "template_gram: pass previous and kept together, or neither"),
    (np.eye(3, dtype=np.float32), np.zeros(3, np.int64), "previous must have dtype float64, got float32"),
    (np.zeros((2, 3)), np.zeros(3, np.int64), "previous must be a square Gram, got shape (2, 3)"),
    (np.eye(3), np.zeros(3, np.int32), "kept must have dtype int64, got int32"),
    (np.eye(3), np.zeros(2, np.int64), "kept has 2 entries, templates has 3 rows"),
    (np.eye(3), np.array([-2, 0, 1]), "kept must hold rows of previous (0..2) or -1"),
    (np.eye(3), np.array([3, 0, 1]), "kept must hold rows of previous (0..2) or -1"),
    (np.eye(4), np.array([4, 0, 1]), "kept must hold rows of previous (0..3) or -1"),
])
def test_template_gram_refusals(previous, kept, message):
    from nrmlc.kernels.distance import template_gram

    with refused(message):
        template_gram(_unit(3), previous, kept)


def test_template_gram_accepts_kept_at_its_edges():
    from nrmlc.kernels.distance import template_gram

    templates = _unit(3)
    previous = template_gram(templates)
    np.testing.assert_array_equal(template_gram(templates, previous, np.array([0, 1, 2])), previous)
    gram = template_gram(templates, previous, np.array([-1, 1, 2]))
    np.testing.assert_allclose(gram, templates @ templates.T, atol=1e-12)
    with refused("templates must have dtype float32 or float64, got int64"):
        template_gram(np.zeros((3, 4), np.int64))


# -- distance._thread_pool: the product blocks' workers ------------------------------------------

def test_thread_pool_is_kept_per_count_and_rebuilt_when_the_count_changes():
    """One pool per worker count, reused while the count stays, rebuilt (the old one shut down)
    when it changes; its workers are named ``nrmlc-gemm`` so thread dumps and profiles show them.
    Counts 3 and 4 are ones the tracker never asks for here, so no earlier pool is reused."""
    import threading

    from nrmlc.kernels import distance

    three = distance._thread_pool(3)
    assert distance._thread_pool(3) is three and three._max_workers == 3
    four = distance._thread_pool(4)
    assert four is not three and four._max_workers == 4 and distance._thread_pool(4) is four
    assert three._shutdown
    name = four.submit(lambda: threading.current_thread().name).result(timeout=60)
    assert name.startswith("nrmlc-gemm_")


def test_one_blas_thread_holds_blas_to_one_thread_inside_and_restores_it():
    """The products' guard: inside ``_one_blas_thread`` every BLAS library runs one thread (why:
    :func:`nrmlc.config.set_threads`), and the caller's count comes back on leaving."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from nrmlc.kernels import distance

    def blas_threads():
        return [entry["num_threads"] for entry in threadpool_info() if entry["user_api"] == "blas"]

    with threadpool_limits(limits=2, user_api="blas"):
        if not blas_threads() or min(blas_threads()) < 2:
            pytest.skip("numpy's BLAS cannot run two threads in this process")
        with distance._one_blas_thread():
            assert set(blas_threads()) == {1}
        assert min(blas_threads()) == 2
