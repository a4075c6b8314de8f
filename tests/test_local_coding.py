"""Tests of nrmlc.kernels.local_coding against the general coder and by hand."""
from __future__ import annotations

import numpy as np
import pytest

from nrmlc.errors import ParameterError
from nrmlc.kernels.coding import code_candidates
from nrmlc.kernels.local_coding import code_local_patches, match_local_histogram


def _unit(rng, shape, dtype):
    rows = rng.standard_normal(shape)
    return (rows / np.linalg.norm(rows, axis=-1, keepdims=True)).astype(dtype)


@pytest.mark.parametrize("ridge", [1.0, 0.01])
@pytest.mark.parametrize("k", [1, 3, 5])
def test_matches_the_general_coder_on_one_dictionary(ridge, k):
    rng = np.random.default_rng(0)
    local = _unit(rng, (7, 11, 36), np.float32)
    atoms = _unit(rng, (20, 36), np.float64)
    gram = atoms @ atoms.T
    neighbours, codes, errors = code_local_patches(local, atoms, gram, k, ridge)
    rows = local.reshape(-1, 36)
    dots = np.ascontiguousarray(rows @ atoms.T.astype(np.float32)).astype(np.float64)
    reference = code_candidates(rows, dots, gram, np.diag(gram).copy(), np.array([k]), len(atoms),
                                ridge, 0.1, False, 1)
    np.testing.assert_array_equal(neighbours.reshape(-1, k), reference["neighbours"])
    np.testing.assert_allclose(codes.reshape(-1, k), reference["codes"], rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(errors.reshape(-1), reference["error_positive"], rtol=1e-6, atol=1e-9)


def test_codes_sum_to_one_and_the_error_is_the_residual():
    rng = np.random.default_rng(1)
    local = _unit(rng, (3, 4, 9), np.float32)
    atoms = _unit(rng, (6, 9), np.float64)
    neighbours, codes, errors = code_local_patches(local, atoms, atoms @ atoms.T, 3, 0.5)
    np.testing.assert_allclose(codes.sum(axis=2), 1.0, rtol=1e-12)
    reconstruction = np.einsum("nlk,nlkd->nld", codes, atoms[neighbours])
    residual = ((local.astype(np.float64) - reconstruction) ** 2).sum(axis=2)
    np.testing.assert_allclose(errors, residual, rtol=1e-5, atol=1e-6)
    dots = local.astype(np.float64) @ atoms.T
    assert np.all(np.take_along_axis(dots, neighbours[:, :, :1], axis=2) >= dots.max(axis=2, keepdims=True) - 1e-6)


def test_an_atom_reconstructs_itself():
    atoms = np.eye(4)
    local = np.eye(4, dtype=np.float32)[None]
    neighbours, codes, errors = code_local_patches(local, atoms, atoms @ atoms.T, 1, 1.0)
    np.testing.assert_array_equal(neighbours[0, :, 0], np.arange(4))
    np.testing.assert_allclose(errors, 0.0, atol=1e-12)


def _numpy_intersection(neighbours, codes, errors, histogram, occlusion_error):
    """The oracle: SCM's histogram intersection over the visible local patches, in numpy."""
    visible = errors < occlusion_error                                           # (n, n_local)
    candidate = np.abs(codes) * visible[:, :, None]                              # (n, n_local, k)
    template = np.take_along_axis(histogram[None], neighbours, axis=2) * visible[:, :, None]
    candidate_sum = candidate.sum(axis=(1, 2))
    template_sum = (histogram.sum(axis=1)[None, :] * visible).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        overlap = np.minimum(candidate / candidate_sum[:, None, None],
                             template / template_sum[:, None, None]).sum(axis=(1, 2))
    return np.where(candidate_sum > 0, np.nan_to_num(overlap), 0.0), (~visible).sum(axis=1)


def test_the_histogram_match_agrees_with_numpy_and_counts_the_occluded():
    rng = np.random.default_rng(3)
    local = _unit(rng, (6, 12, 16), np.float32)
    atoms = _unit(rng, (10, 16), np.float64)
    gram = atoms @ atoms.T
    neighbours, codes, errors = code_local_patches(local, atoms, gram, 3, 1.0)
    histogram = np.zeros((12, 10))
    np.put_along_axis(histogram, neighbours[0], np.abs(codes[0]), axis=1)  # the first candidate is the template
    threshold = np.median(errors)  # about half the local patches count as occluded
    matched = match_local_histogram(local, atoms, gram, 3, 1.0, histogram, threshold)
    for name, value in (("neighbours", neighbours), ("codes", codes), ("errors", errors)):
        np.testing.assert_array_equal(matched[name], value)
    overlap, n_occluded = _numpy_intersection(neighbours, codes, errors, histogram, threshold)
    np.testing.assert_allclose(matched["overlap"], overlap, rtol=1e-12)
    np.testing.assert_array_equal(matched["n_occluded"], n_occluded)
    assert matched["overlap"][0] == pytest.approx(1.0) and 0 < n_occluded.sum() < errors.size
    everything_occluded = match_local_histogram(local, atoms, gram, 3, 1.0, histogram, 0.0)
    np.testing.assert_array_equal(everything_occluded["overlap"], 0.0)
    np.testing.assert_array_equal(everything_occluded["n_occluded"], 12)
    with pytest.raises(ParameterError, match="histogram"):
        match_local_histogram(local, atoms, gram, 3, 1.0, histogram[:5], threshold)


@pytest.mark.parametrize("change, message", [
    (dict(k=0), "k"), (dict(k=7), "k"), (dict(ridge=0.0), "ridge"), (dict(ridge=-1.0), "ridge"),
    (dict(atoms=np.ones((6, 5))), "atoms"), (dict(local=np.ones((2, 3, 9))), "local"),
])
def test_bad_input_is_refused_with_its_name(change, message):
    rng = np.random.default_rng(2)
    arguments = dict(local=_unit(rng, (2, 3, 9), np.float32), atoms=_unit(rng, (6, 9), np.float64), k=3, ridge=1.0)
    arguments.update(change)
    atoms = arguments["atoms"]
    with pytest.raises(ParameterError, match=message):
        code_local_patches(arguments["local"], atoms, atoms @ atoms.T, arguments["k"], arguments["ridge"])


@pytest.mark.parametrize("shape", [(0, 12, 16), (3, 0, 16)])
def test_no_candidates_or_no_local_patches_give_empty_results(shape):
    """Nothing to code is an empty result of the right shapes, not numpy's reshape error."""
    rng = np.random.default_rng(4)
    atoms = _unit(rng, (10, 16), np.float64)
    gram = atoms @ atoms.T
    local = np.zeros(shape, np.float32)
    neighbours, codes, errors = code_local_patches(local, atoms, gram, 3, 1.0)
    assert neighbours.shape == codes.shape == shape[:2] + (3,) and errors.shape == shape[:2]
    matched = match_local_histogram(local, atoms, gram, 3, 1.0, np.zeros((shape[1], 10)), 0.5)
    assert matched["overlap"].shape == matched["n_occluded"].shape == (shape[0],)
