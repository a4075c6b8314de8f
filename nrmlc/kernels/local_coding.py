"""Approximated LLC of each candidate's local patches on a small atom dictionary.

The generative term (:mod:`nrmlc.tracker.generative`) codes every 6x6 local patch of a
candidate on its ``k`` nearest atoms, with the regularised sum-to-one coder of
:mod:`nrmlc.kernels.coding` (``c = (G + ridge I)^{-1} 1 / 1'(G + ridge I)^{-1} 1`` with
``G[a, b] = AA[u_a, u_b] - YA[u_a] - YA[u_b] + |y|^2``). Its results agree with
:func:`nrmlc.kernels.coding.code_candidates` on one dictionary (``tests/test_local_coding.py``),
but this kernel skips the general coder's machinery (nested dictionaries, their weights, the
jitter and refinement that a zero ridge needs): with the general coder the tracker with the
term ran at 31 frames/s on 2 workers in the development screening, with this kernel at 52
(docs/FINDINGS.md, round 13). The ``O(dim)`` products come from one BLAS call, as in
:mod:`nrmlc.kernels.distance`.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from nrmlc.config import NUMBA_FLAGS, PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.kernels.checks import check_array, check_int, check_nonnegative_real

__all__ = ["code_local_patches"]


@njit(**NUMBA_FLAGS)
def _code_local_row(dots_row, atom_gram, k, ridge, members, gram, chol, solution, neighbours_out, codes_out):
    """Code one unit local patch given its dots with the atoms; returns its squared error."""
    n_atoms = dots_row.shape[0]
    # The k largest dots, in descending order (nearest first for unit atoms and patches).
    for r in range(k):
        members[r] = -1
    for a in range(n_atoms):
        value = dots_row[a]
        if members[k - 1] >= 0 and value <= dots_row[members[k - 1]]:
            continue
        position = k - 1
        while position > 0 and (members[position - 1] < 0 or value > dots_row[members[position - 1]]):
            members[position] = members[position - 1]
            position -= 1
        members[position] = a
    for r in range(k):
        for q in range(r + 1):
            value = atom_gram[members[r], members[q]] - dots_row[members[r]] - dots_row[members[q]] + 1.0
            gram[r, q] = value
            gram[q, r] = value
    for r in range(k):
        for q in range(r + 1):
            value = gram[r, q]
            if q == r:
                value += ridge
            for p in range(q):
                value -= chol[r, p] * chol[q, p]
            if q == r:
                chol[r, r] = np.sqrt(max(value, 1e-300))
            else:
                chol[r, q] = value / chol[q, q]
    for r in range(k):
        value = 1.0
        for p in range(r):
            value -= chol[r, p] * solution[p]
        solution[r] = value / chol[r, r]
    total = 0.0
    for r in range(k - 1, -1, -1):
        value = solution[r]
        for p in range(r + 1, k):
            value -= chol[p, r] * solution[p]
        solution[r] = value / chol[r, r]
        total += solution[r]
    error = 0.0
    for r in range(k):
        solution[r] /= total
    for r in range(k):
        neighbours_out[r] = members[r]
        codes_out[r] = solution[r]
        for q in range(k):
            error += solution[r] * gram[r, q] * solution[q]
    return max(error, 0.0)


@njit(**PARALLEL_FLAGS)
def _code_local_patches(dots, atom_gram, k, ridge, members, gram, chol, solution, neighbours, codes, errors):
    n_candidates, n_local = dots.shape[0], dots.shape[1]
    for i in prange(n_candidates):
        for j in range(n_local):
            errors[i, j] = _code_local_row(dots[i, j], atom_gram, k, ridge, members[i], gram[i], chol[i],
                                           solution[i], neighbours[i, j], codes[i, j])


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
    dots = (local.reshape(n * n_local, dim) @ atoms.T.astype(np.float32)).astype(np.float64).reshape(n, n_local, n_atoms)
    neighbours = np.empty((n, n_local, k), dtype=np.int64)
    codes = np.empty((n, n_local, k))
    errors = np.empty((n, n_local))
    _code_local_patches(dots, atom_gram, k, ridge, np.empty((n, k), dtype=np.int64), np.empty((n, k, k)),
                        np.zeros((n, k, k)), np.empty((n, k)), neighbours, codes, errors)
    return neighbours, codes, errors
