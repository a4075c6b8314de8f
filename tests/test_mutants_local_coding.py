"""Tests written against the mutants mutmut left alive in nrmlc/kernels/local_coding.py.

``make mutate`` (docs/research/mutation.md) only mutates the checked Python wrappers, not the
numba kernels, so what these pin is the wrappers' own work: every refusal of
``code_local_patches`` and ``match_local_histogram`` with its whole message (the argument's
name and, for the histogram, the shape it expected), each bound at and just past its edge,
and the dtypes of the arrays ``_run`` hands back. Values are checked against a numpy
float64 oracle, never against the wrappers' own output.
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from nrmlc.errors import ParameterError
from nrmlc.kernels.local_coding import code_local_patches, match_local_histogram

N, N_LOCAL, DIM, N_ATOMS = 2, 3, 9, 6  # all different, so a message naming the wrong axis shows


def refused(message):
    return pytest.raises(ParameterError, match=f"^{re.escape(message)}$")


def _unit(rng, shape, dtype):
    rows = rng.standard_normal(shape)
    return (rows / np.linalg.norm(rows, axis=-1, keepdims=True)).astype(dtype)


def _inputs(seed=0):
    rng = np.random.default_rng(seed)
    local = _unit(rng, (N, N_LOCAL, DIM), np.float32)
    atoms = _unit(rng, (N_ATOMS, DIM), np.float64)
    return local, atoms, atoms @ atoms.T


def _match(local, atoms, atom_gram, k, ridge):
    """match_local_histogram with a histogram of the right shape and a valid occlusion_error."""
    return match_local_histogram(local, atoms, atom_gram, k, ridge, np.ones((N_LOCAL, N_ATOMS)), 0.5)


@pytest.fixture(params=[code_local_patches, _match], ids=["code_local_patches", "match_local_histogram"])
def wrapper(request):
    """Both public wrappers: each runs ``_check_local`` first."""
    return request.param


# -- _check_local: the arrays, each refusal naming its argument --------------------------------

def test_local_atoms_and_atom_gram_refusals_name_the_argument(wrapper):
    local, atoms, gram = _inputs()
    with refused("local must have dtype float32, got float64"):
        wrapper(local.astype(np.float64), atoms, gram, 3, 1.0)
    with refused("local must be 3-D, got shape (6, 9)"):
        wrapper(local.reshape(-1, DIM), atoms, gram, 3, 1.0)
    with refused("local must be a numpy array, got list"):
        wrapper(local.tolist(), atoms, gram, 3, 1.0)
    with refused("atoms must have dtype float64, got float32"):
        wrapper(local, atoms.astype(np.float32), gram, 3, 1.0)
    with refused("atoms must be 2-D, got shape (54,)"):
        wrapper(local, atoms.ravel(), gram, 3, 1.0)
    with refused("atoms must be C-contiguous"):
        wrapper(local, np.asfortranarray(atoms), gram, 3, 1.0)
    with refused("atom_gram must have dtype float64, got float32"):
        wrapper(local, atoms, gram.astype(np.float32), 3, 1.0)
    with refused("atom_gram must be 2-D, got shape (36,)"):
        wrapper(local, atoms, gram.ravel(), 3, 1.0)
    with refused("atom_gram must be a numpy array, got list"):
        wrapper(local, atoms, gram.tolist(), 3, 1.0)


def test_atoms_and_atom_gram_must_fit_the_local_patches(wrapper):
    local, atoms, gram = _inputs()
    with refused("atoms (6, 8) and atom_gram (6, 6) do not fit local patches of length 9"):
        wrapper(local, np.ascontiguousarray(atoms[:, :8]), gram, 3, 1.0)
    with refused("atoms (6, 9) and atom_gram (5, 5) do not fit local patches of length 9"):
        wrapper(local, atoms, np.ascontiguousarray(gram[:5, :5]), 3, 1.0)
    with refused("atoms (6, 9) and atom_gram (6, 5) do not fit local patches of length 9"):
        wrapper(local, atoms, np.ascontiguousarray(gram[:, :5]), 3, 1.0)


# -- _check_local: k and ridge at and past their edges -----------------------------------------

@pytest.mark.parametrize("k", [1, N_ATOMS])
def test_k_edges_are_in(k):
    local, atoms, gram = _inputs()
    neighbours, codes, errors = code_local_patches(local, atoms, gram, k, 1.0)
    assert neighbours.shape == codes.shape == (N, N_LOCAL, k) and errors.shape == (N, N_LOCAL)


@pytest.mark.parametrize("k, message", [
    (0, "k must be >= 1, <= 6, got 0"),
    (N_ATOMS + 1, "k must be >= 1, <= 6, got 7"),
    (2.0, "k must be an integer, got 2.0"),
    (True, "k must be an integer, got True"),
])
def test_k_refusals(wrapper, k, message):
    local, atoms, gram = _inputs()
    with refused(message):
        wrapper(local, atoms, gram, k, 1.0)


def test_ridge_just_above_zero_is_in():
    local, atoms, gram = _inputs()
    _, codes, _ = code_local_patches(local, atoms, gram, 3, 1e-300)
    assert np.all(np.isfinite(codes))


@pytest.mark.parametrize("ridge, message", [
    (0.0, "ridge must be > 0, got 0.0"),
    (0, "ridge must be > 0, got 0.0"),
    (-1e-300, "ridge must be finite and >= 0, got -1e-300"),
    (float("nan"), "ridge must be finite and >= 0, got nan"),
    (float("inf"), "ridge must be finite and >= 0, got inf"),
    (None, "ridge must be a real number, got None"),
    ("1", "ridge must be a real number, got '1'"),
])
def test_ridge_refusals(wrapper, ridge, message):
    local, atoms, gram = _inputs()
    with refused(message):
        wrapper(local, atoms, gram, 3, ridge)


# -- match_local_histogram: the histogram and occlusion_error --------------------------------

def test_histogram_refusals_name_it_and_the_expected_shape():
    local, atoms, gram = _inputs()
    good = np.ones((N_LOCAL, N_ATOMS))
    with refused("histogram must have dtype float64, got float32"):
        match_local_histogram(local, atoms, gram, 3, 1.0, good.astype(np.float32), 0.5)
    with refused("histogram must be 2-D, got shape (18,)"):
        match_local_histogram(local, atoms, gram, 3, 1.0, good.ravel(), 0.5)
    with refused("histogram must be C-contiguous"):
        match_local_histogram(local, atoms, gram, 3, 1.0, np.asfortranarray(good), 0.5)
    # (n_local, n_atoms) = (3, 6) with dim 9: neither the patch length nor the atoms' length is expected
    with refused("histogram is (6, 3), expected (n_local, n_atoms) = (3, 6)"):
        match_local_histogram(local, atoms, gram, 3, 1.0, np.ones((N_ATOMS, N_LOCAL)), 0.5)
    with refused("histogram is (3, 9), expected (n_local, n_atoms) = (3, 6)"):
        match_local_histogram(local, atoms, gram, 3, 1.0, np.ones((N_LOCAL, DIM)), 0.5)
    with refused("histogram is (9, 6), expected (n_local, n_atoms) = (3, 6)"):
        match_local_histogram(local, atoms, gram, 3, 1.0, np.ones((DIM, N_ATOMS)), 0.5)


@pytest.mark.parametrize("occlusion_error, message", [
    (-1e-300, "occlusion_error must be finite and >= 0, got -1e-300"),
    (float("inf"), "occlusion_error must be finite and >= 0, got inf"),
    (float("nan"), "occlusion_error must be finite and >= 0, got nan"),
    (False, "occlusion_error must be a real number, got False"),
    ("1", "occlusion_error must be a real number, got '1'"),
])
def test_occlusion_error_refusals(occlusion_error, message):
    local, atoms, gram = _inputs()
    with refused(message):
        match_local_histogram(local, atoms, gram, 3, 1.0, np.ones((N_LOCAL, N_ATOMS)), occlusion_error)


# -- _run: what it hands back ---------------------------------------------------------------------

def test_match_returns_int64_occlusion_counts_and_float64_values():
    """n_occluded is a count (int64, like neighbours), checked against a numpy count of the
    float64 residuals; the other outputs keep their documented dtypes and shapes."""
    local, atoms, gram = _inputs(1)
    histogram = np.ones((N_LOCAL, N_ATOMS))
    everything = match_local_histogram(local, atoms, gram, 2, 0.5, histogram, 0.0)
    nothing = match_local_histogram(local, atoms, gram, 2, 0.5, histogram, 1e300)
    # The oracle: the squared residual of each patch's code, in float64.
    neighbours, codes = nothing["neighbours"], nothing["codes"]
    reconstruction = np.einsum("nlk,nlkd->nld", codes, atoms[neighbours])
    residual = ((local.astype(np.float64) - reconstruction) ** 2).sum(axis=2)
    np.testing.assert_allclose(nothing["errors"], residual, rtol=1e-5, atol=1e-6)
    middle = np.sort(residual, axis=None)[N * N_LOCAL // 2 - 1:N * N_LOCAL // 2 + 1]
    assert middle[1] - middle[0] > 1e-3  # far wider than the kernel's float32 dots can move an error
    threshold = float(middle.mean())  # half the patches count as occluded
    some = match_local_histogram(local, atoms, gram, 2, 0.5, histogram, threshold)
    for result, expected in ((everything, np.full(N, N_LOCAL)), (nothing, np.zeros(N)),
                             (some, (residual >= threshold).sum(axis=1))):
        assert result["n_occluded"].dtype == np.int64 and result["n_occluded"].shape == (N,)
        np.testing.assert_array_equal(result["n_occluded"], expected)
        assert result["neighbours"].dtype == np.int64 and result["neighbours"].shape == (N, N_LOCAL, 2)
        assert result["codes"].dtype == np.float64 and result["codes"].shape == (N, N_LOCAL, 2)
        assert result["errors"].dtype == np.float64 and result["errors"].shape == (N, N_LOCAL)
        assert result["overlap"].dtype == np.float64 and result["overlap"].shape == (N,)
    assert some["n_occluded"].sum() == N * N_LOCAL // 2
