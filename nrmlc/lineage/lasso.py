"""The non-negative lasso of ASLA's sparse coding, in place of SPAMS' ``mexLasso``.

ASLA (``trackers/ASLA/run_ASLA.m`` of the OTB benchmark's code, github.com/jwlim/tracker_benchmark)
calls SPAMS' ``mexLasso`` with the parameters of ``paraConfig_ASLA.m``: ``mode = 2``,
``lambda = 0.01`` and ``pos = 'ture'``. The last is a misspelt string, but SPAMS reads a field as
``(T) mxGetScalar(field)`` (``getScalarStructDef`` in its ``mexutils.h``): the first character's
code, 116, converted to a bool, so any non-empty string means *true* and the positivity constraint
is on. For every column ``x`` of ``X``, mode 2 with ``pos`` solves

    minimise  0.5 ||x - D a||^2 + lambda ||a||_1 + 0.5 ridge ||a||^2   subject to  a >= 0,

where SPAMS adds ``max(lambda2, 1e-10)`` to the Gram matrix's diagonal before its LARS
(``lasso()`` in SPAMS' ``decomp.h``): with ``lambda2 = 0`` that is ``ridge = 1e-10``
(:data:`SPAMS_RIDGE`). The ``mexLasso.mexw64`` shipped with ASLA holds the double 1e-10 among its
constants, consistent with its version doing the same. The ridge makes the problem strictly
convex, so its minimiser is unique and any exact method finds SPAMS' answer up to rounding.

The solver here is not LARS but a primal active-set method on the Gram matrix ``G = D'D`` (Lawson
and Hanson's NNLS in normal-equation form, as in Bro and De Jong's FNNLS): with ``a >= 0`` the
objective is the quadratic ``0.5 a'(G + ridge I)a - (D'x - lambda)'a + const``; the atom whose
gradient ``w = D'x - lambda - (G + ridge I)a`` is largest enters, the unconstrained minimiser on
the active atoms is found from a Cholesky factor grown row by row, and a step back to the
feasible segment removes atoms whose coefficient would turn negative. It stops when no inactive
atom's gradient exceeds ``1e-11 max|D'x|``, and is exact otherwise: it terminates finitely, and
its iteration cap (``5p + 50`` steps) only stops a cycle caused by rounding. At ASLA's sizes (90
atoms, typically 3-15 of them active; 5400 problems in about 30 ms of one core) it is fast, and
it does not slow down on the near-duplicate atoms ASLA's dictionaries are made of (correlations
above 0.9999), where coordinate descent crawls.

An atom that is (to within ``1e-12`` of its squared norm) a combination of the active ones is
set aside until an atom leaves the active set: it cannot lower the objective (without the ridge,
exact duplicates are such atoms; with the ridge there are none).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from nrmlc.config import NUMBA_FLAGS, PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.kernels.checks import check_array, check_finite, check_nonnegative_real
from nrmlc.lineage.blocks import problem_blocks
from nrmlc.lineage.triangular import cholesky_pivot, cholesky_solve

__all__ = ["SPAMS_RIDGE", "lasso_nonnegative", "lasso_nonnegative_gram", "lasso_objective",
           "lasso_nonnegative_reference"]

#: The diagonal SPAMS adds to the Gram matrix (``max(lambda2, 1e-10)`` with ``lambda2 = 0``).
SPAMS_RIDGE = 1e-10

#: An inactive atom may enter while its gradient exceeds this fraction of ``max |D'x|``: well above
#: the rounding of the gradient (about ``1e-16 x active atoms`` of that scale), far below anything
#: that moves the objective (its gap is at most the tolerance times ``||a||_1``).
_KKT_TOLERANCE = 1e-11

#: An atom is dependent on the active ones when its squared distance to their span is at most this
#: fraction of its squared norm (the new Cholesky pivot).
_PIVOT_TOLERANCE = 1e-12


# Atom states inside the solver.
_FREE = 0
_ACTIVE = 1
_SET_ASIDE = 2


@njit(**NUMBA_FLAGS)
def _append_atom(gram, members, k, atom, factor, column):
    """Add ``atom`` as row ``k`` of the Cholesky factor of ``gram[members, members]``; False (and
    nothing changed) when the atom is numerically in the span of the ``k`` active atoms."""
    for r in range(k):
        column[r] = gram[members[r], atom]
    pivot = cholesky_pivot(factor, k, column, gram[atom, atom])
    if not (pivot > _PIVOT_TOLERANCE * gram[atom, atom]):
        return False
    for r in range(k):
        factor[k, r] = column[r]
    factor[k, k] = math.sqrt(pivot)
    members[k] = atom
    return True


@njit(**NUMBA_FLAGS)
def _solve_active(factor, k, members, rhs, trial):
    """``trial[:k]`` = the minimiser on the active atoms, from ``L L' s = rhs[members]``."""
    for r in range(k):
        trial[r] = rhs[members[r]]
    cholesky_solve(factor, k, trial)


@njit(**NUMBA_FLAGS)
def _solve_problem(gram, correlations, lam, factor, real_work, int_work, coefficients):
    """One non-negative lasso from its Gram matrix and correlations (module docstring).

    ``coefficients`` (p,) receives the solution; the return value is the number of atom entries
    made, or -1 when the iteration cap stopped a cycling run (the coefficients are then the
    last feasible point).
    """
    p = gram.shape[0]
    rhs, gradient, trial, column = real_work
    members, state = int_work
    scale = 0.0
    for j in range(p):
        rhs[j] = correlations[j] - lam
        gradient[j] = rhs[j]
        coefficients[j] = 0.0
        state[j] = _FREE
        scale = max(scale, abs(correlations[j]))
    tolerance = _KKT_TOLERANCE * scale
    k = 0
    entries = 0
    max_steps = 5 * p + 50
    steps = 0
    while True:
        steps += 1
        if steps > max_steps:
            return -1
        atom = -1
        largest = tolerance
        for j in range(p):
            if state[j] == _FREE and gradient[j] > largest:
                largest = gradient[j]
                atom = j
        if atom < 0:
            return entries
        if not _append_atom(gram, members, k, atom, factor, column):
            state[atom] = _SET_ASIDE
            continue
        state[atom] = _ACTIVE
        k += 1
        entries += 1
        first = True
        while True:
            _solve_active(factor, k, members, rhs, trial)
            feasible = True
            for r in range(k):
                if not (trial[r] > 0.0):
                    feasible = False
                    break
            if feasible:
                break
            if first and not (trial[k - 1] > 0.0):
                # In exact arithmetic an atom with a positive gradient enters with a positive
                # coefficient; this is rounding at the tolerance's edge. Without this exit the
                # step length below would be 0 and the method would cycle.
                k -= 1
                state[atom] = _SET_ASIDE
                break
            first = False
            steps += 1
            if steps > max_steps:
                return -1
            # Move from the feasible point towards the trial one until a coefficient reaches 0.
            step = 1.0
            blocking = -1
            for r in range(k):
                if trial[r] <= 0.0:
                    current = coefficients[members[r]]
                    ratio = current / (current - trial[r])
                    if ratio < step or blocking < 0:
                        step = ratio
                        blocking = r
            for r in range(k):
                current = coefficients[members[r]]
                coefficients[members[r]] = current + step * (trial[r] - current)
            coefficients[members[blocking]] = 0.0
            # Drop every atom at 0 and refactor the rest; atoms set aside may fit the smaller set.
            old_k = k
            k = 0
            for r in range(old_k):
                member = members[r]
                if coefficients[member] > 0.0 and _append_atom(gram, members, k, member, factor, column):
                    k += 1
                else:
                    coefficients[member] = 0.0
                    state[member] = _FREE
            for j in range(p):
                if state[j] == _SET_ASIDE:
                    state[j] = _FREE
        for r in range(k):
            coefficients[members[r]] = trial[r]
        # Row by row (G is symmetric), so that the inner loop runs along contiguous memory.
        for j in range(p):
            gradient[j] = rhs[j]
        for r in range(k):
            row = gram[members[r]]
            value = trial[r]
            for j in range(p):
                gradient[j] -= row[j] * value


@njit(**PARALLEL_FLAGS)
def _solve_problems(gram, correlations, lam, block_size, factors, real_work, int_work, coefficients, entries):
    # prange over blocks of problems (:mod:`nrmlc.lineage.blocks`); each problem is solved by one thread.
    n = correlations.shape[0]
    for block in prange(factors.shape[0]):
        stop = min(n, (block + 1) * block_size)
        for i in range(block * block_size, stop):
            entries[i] = _solve_problem(gram, correlations[i], lam, factors[block], real_work[block],
                                        int_work[block], coefficients[i])


def _check_lambda(lam) -> float:
    lam = check_nonnegative_real("lam", lam)
    if lam <= 0.0:
        raise ParameterError(f"lam must be > 0, got {lam}")
    return lam


def lasso_nonnegative_gram(gram: np.ndarray, correlations: np.ndarray, lam: float,
                           return_entries: bool = False):
    """Non-negative lassos from a shared Gram matrix (module docstring).

    Parameters
    ----------
    gram : (p, p) float64
        ``D'D`` plus any ridge on the diagonal; symmetric positive semi-definite, C-contiguous.
    correlations : (n, p) float64
        Row ``i`` is ``D'x_i``; C-contiguous.
    lam : float
        The l1 weight, > 0.
    return_entries : bool
        Also return how many atom entries each problem took (-1: stopped by the iteration cap,
        which only a cycling caused by rounding reaches).

    Returns
    -------
    coefficients : (n, p) float64
        Row ``i`` minimises ``0.5 a'Ga - correlations[i]'a + lam sum(a)`` over ``a >= 0``.
    entries : (n,) int64
        Only with ``return_entries``.
    """
    check_array("gram", gram, np.float64, 2)
    check_array("correlations", correlations, np.float64, 2)
    p = gram.shape[0]
    if gram.shape != (p, p) or p == 0:
        raise ParameterError(f"gram must be square and non-empty, got shape {gram.shape}")
    if correlations.shape[1] != p:
        raise ParameterError(f"correlations has {correlations.shape[1]} columns, gram has {p} atoms")
    check_finite("gram", gram)
    check_finite("correlations", correlations)
    if not np.array_equal(gram, gram.T):
        raise ParameterError("gram must be symmetric")
    if np.any(np.diag(gram) < 0):
        raise ParameterError("gram must have a non-negative diagonal (it is D'D)")
    lam = _check_lambda(lam)
    n = correlations.shape[0]
    coefficients = np.empty((n, p), dtype=np.float64)
    entries = np.empty(n, dtype=np.int64)
    if n:
        n_blocks, block_size = problem_blocks(n)
        factors = np.empty((n_blocks, p, p), dtype=np.float64)
        real_work = np.empty((n_blocks, 4, p), dtype=np.float64)
        int_work = np.empty((n_blocks, 2, p), dtype=np.int64)
        _solve_problems(gram, correlations, lam, block_size, factors, real_work, int_work, coefficients, entries)
    return (coefficients, entries) if return_entries else coefficients


def _check_problem(X, D):
    check_array("X", X, np.float64, 2)
    check_array("D", D, np.float64, 2)
    if X.shape[0] != D.shape[0]:
        raise ParameterError(f"X has {X.shape[0]} rows, D has {D.shape[0]} (both are the signal length)")
    if D.shape[1] == 0:
        raise ParameterError("D must have at least one atom (column)")
    check_finite("X", X)
    check_finite("D", D)


def lasso_nonnegative(X: np.ndarray, D: np.ndarray, lam: float, ridge: float = 0.0) -> np.ndarray:
    """``mexLasso(X, D, struct('mode', 2, 'lambda', lam, 'pos', true))`` with SPAMS' ridge as a
    parameter (module docstring).

    Parameters
    ----------
    X : (m, n) float64
        One signal per column, C-contiguous.
    D : (m, p) float64
        One atom per column, C-contiguous.
    lam : float
        The l1 weight, > 0.
    ridge : float
        Added to the Gram matrix's diagonal; :data:`SPAMS_RIDGE` reproduces SPAMS, 0 the plain lasso.

    Returns
    -------
    (p, n) float64
        Column ``i`` minimises ``0.5 ||X[:, i] - D a||^2 + lam ||a||_1 + 0.5 ridge ||a||^2`` over ``a >= 0``.
    """
    _check_problem(X, D)
    ridge = check_nonnegative_real("ridge", ridge)
    gram = D.T @ D
    gram = 0.5 * (gram + gram.T)  # exactly symmetric whatever the BLAS did
    gram[np.diag_indices_from(gram)] += ridge
    correlations = np.ascontiguousarray(X.T @ D)
    return lasso_nonnegative_gram(gram, correlations, lam).T.copy()


def lasso_objective(X, D, A, lam: float, ridge: float = 0.0) -> np.ndarray:
    """Each column's objective ``0.5 ||x - D a||^2 + lam ||a||_1 + 0.5 ridge ||a||^2``.

    Parameters
    ----------
    X : (m, n) array_like
    D : (m, p) array_like
    A : (p, n) array_like
    lam, ridge : float

    Returns
    -------
    (n,) float64
    """
    X, D, A = (np.asarray(v, dtype=np.float64) for v in (X, D, A))
    residual = X - D @ A
    return 0.5 * (residual ** 2).sum(axis=0) + lam * np.abs(A).sum(axis=0) + 0.5 * ridge * (A ** 2).sum(axis=0)


def _support_enumeration(gram, b):
    """Minimiser of ``0.5 a'Ga - b'a`` over ``a >= 0`` by trying every support (small p only).

    A minimiser exists whose support has linearly independent atoms (Caratheodory), on which the
    unconstrained solve is unique and non-negative; the best feasible support is therefore optimal.
    """
    p = gram.shape[0]
    best, best_value = np.zeros(p), 0.0
    for mask in range(1, 1 << p):
        support = [j for j in range(p) if mask >> j & 1]
        sub = gram[np.ix_(support, support)]
        solution = np.linalg.lstsq(sub, b[support], rcond=None)[0]
        if np.any(solution < 0):
            continue
        a = np.zeros(p)
        a[support] = solution
        value = 0.5 * a @ gram @ a - b @ a
        if value < best_value:
            best, best_value = a, value
    return best


def lasso_nonnegative_reference(X, D, lam: float, ridge: float = 0.0) -> np.ndarray:
    """Slow oracle of :func:`lasso_nonnegative` (tests only), by other means: scipy's NNLS on
    ``min ||R a - R^{-T} b||`` with ``R'R = D'D + ridge I`` (Cholesky) and ``b = D'X - lam``, whose
    minimiser is the lasso's; when that Gram matrix is singular and ``p <= 12``, every support is
    tried instead.

    Parameters
    ----------
    X : (m, n) array_like
    D : (m, p) array_like
    lam, ridge : float

    Returns
    -------
    (p, n) float64
    """
    from scipy.linalg import solve_triangular
    from scipy.optimize import nnls

    X, D = np.asarray(X, dtype=np.float64), np.asarray(D, dtype=np.float64)
    gram = D.T @ D + ridge * np.eye(D.shape[1])
    b = D.T @ X - lam
    out = np.zeros((D.shape[1], X.shape[1]))
    try:
        upper = np.linalg.cholesky(gram).T
        if np.linalg.cond(gram) > 1e12:
            raise np.linalg.LinAlgError("near-singular")
    except np.linalg.LinAlgError:
        if D.shape[1] > 12:
            raise ParameterError("the reference needs a well-conditioned D'D + ridge I, or at most 12 atoms")
        for i in range(X.shape[1]):
            out[:, i] = _support_enumeration(gram, b[:, i])
        return out
    for i in range(X.shape[1]):
        target = solve_triangular(upper, b[:, i], trans="T")
        out[:, i] = nnls(upper, target, maxiter=50 * D.shape[1])[0]
    return out
