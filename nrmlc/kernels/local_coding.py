"""Approximated LLC of each candidate's local patches on a small atom dictionary.

The generative term (:mod:`nrmlc.tracker.generative`) codes every local patch of a
candidate on its ``k`` nearest atoms with the regularised sum-to-one coder of
:mod:`nrmlc.kernels.coding` on one dictionary. The row work is the general coder's own
(``_nearest_row`` picks the atoms, ``_encode_row`` solves); what this kernel adds is the
layout: one parallel pass over candidates, each coding its ``n_local`` rows, and the
reconstruction error ``c'Gc`` of each, which SCM's occlusion test needs. The products come
from one single-threaded ``sgemm`` (see ``_run``).
``tests/test_local_coding.py`` checks the results against
:func:`nrmlc.kernels.coding.code_candidates`.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from nrmlc.config import NUMBA_FLAGS, PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.kernels.checks import check_array, check_int, check_nonnegative_real
from nrmlc.kernels.coding import _encode_row, _encode_work
from nrmlc.kernels.distance import _nearest_row, _one_blas_thread

__all__ = ["code_local_patches", "match_local_histogram"]


@njit(**NUMBA_FLAGS)
def _code_local_row(dots_row, atom_gram, atom_sq_norms, size, ridge, members, distances, gram, chol, real_work,
                    int_work, coefficients, neighbours_out, codes_out):
    """Code one unit local patch given its dots with the atoms (the general coder's row
    functions on one dictionary of ``size[0]`` atoms); returns its squared error."""
    k = members.shape[0]
    _nearest_row(dots_row, 1.0, atom_sq_norms, members, distances)
    _encode_row(atom_gram, dots_row, 1.0, members, size, ridge, False, gram, chol, real_work, int_work,
                coefficients)
    # _encode_row leaves the Gram of (y - atom) on the members in ``gram``: the error is c'Gc.
    error = 0.0
    for r in range(k):
        neighbours_out[r] = members[r]
        codes_out[r] = coefficients[0, r]
        for q in range(k):
            error += coefficients[0, r] * gram[r, q] * coefficients[0, q]
    return max(error, 0.0)


@njit(**NUMBA_FLAGS)
def _intersect_row(histogram, histogram_sums, occlusion_error, neighbours, codes, errors):
    """SCM's similarity of one candidate's local codes (n_local, k) to the template histogram
    (n_local, n_atoms): the histogram intersection over the visible local patches (error
    below ``occlusion_error``), each histogram normalised over them; returns it and the
    number of occluded local patches."""
    n_local, k = codes.shape
    candidate_sum = 0.0
    template_sum = 0.0
    n_occluded = 0
    for j in range(n_local):
        if errors[j] < occlusion_error:
            template_sum += histogram_sums[j]
            for r in range(k):
                candidate_sum += abs(codes[j, r])
        else:
            n_occluded += 1
    overlap = 0.0
    if candidate_sum > 0.0 and template_sum > 0.0:
        # Only the candidate's own atoms can contribute to the intersection.
        for j in range(n_local):
            if errors[j] < occlusion_error:
                for r in range(k):
                    overlap += min(abs(codes[j, r]) / candidate_sum, histogram[j, neighbours[j, r]] / template_sum)
    return overlap, n_occluded


@njit(**PARALLEL_FLAGS)
def _code_local_patches(dots, atom_gram, atom_sq_norms, size, ridge, histogram, histogram_sums, occlusion_error,
                        match, members, distances, gram, chol, real_work, int_work, coefficients, neighbours, codes,
                        errors, overlap, n_occluded):
    n_candidates, n_local = dots.shape[0], dots.shape[1]
    for i in prange(n_candidates):
        for j in range(n_local):
            errors[i, j] = _code_local_row(dots[i, j], atom_gram, atom_sq_norms, size, ridge, members[i],
                                           distances[i], gram[i], chol[i], real_work[i], int_work[i],
                                           coefficients[i], neighbours[i, j], codes[i, j])
        if match:
            overlap[i], n_occluded[i] = _intersect_row(histogram, histogram_sums, occlusion_error, neighbours[i],
                                                       codes[i], errors[i])


def _check_local(local: np.ndarray, atoms: np.ndarray, atom_gram: np.ndarray, k: int, ridge: float) -> tuple:
    """Checked (k, ridge) of :func:`code_local_patches`' arguments."""
    check_array("local", local, np.float32, 3)
    check_array("atoms", atoms, np.float64, 2)
    check_array("atom_gram", atom_gram, np.float64, 2)
    n, n_local, dim = local.shape
    n_atoms = atoms.shape[0]
    if atoms.shape[1] != dim or atom_gram.shape != (n_atoms, n_atoms):
        raise ParameterError(f"atoms {atoms.shape} and atom_gram {atom_gram.shape} do not fit local "
                             f"patches of length {dim}")
    k = check_int("k", k, 1, n_atoms)
    ridge = check_nonnegative_real("ridge", ridge)
    if ridge <= 0:
        raise ParameterError(f"ridge must be > 0, got {ridge}")
    return k, ridge


def _run(local, atoms, atom_gram, k, ridge, histogram, histogram_sums, occlusion_error, match) -> dict:
    n, n_local, dim = local.shape
    # One single-threaded sgemm, widened exactly in the kernel: a plain ``@`` let OpenBLAS's
    # threads spin on the cores the next kernels need, and splitting these few rows over
    # threads (as candidate_template_dots does) cost more than the product.
    dots = np.empty((n * n_local, atoms.shape[0]), dtype=np.float32)
    with _one_blas_thread():
        np.matmul(local.reshape(n * n_local, dim), atoms.T.astype(np.float32), out=dots)
    dots = dots.reshape(n, n_local, atoms.shape[0])
    out = dict(neighbours=np.empty((n, n_local, k), dtype=np.int64), codes=np.empty((n, n_local, k)),
               errors=np.empty((n, n_local)), overlap=np.zeros(n), n_occluded=np.zeros(n, dtype=np.int64))
    _code_local_patches(dots, atom_gram, np.ascontiguousarray(np.diag(atom_gram)), np.array([k], dtype=np.int64),
                        ridge, histogram, histogram_sums, occlusion_error, match, np.empty((n, k), dtype=np.int64),
                        np.empty((n, k)), *_encode_work(n, k), np.empty((n, 1, k)), out["neighbours"], out["codes"],
                        out["errors"], out["overlap"], out["n_occluded"])
    return out


def code_local_patches(local: np.ndarray, atoms: np.ndarray, atom_gram: np.ndarray, k: int,
                       ridge: float) -> tuple:
    """Code each unit local patch on its ``k`` nearest unit atoms.

    Parameters
    ----------
    local : ndarray, shape (n_candidates, n_local, dim), float32, unit rows
    atoms : ndarray, shape (n_atoms, dim), float64, unit rows
    atom_gram : ndarray, shape (n_atoms, n_atoms), float64
        ``atoms @ atoms.T``.
    k : int
        Atoms per code, 1 <= k <= n_atoms.
    ridge : float
        The coder's ``lambda`` (> 0).

    Returns
    -------
    neighbours : (n_candidates, n_local, k) int64
        Each patch's atoms, nearest first.
    codes : (n_candidates, n_local, k) float64
        Its code on them (sums to one).
    errors : (n_candidates, n_local) float64
        Its squared reconstruction error.
    """
    k, ridge = _check_local(local, atoms, atom_gram, k, ridge)
    empty = np.zeros((1, 1))
    out = _run(local, atoms, atom_gram, k, ridge, empty, empty[0], 0.0, False)
    return out["neighbours"], out["codes"], out["errors"]


def match_local_histogram(local: np.ndarray, atoms: np.ndarray, atom_gram: np.ndarray, k: int, ridge: float,
                          histogram: np.ndarray, occlusion_error: float) -> dict:
    """:func:`code_local_patches`, then SCM's similarity of each candidate to a template histogram.

    Parameters
    ----------
    local, atoms, atom_gram, k, ridge
        As :func:`code_local_patches`.
    histogram : ndarray, shape (n_local, n_atoms), float64
        The template's codes, one row per local patch.
    occlusion_error : float
        A local patch whose squared error is not below this counts as occluded: it leaves
        both histograms.

    Returns
    -------
    dict with ``neighbours``, ``codes``, ``errors`` as :func:`code_local_patches`,
    ``overlap (n_candidates,)``, the intersection of the candidate's |codes| with the
    template's over the visible local patches, each normalised to sum 1 over them (0 where
    none is visible), and ``n_occluded (n_candidates,)``.
    """
    k, ridge = _check_local(local, atoms, atom_gram, k, ridge)
    check_array("histogram", histogram, np.float64, 2)
    if histogram.shape != (local.shape[1], atoms.shape[0]):
        raise ParameterError(f"histogram is {histogram.shape}, expected (n_local, n_atoms) = "
                             f"{(local.shape[1], atoms.shape[0])}")
    occlusion_error = check_nonnegative_real("occlusion_error", occlusion_error)
    return _run(local, atoms, atom_gram, k, ridge, histogram, histogram.sum(axis=1), occlusion_error, True)
