"""Cholesky factors grown a row at a time, and solves with them, in place: the steps the lineage's active-set solvers (the lasso
of :mod:`nrmlc.lineage.lasso`, L1's Newton step in :mod:`nrmlc.lineage.l1`) take each time their
active set changes. Plain loops, so that they run inside the solvers' ``prange`` over problems."""
from __future__ import annotations

from numba import njit

from nrmlc.config import NUMBA_FLAGS


@njit(**NUMBA_FLAGS)
def forward_substitute(factor, k, x):
    """``x[:k]`` <- ``L^-1 x[:k]``, ``L`` the lower triangle of ``factor[:k, :k]`` (float64, (>= k, >= k))."""
    for r in range(k):
        total = x[r]
        for c in range(r):
            total -= factor[r, c] * x[c]
        x[r] = total / factor[r, r]


@njit(**NUMBA_FLAGS)
def cholesky_pivot(factor, k, row, diagonal):
    """The next row of a Cholesky factor: ``row[:k]`` <- ``L^-1 row[:k]`` (``L`` as in
    :func:`forward_substitute`), and the return value ``diagonal - ||row[:k]||^2``, the square of
    the row's diagonal entry (not above 0: the matrix is not positive definite at this row)."""
    forward_substitute(factor, k, row)
    pivot = diagonal
    for r in range(k):
        pivot -= row[r] * row[r]
    return pivot


@njit(**NUMBA_FLAGS)
def cholesky_solve(factor, k, x):
    """``x[:k]`` <- ``(L L')^-1 x[:k]``, ``L`` as in :func:`forward_substitute`."""
    forward_substitute(factor, k, x)
    for r in range(k - 1, -1, -1):
        total = x[r]
        for c in range(r + 1, k):
            total -= factor[c, r] * x[c]
        x[r] = total / factor[r, r]
