"""Tests of nrmlc.kernels.distance against the brute-force references."""
from __future__ import annotations

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrmlc.errors import ParameterError
from nrmlc.kernels.distance import candidate_template_dots, nearest_templates, squared_norms, template_gram
from nrmlc.testing.reference import make_problem, reference_dots, reference_nearest, reference_sq_distances


def _tables(candidates, templates):
    dots = candidate_template_dots(candidates, templates)
    gram = template_gram(templates)
    candidate_sq_norms = (candidates.astype(np.float64) ** 2).sum(axis=1)
    return dots, gram, candidate_sq_norms, np.diag(gram).copy()


def test_dots_float32_match_reference():
    candidates, templates = make_problem(0)
    dots = candidate_template_dots(candidates, templates)
    assert dots.dtype == np.float64 and dots.shape == (40, 60) and dots.flags.c_contiguous
    # sgemm accumulates in float32: absolute error ~1e-7 per unit-norm dot.
    np.testing.assert_allclose(dots, reference_dots(candidates, templates), rtol=0, atol=2e-6)


def test_dots_float64_match_reference():
    candidates, templates = make_problem(1)
    candidates, templates = candidates.astype(np.float64), templates.astype(np.float64)
    dots = candidate_template_dots(candidates, templates)
    np.testing.assert_allclose(dots, reference_dots(candidates, templates), rtol=0, atol=1e-14)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_squared_norms_match_reference(dtype):
    candidates, _ = make_problem(3, n_candidates=50, dim=1024)
    vectors = (candidates * 3.0).astype(dtype)
    sq_norms = squared_norms(vectors)
    assert sq_norms.dtype == np.float64 and sq_norms.shape == (50,)
    expected = np.einsum("id,id->i", vectors.astype(np.float64), vectors.astype(np.float64))
    np.testing.assert_allclose(sq_norms, expected, rtol=1e-14, atol=0)
    previous = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = squared_norms(vectors)
    finally:
        numba.set_num_threads(previous)
    assert one.tobytes() == sq_norms.tobytes()
    with pytest.raises(ParameterError, match="vectors"):
        squared_norms(vectors.astype(np.int32))


@pytest.mark.parametrize("n_candidates", [1, 127, 128, 300, 601])
def test_dots_same_bits_whatever_the_thread_split(n_candidates):
    # Row blocks go to different threads; every thread count must give the same bits. Not
    # necessarily those of one product: OpenBLAS's Haswell sgemm gives a row other bits in a
    # call of another size (or with another BLAS thread count), so the oracle is the 1-thread run.
    rng = np.random.default_rng(n_candidates)
    candidates = rng.random((n_candidates, 256)).astype(np.float32)
    templates = rng.random((70, 256)).astype(np.float32)
    previous = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        reference = candidate_template_dots(candidates, templates)
        for n_threads in range(2, numba.config.NUMBA_NUM_THREADS + 1):
            numba.set_num_threads(n_threads)
            assert candidate_template_dots(candidates, templates).tobytes() == reference.tobytes()
    finally:
        numba.set_num_threads(previous)
    np.testing.assert_allclose(reference, reference_dots(candidates, templates), rtol=0, atol=1e-4)


@pytest.mark.parametrize("dtype, atol", [(np.float32, 1e-6), (np.float64, 1e-14)])
def test_template_gram_symmetric_and_in_the_templates_precision(dtype, atol):
    _, templates = make_problem(2)
    templates = templates.astype(dtype)
    gram = template_gram(templates)
    assert gram.dtype == np.float64 and gram.shape == (60, 60)
    np.testing.assert_array_equal(gram, gram.T)
    np.testing.assert_allclose(gram, reference_dots(templates, templates), rtol=0, atol=atol)
    if dtype == np.float32:
        # Float32 products, as the candidate dots: worse than float64 can do.
        assert np.abs(gram - reference_dots(templates, templates)).max() > 1e-12


def test_gram_assembly_reads_one_triangle_of_the_new_block():
    # Symmetric by construction, not by trusting BLAS to write equal triangles: a new block
    # whose lower triangle is garbage must leave no trace in the Gram.
    from nrmlc.kernels.distance import _assemble_gram

    rng = np.random.default_rng(3)
    among_new = rng.random((4, 4))
    upper = np.triu(among_new)
    among_new[np.tril_indices(4, -1)] = -7.0
    gram = np.empty((4, 4))
    _assemble_gram(gram, np.empty((0, 0)), np.full(4, -1, dtype=np.int64), np.arange(4), np.empty(0, dtype=np.int64),
                   among_new, np.empty((4, 0)))
    np.testing.assert_array_equal(gram, gram.T)
    np.testing.assert_array_equal(np.triu(gram), upper)


def _unit_rows(rng, n_rows, dim, dtype):
    rows = rng.random((n_rows, dim))
    return (rows / np.linalg.norm(rows, axis=1, keepdims=True)).astype(dtype)


def _replace_rows(templates, rng, n_new):
    """A template set with the last ``n_new`` rows and one earlier row replaced; the ``kept`` map."""
    updated = templates.copy()
    kept = np.arange(len(templates), dtype=np.int64)
    changed = np.r_[rng.integers(0, len(templates) - n_new), np.arange(len(templates) - n_new, len(templates))]
    updated[changed] = _unit_rows(rng, len(changed), templates.shape[1], templates.dtype)
    kept[changed] = -1
    return updated, kept


@pytest.mark.parametrize("dtype, atol", [(np.float32, 1e-6), (np.float64, 1e-14)])
def test_template_gram_carries_the_rows_that_stayed(dtype, atol):
    rng = np.random.default_rng(4)
    _, templates = make_problem(4)
    templates = templates.astype(dtype)
    previous = template_gram(templates)
    updated, kept = _replace_rows(templates, rng, 25)
    # One row appended as well: the tracker's positives grow until the cap.
    updated = np.ascontiguousarray(np.vstack([updated, _unit_rows(rng, 1, templates.shape[1], dtype)]))
    kept = np.append(kept, -1)
    gram = template_gram(updated, previous, kept)
    np.testing.assert_array_equal(gram, gram.T)
    stayed = np.flatnonzero(kept >= 0)
    np.testing.assert_array_equal(gram[np.ix_(stayed, stayed)], previous[np.ix_(stayed, stayed)])
    np.testing.assert_allclose(gram, reference_dots(updated, updated), rtol=0, atol=atol)
    # Rows may also move: a carried entry follows its template.
    order = rng.permutation(len(templates))
    moved = template_gram(np.ascontiguousarray(templates[order]), previous, order.astype(np.int64))
    np.testing.assert_array_equal(moved, previous[np.ix_(order, order)])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_template_gram_is_bit_identical_across_thread_counts(dtype):
    rng = np.random.default_rng(5)
    templates = _unit_rows(rng, 250, 1024, dtype)
    updated, kept = _replace_rows(templates, rng, 150)
    results = []
    previous_threads = numba.get_num_threads()
    try:
        for n_threads in range(1, numba.config.NUMBA_NUM_THREADS + 1):
            numba.set_num_threads(n_threads)
            full = template_gram(templates)
            results.append((full.tobytes(), template_gram(updated, full, kept).tobytes()))
    finally:
        numba.set_num_threads(previous_threads)
    assert all(result == results[0] for result in results)


def test_template_gram_refuses_a_bad_previous_gram():
    _, templates = make_problem(6)
    gram = template_gram(templates)
    kept = np.arange(60, dtype=np.int64)
    with pytest.raises(ParameterError, match="together"):
        template_gram(templates, gram)
    with pytest.raises(ParameterError, match="square"):
        template_gram(templates, np.ascontiguousarray(gram[:, :10]), kept)
    with pytest.raises(ParameterError, match="kept"):
        template_gram(templates, gram, kept[:-1].copy())
    with pytest.raises(ParameterError, match="kept must hold rows"):
        template_gram(templates, gram[:30, :30].copy(), kept)
    with pytest.raises(ParameterError, match="kept"):
        template_gram(templates, gram, kept.astype(np.int32))


@pytest.mark.parametrize("k", [1, 5, 10, 60])
def test_nearest_matches_brute_force(k):
    candidates, templates = make_problem(3)
    # float64 products so that the expansion is accurate to ~1e-15.
    dots, _, cand_norms, tmpl_norms = _tables(candidates.astype(np.float64),
                                               templates.astype(np.float64))
    indices, sq_distances = nearest_templates(dots, cand_norms, tmpl_norms, k)
    assert indices.shape == (40, k) and indices.dtype == np.int64
    exact = reference_sq_distances(candidates, templates)
    _, expected = reference_nearest(exact, k)
    np.testing.assert_allclose(sq_distances, expected, rtol=0, atol=1e-13)
    # Robust to near-ties: the chosen templates really are at those distances.
    np.testing.assert_allclose(np.take_along_axis(exact, indices, axis=1), expected,
                               rtol=0, atol=1e-13)
    assert np.all(np.diff(sq_distances, axis=1) >= 0)
    assert all(len(set(row)) == k for row in indices.tolist())


def test_nearest_with_float32_dots():
    candidates, templates = make_problem(4)
    dots, _, cand_norms, tmpl_norms = _tables(candidates, templates)
    indices, sq_distances = nearest_templates(dots, cand_norms, tmpl_norms, 10)
    exact = reference_sq_distances(candidates, templates)
    _, expected = reference_nearest(exact, 10)
    np.testing.assert_allclose(sq_distances, expected, rtol=0, atol=5e-6)
    np.testing.assert_allclose(np.take_along_axis(exact, indices, axis=1), expected,
                               rtol=0, atol=1e-5)


@settings(max_examples=50, deadline=None)
@given(
    n_candidates=st.integers(1, 6),
    n_templates=st.integers(1, 25),
    k_fraction=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_nearest_exact_ties_match_stable_argsort(n_candidates, n_templates, k_fraction, seed):
    # Small integers: every distance is computed exactly, with many ties, so the
    # result must equal the stable argsort bit for bit.
    rng = np.random.default_rng(seed)
    k = 1 + int(k_fraction * (n_templates - 1))
    dots = rng.integers(-3, 4, (n_candidates, n_templates)).astype(np.float64)
    cand_norms = rng.integers(0, 4, n_candidates).astype(np.float64)
    tmpl_norms = rng.integers(0, 4, n_templates).astype(np.float64)
    indices, sq_distances = nearest_templates(dots, cand_norms, tmpl_norms, k)
    distances = np.maximum(cand_norms[:, None] + tmpl_norms[None, :] - 2.0 * dots, 0.0)
    expected_indices, expected_distances = reference_nearest(distances, k)
    np.testing.assert_array_equal(indices, expected_indices)
    np.testing.assert_array_equal(sq_distances, expected_distances)


def test_nearest_duplicate_templates_prefer_lower_index():
    candidates, templates = make_problem(5)
    dots, _, cand_norms, tmpl_norms = _tables(candidates, templates)
    # Template t+60 is a copy of template t (tables duplicated, so the ties are exact).
    dots = np.ascontiguousarray(np.hstack([dots, dots]))
    tmpl_norms = np.concatenate([tmpl_norms, tmpl_norms])
    indices, _ = nearest_templates(dots, cand_norms, tmpl_norms, 2)
    # Each template's copy has exactly the same distance; the lower index comes first.
    assert np.all(indices[:, 1] == indices[:, 0] + 60)


def test_nearest_nan_ranks_last():
    dots = np.array([[0.5, np.nan, 0.9, 0.1]])
    indices, sq_distances = nearest_templates(dots, np.ones(1), np.ones(4), 4)
    np.testing.assert_array_equal(indices, [[2, 0, 3, 1]])
    assert np.isinf(sq_distances[0, 3])


def test_determinism_across_thread_counts():
    rng = np.random.default_rng(6)
    candidates = rng.random((300, 32)).astype(np.float32)
    templates = rng.random((120, 32)).astype(np.float32)
    dots, _, cand_norms, tmpl_norms = _tables(candidates, templates)
    previous = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = nearest_templates(dots, cand_norms, tmpl_norms, 10)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        two = nearest_templates(dots, cand_norms, tmpl_norms, 10)
    finally:
        numba.set_num_threads(previous)
    assert one[0].tobytes() == two[0].tobytes()
    assert one[1].tobytes() == two[1].tobytes()


def test_parameter_errors():
    candidates, templates = make_problem(7)
    with pytest.raises(ParameterError, match="candidates"):
        candidate_template_dots(candidates.astype(np.int32), templates)
    with pytest.raises(ParameterError, match="templates"):
        candidate_template_dots(candidates, templates.astype(np.float64))
    with pytest.raises(ParameterError, match="C-contiguous"):
        candidate_template_dots(np.asfortranarray(candidates), templates)
    with pytest.raises(ParameterError, match="dim"):
        candidate_template_dots(candidates, templates[:, :10].copy())
    with pytest.raises(ParameterError, match="templates"):
        template_gram(templates[0])
    dots, _, cand_norms, tmpl_norms = _tables(candidates, templates)
    with pytest.raises(ParameterError, match="k must be"):
        nearest_templates(dots, cand_norms, tmpl_norms, 0)
    with pytest.raises(ParameterError, match="k must be"):
        nearest_templates(dots, cand_norms, tmpl_norms, 61)
    with pytest.raises(ParameterError, match="k must be an integer"):
        nearest_templates(dots, cand_norms, tmpl_norms, 2.0)
    with pytest.raises(ParameterError, match="dots"):
        nearest_templates(dots.astype(np.float32), cand_norms, tmpl_norms, 3)
    with pytest.raises(ParameterError, match="candidate_sq_norms"):
        nearest_templates(dots, cand_norms[:-1].copy(), tmpl_norms, 3)
    with pytest.raises(ParameterError, match="template_sq_norms"):
        nearest_templates(dots, cand_norms, tmpl_norms[:-1].copy(), 3)
    with pytest.raises(ParameterError, match="C-contiguous"):
        nearest_templates(dots[:, ::2], cand_norms, tmpl_norms[::2].copy(), 3)


def test_product_block_no_worker_has_started_is_computed_by_the_caller():
    # The gemm worker thread is kept busy (as on a loaded machine, where it may not get a
    # core): the caller takes its block instead of waiting, with the same result.
    import threading

    from nrmlc.kernels import distance

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs 2 numba threads")
    rng = np.random.default_rng(3)
    candidates = rng.random((300, 64), dtype=np.float32)
    templates = rng.random((40, 64), dtype=np.float32)
    previous = numba.get_num_threads()
    release = threading.Event()
    try:
        numba.set_num_threads(2)
        expected = candidate_template_dots(candidates, templates)
        blocker = distance._thread_pool(1).submit(release.wait, 30)
        dots = candidate_template_dots(candidates, templates)
        assert not blocker.done()  # the caller did not wait for the busy worker
    finally:
        release.set()
        numba.set_num_threads(previous)
    np.testing.assert_array_equal(dots, expected)
