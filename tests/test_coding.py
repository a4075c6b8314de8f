"""Tests of nrmlc.kernels.coding against the explicit float64 references."""
from __future__ import annotations

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrmlc.errors import ParameterError
from nrmlc.kernels.coding import code_candidates, combine_dictionaries, encode_dictionaries, scatter_codes
from nrmlc.kernels.distance import candidate_template_dots, nearest_templates, squared_norms, template_gram
from nrmlc.testing.reference import (
    kkt_report,
    make_problem,
    reference_combine,
    reference_encode,
    reference_simplex_qp,
    unit_rows,
)

SIZES = np.array([5, 8, 10], dtype=np.int64)
N_POSITIVE = 20

#: The thread-count comparisons need a second numba thread; with one (a single core) they would
#: compare one thread with itself.
TWO_THREADS = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason=(
    "NUMBA_NUM_THREADS is 1 here (a single core): one thread against one compares nothing"))

#: (ridge, constrained) -> tolerances of the coefficient comparison. The plain
#: coder is compared with the exact minimum-norm solution, from which the
#: jitter moves it by ~jitter / (smallest eigenvalue of G).
MODES = {
    "regularised": (1.0, False),
    "regularised_small": (1e-3, False),
    "plain": (0.0, False),
    "constrained": (1.0, True),
    "constrained_small": (1e-3, True),
    "constrained_plain": (0.0, True),
}


def _tolerances(ridge):
    return dict(rtol=1e-6, atol=1e-9) if ridge > 0 else dict(rtol=0, atol=1e-5)


def _pipeline(candidates, templates, k_max=10):
    """Kernel-side tables: dots, template Gram, norms, neighbours."""
    dots = candidate_template_dots(candidates, templates)
    gram = template_gram(templates)
    cand_norms = (candidates.astype(np.float64) ** 2).sum(axis=1)
    neighbours, _ = nearest_templates(dots, cand_norms, np.diag(gram).copy(), k_max)
    return gram, dots, cand_norms, neighbours


@pytest.fixture(scope="module")
def problem():
    candidates, templates = make_problem(10)
    # float64 products: the comparison then measures the kernels, not sgemm.
    tables = _pipeline(candidates.astype(np.float64), templates.astype(np.float64))
    return candidates, templates, tables


@pytest.mark.parametrize("mode", MODES)
def test_encode_matches_reference(problem, mode):
    ridge, constrained = MODES[mode]
    candidates, templates, (gram, dots, cand_norms, neighbours) = problem
    coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours, SIZES, ridge, constrained)
    assert coefficients.shape == (40, 3, 10) and coefficients.dtype == np.float64
    expected = reference_encode(candidates, templates, neighbours, SIZES, ridge, constrained)
    np.testing.assert_allclose(coefficients, expected, **_tolerances(ridge))
    for j, k in enumerate(SIZES):
        assert np.all(coefficients[:, j, k:] == 0.0)
    np.testing.assert_allclose(coefficients.sum(axis=2), 1.0, rtol=0, atol=1e-12)
    if constrained:
        assert coefficients.min() >= 0.0


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("n_iterations", [0, 1, 2, 3])
def test_combine_matches_reference(problem, mode, n_iterations):
    ridge, constrained = MODES[mode]
    candidates, templates, (gram, dots, cand_norms, neighbours) = problem
    coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours, SIZES, ridge, constrained)
    weights, codes, error_positive, error_negative = combine_dictionaries(
        gram, dots, cand_norms, neighbours, coefficients, SIZES, N_POSITIVE, ridge, constrained,
        n_iterations,
    )
    expected = reference_combine(candidates, templates, neighbours, coefficients, SIZES,
                                 N_POSITIVE, ridge, constrained, n_iterations)
    tolerance = _tolerances(ridge)
    np.testing.assert_allclose(weights, expected[0], **tolerance)
    np.testing.assert_allclose(scatter_codes(codes, neighbours, 60), expected[1], **tolerance)
    np.testing.assert_allclose(error_positive, expected[2], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(error_negative, expected[3], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(codes.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    if constrained:
        assert weights.min() >= 0.0 and codes.min() >= 0.0


def test_float32_pipeline_close_to_reference():
    # The tracker's path: sgemm dots (float32 accumulation) with the paper's
    # lambda = beta = 1; their ~1e-7 error barely moves the regularised coder.
    candidates, templates = make_problem(11)
    gram, dots, cand_norms, neighbours = _pipeline(candidates, templates)
    coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours, SIZES, 1.0, False)
    expected = reference_encode(candidates, templates, neighbours, SIZES, 1.0, False)
    np.testing.assert_allclose(coefficients, expected, rtol=0, atol=1e-5)
    weights, codes, error_positive, error_negative = combine_dictionaries(
        gram, dots, cand_norms, neighbours, coefficients, SIZES, N_POSITIVE, 1.0, False, 2)
    expected = reference_combine(candidates, templates, neighbours, coefficients, SIZES,
                                 N_POSITIVE, 1.0, False, 2)
    np.testing.assert_allclose(weights, expected[0], rtol=0, atol=1e-5)
    np.testing.assert_allclose(error_positive, expected[2], rtol=0, atol=1e-5)
    np.testing.assert_allclose(error_negative, expected[3], rtol=0, atol=1e-5)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), ridge=st.sampled_from([0.0, 1e-6, 1e-2, 1.0, 30.0]),
       constrained=st.booleans(), n_iterations=st.integers(0, 3))
def test_sum_to_one_property(seed, ridge, constrained, n_iterations):
    candidates, templates = make_problem(seed, n_candidates=8, n_templates=20, dim=16,
                                         n_positive=5)
    gram, dots, cand_norms, neighbours = _pipeline(candidates, templates, k_max=10)
    coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours, SIZES, ridge, constrained)
    weights, codes, error_positive, error_negative = combine_dictionaries(
        gram, dots, cand_norms, neighbours, coefficients, SIZES, 5, ridge, constrained,
        n_iterations)
    for array in (coefficients, weights, codes, error_positive, error_negative):
        assert np.all(np.isfinite(array))
    np.testing.assert_allclose(coefficients.sum(axis=2), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(codes.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    assert error_positive.min() >= 0.0 and error_negative.min() >= 0.0
    if constrained:
        assert coefficients.min() >= 0.0 and weights.min() >= 0.0


def _qp_via_kernel(matrix, ridge):
    """Run the active-set QP of encode_dictionaries on an arbitrary PSD ``matrix``.

    With ``y = 0`` (zero dots and norm) the local Gram is the template Gram itself.
    """
    k = matrix.shape[0]
    coefficients = encode_dictionaries(
        np.ascontiguousarray(matrix), np.zeros((1, k)), np.zeros(1),
        np.arange(k, dtype=np.int64)[None, :], np.array([k], dtype=np.int64), ridge, True)
    return coefficients[0, 0]


@st.composite
def psd_matrices(draw):
    k = draw(st.integers(1, 16))
    rank = draw(st.integers(1, k))
    seed = draw(st.integers(0, 2**32 - 1))
    duplicate = draw(st.booleans())
    rng = np.random.default_rng(seed)
    factor = rng.normal(size=(rank, k)) + draw(st.sampled_from([0.0, 1.0]))
    if duplicate and k > 1:
        factor[:, 1] = factor[:, 0]  # duplicate template: singular for any rank
    matrix = factor.T @ factor
    matrix /= np.abs(matrix).max()  # scale ~1 so that absolute tolerances mean something
    return (matrix + matrix.T) / 2


@settings(max_examples=50, deadline=None)
@given(matrix=psd_matrices(), ridge=st.sampled_from([0.0, 1e-4, 1e-1, 1.0]))
def test_qp_kkt_and_scipy(matrix, ridge):
    k = matrix.shape[0]
    objective_matrix = matrix + ridge * np.eye(k)
    c = _qp_via_kernel(matrix, ridge)
    report = kkt_report(objective_matrix, c)
    tolerance = 1e-8
    assert report["min_c"] >= 0.0
    assert report["sum_error"] <= 1e-12
    # Stationarity and slackness hold up to the jitter used when ridge == 0.
    assert report["stationarity"] <= tolerance
    assert report["dual_infeasibility"] >= -tolerance
    assert report["complementarity"] <= tolerance
    scipy_c = reference_simplex_qp(objective_matrix)
    assert c @ objective_matrix @ c <= scipy_c @ objective_matrix @ scipy_c + 1e-9
    if ridge > 0:
        # Strictly convex: the minimiser is unique.
        np.testing.assert_allclose(c, scipy_c, rtol=0, atol=1e-6)


def test_qp_known_solution():
    # y = 0 and templates (-1, 1), (1, 1), (0, 3): the closest point of their
    # triangle to y is (0, 1) = (t0 + t1) / 2, and t2 stays exactly at zero.
    points = np.array([[-1.0, 1.0], [1.0, 1.0], [0.0, 3.0]])
    c = _qp_via_kernel(points @ points.T, 0.0)
    np.testing.assert_allclose(c, [0.5, 0.5, 0.0], rtol=0, atol=1e-12)
    assert c[2] == 0.0


def test_qp_tied_optima_pick_minimum_norm():
    # y = 0 on the line through t0 = -1, t1 = 2, t2 = 5: every c on the segment
    # from (2/3, 1/3, 0) to (5/6, 0, 1/6) is optimal; the ridge -> 0+ limit
    # (minimum norm) is the first end point.
    points = np.array([[-1.0], [2.0], [5.0]])
    c = _qp_via_kernel(points @ points.T, 0.0)
    np.testing.assert_allclose(c, [2 / 3, 1 / 3, 0.0], rtol=0, atol=1e-8)


@pytest.mark.parametrize("constrained", [False, True])
def test_plain_duplicate_templates_finite(constrained):
    candidates, templates = make_problem(12, n_templates=30, n_positive=10)
    # Every template twice and candidates equal to templates: G is singular.
    templates = np.vstack([templates, templates])
    candidates = np.vstack([candidates, templates[:10]])
    for dtype in (np.float32, np.float64):
        gram, dots, cand_norms, neighbours = _pipeline(candidates.astype(dtype),
                                                       templates.astype(dtype))
        coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours, SIZES, 0.0,
                                           constrained)
        weights, codes, error_positive, error_negative = combine_dictionaries(
            gram, dots, cand_norms, neighbours, coefficients, SIZES, 10, 0.0, constrained, 2)
        for array in (coefficients, weights, codes, error_positive, error_negative):
            assert np.all(np.isfinite(array))
        np.testing.assert_allclose(coefficients.sum(axis=2), 1.0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(weights.sum(axis=1), 1.0, rtol=0, atol=1e-12)


def test_plain_duplicate_pair_splits_evenly():
    # Minimum-norm limit: two identical templates share their weight equally.
    candidates, templates = make_problem(13, n_templates=30, n_positive=10)
    templates = np.vstack([templates, templates]).astype(np.float64)
    gram, dots, cand_norms, neighbours = _pipeline(candidates.astype(np.float64), templates)
    coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours,
                                       np.array([2], dtype=np.int64), 0.0, False)
    assert np.all(neighbours[:, 1] == neighbours[:, 0] + 30)
    np.testing.assert_allclose(coefficients[:, 0, :2], 0.5, rtol=0, atol=1e-6)


@pytest.mark.parametrize("constrained", [False, True])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_all_templates_equal_candidate_gives_uniform(constrained, dtype):
    rng = np.random.default_rng(14)
    patch = unit_rows(rng.random((1, 64)))
    templates = np.repeat(patch, 12, axis=0).astype(dtype)
    candidates = np.repeat(patch, 3, axis=0).astype(dtype)
    gram, dots, cand_norms, neighbours = _pipeline(candidates, templates)
    coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours, SIZES, 0.0, constrained)
    for j, k in enumerate(SIZES):
        np.testing.assert_allclose(coefficients[:, j, :k], 1.0 / k, rtol=0, atol=1e-5)
    # Exactly zero data: G == 0 exactly, uniform exactly (to rounding).
    zeros = np.zeros((1, 4))
    coefficients = encode_dictionaries(np.zeros((4, 4)), zeros, np.zeros(1),
                                       np.arange(4, dtype=np.int64)[None, :],
                                       np.array([4], dtype=np.int64), 0.0, constrained)
    np.testing.assert_allclose(coefficients[0, 0], 0.25, rtol=1e-14)


@pytest.mark.parametrize("constrained", [False, True])
def test_large_ridge_approaches_uniform(problem, constrained):
    _, _, (gram, dots, cand_norms, neighbours) = problem
    coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours, SIZES, 1e6, constrained)
    for j, k in enumerate(SIZES):
        np.testing.assert_allclose(coefficients[:, j, :k], 1.0 / k, rtol=0, atol=1e-5)
    weights, *_ = combine_dictionaries(gram, dots, cand_norms, neighbours, coefficients, SIZES,
                                       N_POSITIVE, 1e6, constrained, 1)
    np.testing.assert_allclose(weights, 1.0 / 3, rtol=0, atol=1e-5)


def test_nan_input_gives_nan_not_fallback(problem):
    _, _, (gram, dots, cand_norms, neighbours) = problem
    dots = dots.copy()
    dots[0, neighbours[0, 0]] = np.nan
    for constrained in (False, True):
        coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours, SIZES, 1.0,
                                           constrained)
        assert np.all(np.isnan(coefficients[0, :, 0]))
        assert np.all(np.isfinite(coefficients[1:]))


def test_scatter_codes():
    codes = np.array([[0.5, 0.3, 0.2], [0.1, 0.2, 0.7]])
    neighbours = np.array([[4, 0, 2], [1, 1, 3]], dtype=np.int64)
    full = scatter_codes(codes, neighbours, 5)
    np.testing.assert_array_equal(full, [[0.3, 0, 0.2, 0, 0.5], [0, 0.30000000000000004, 0, 0.7, 0]])
    with pytest.raises(ParameterError, match="neighbour_indices"):
        scatter_codes(codes, neighbours, 4)


@TWO_THREADS
def test_determinism_across_thread_counts():
    candidates, templates = make_problem(15, n_candidates=300, n_templates=80, dim=32)
    gram, dots, cand_norms, neighbours = _pipeline(candidates, templates)
    previous = numba.get_num_threads()
    results = []
    try:
        for n_threads in (1, 2):
            numba.set_num_threads(n_threads)
            run = []
            for ridge, constrained in MODES.values():
                coefficients = encode_dictionaries(gram, dots, cand_norms, neighbours, SIZES,
                                                   ridge, constrained)
                run.append(coefficients)
                run.extend(combine_dictionaries(gram, dots, cand_norms, neighbours, coefficients,
                                                SIZES, N_POSITIVE, ridge, constrained, 2))
            results.append(run)
    finally:
        numba.set_num_threads(previous)
    for one, two in zip(*results):
        assert one.tobytes() == two.tobytes()


def test_parameter_errors(problem):
    _, _, (gram, dots, cand_norms, neighbours) = problem
    args = dict(template_gram=gram, dots=dots, candidate_sq_norms=cand_norms,
                neighbour_indices=neighbours, dictionary_sizes=SIZES, ridge=1.0,
                constrained=False)

    def check(match, **changes):
        with pytest.raises(ParameterError, match=match):
            encode_dictionaries(**{**args, **changes})

    check("template_gram", template_gram=gram[:-1])
    check("dots", dots=dots.astype(np.float32))
    check("C-contiguous", dots=np.asfortranarray(dots))
    check("candidate_sq_norms", candidate_sq_norms=cand_norms[:-1].copy())
    check("neighbour_indices", neighbour_indices=neighbours.astype(np.int32))
    check("neighbour_indices", neighbour_indices=neighbours + 60)
    check("dictionary_sizes", dictionary_sizes=np.array([5, 11], dtype=np.int64))
    check("dictionary_sizes", dictionary_sizes=np.array([0], dtype=np.int64))
    check("dictionary_sizes", dictionary_sizes=[5, 8])
    check("ridge", ridge=-1.0)
    check("ridge", ridge=float("nan"))
    check("constrained", constrained=1)
    coefficients = encode_dictionaries(**args)
    combine_args = dict(template_gram=gram, dots=dots, candidate_sq_norms=cand_norms,
                        neighbour_indices=neighbours, coefficients=coefficients,
                        dictionary_sizes=SIZES, n_positive=N_POSITIVE, ridge=1.0,
                        constrained=False, n_iterations=2)

    def check_combine(match, **changes):
        with pytest.raises(ParameterError, match=match):
            combine_dictionaries(**{**combine_args, **changes})

    check_combine("coefficients", coefficients=coefficients[:, :2].copy())
    check_combine("n_positive", n_positive=61)
    check_combine("n_positive", n_positive=-1)
    check_combine("n_iterations", n_iterations=-1)
    check_combine("n_iterations", n_iterations=1.5)
    check_combine("ridge", ridge=float("inf"))


def _in_turn(candidates, templates, sizes, ridge_c, ridge_w, constrained, n_iterations):
    """The four kernels called one after the other, as the fused one must reproduce."""
    dots = candidate_template_dots(candidates, templates)
    gram = template_gram(templates)
    t_norms = np.ascontiguousarray(np.diag(gram))
    sq_norms = squared_norms(candidates)
    neighbours, sq_distances = nearest_templates(dots, sq_norms, t_norms, int(sizes.max()))
    coefficients = encode_dictionaries(gram, dots, sq_norms, neighbours, sizes, ridge_c, constrained)
    weights, codes, error_positive, error_negative = combine_dictionaries(
        gram, dots, sq_norms, neighbours, coefficients, sizes, N_POSITIVE, ridge_w, constrained, n_iterations)
    return dict(sq_norms=sq_norms, neighbours=neighbours, sq_distances=sq_distances, coefficients=coefficients,
                weights=weights, codes=codes, error_positive=error_positive, error_negative=error_negative), \
        (dots, gram, t_norms)


@pytest.mark.parametrize("ridges, constrained", [((1.0, 0.1), False), ((1.0, 0.1), True), ((0.0, 0.0), False),
                                                  ((0.0, 0.0), True), ((1e-3, 1e-3), False)])
@pytest.mark.parametrize("sizes, n_iterations", [((5, 8, 10), 3), ((8, 3, 5), 1), ((4,), 0)])
def test_code_candidates_equals_the_four_kernels_in_turn_bit_for_bit(ridges, constrained, sizes, n_iterations):
    candidates, templates = make_problem(11, n_candidates=70, n_templates=60, dim=64)
    sizes = np.asarray(sizes, dtype=np.int64)
    expected, (dots, gram, t_norms) = _in_turn(candidates, templates, sizes, *ridges, constrained, n_iterations)
    fused = code_candidates(candidates, dots, gram, t_norms, sizes, N_POSITIVE, *ridges, constrained, n_iterations)
    assert sorted(fused) == sorted(expected)
    for name, value in expected.items():
        assert fused[name].dtype == value.dtype and fused[name].shape == value.shape, name
        np.testing.assert_array_equal(fused[name], value, err_msg=name)


@TWO_THREADS
def test_code_candidates_is_the_same_for_any_thread_count():
    candidates, templates = make_problem(12, n_candidates=301, n_templates=60, dim=64)
    dots = candidate_template_dots(candidates, templates)
    gram = template_gram(templates)
    t_norms = np.ascontiguousarray(np.diag(gram))
    previous = numba.get_num_threads()
    results = []
    try:
        for threads in (1, 2):
            numba.set_num_threads(threads)
            results.append(code_candidates(candidates, dots, gram, t_norms, SIZES, N_POSITIVE, 1.0, 0.1, True, 3))
    finally:
        numba.set_num_threads(previous)
    for name in results[0]:
        np.testing.assert_array_equal(results[0][name], results[1][name], err_msg=name)


def test_code_candidates_checks_its_input():
    candidates, templates = make_problem(13, n_candidates=10, n_templates=30, dim=16, n_positive=10)
    dots = candidate_template_dots(candidates, templates)
    gram = template_gram(templates)
    t_norms = np.ascontiguousarray(np.diag(gram))
    arguments = (candidates, dots, gram, t_norms, SIZES, 4, 1.0, 0.1, False, 3)
    code_candidates(*arguments)
    with pytest.raises(ParameterError, match="candidates has 9 rows"):
        code_candidates(candidates[:9], *arguments[1:])
    with pytest.raises(ParameterError, match="max\\(dictionary_sizes\\) must be >= 1, <= 30"):
        code_candidates(*arguments[:4], np.array([5, 31]), *arguments[5:])
    with pytest.raises(ParameterError, match="ridge_w must be finite"):
        code_candidates(*arguments[:7], -1.0, *arguments[8:])
    with pytest.raises(ParameterError, match="template_sq_norms has 29 entries"):
        code_candidates(*arguments[:3], t_norms[:29], *arguments[4:])
