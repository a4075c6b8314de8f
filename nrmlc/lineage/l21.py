"""The L21 multi-task sparse coding of MTT, solved by an accelerated proximal gradient method.

MTT (Zhang, Ghanem, Liu and Ahuja, CVPR 2012; IJCV 2013, Sec. 3) codes all ``n`` particles of a
frame together. The observations ``X = [x_1 .. x_n]`` (``N`` x ``n``, one whitened unit patch per
column) are represented over ``B = [D, I]``: the ``k`` target templates ``D`` (``N`` x ``k``) and
the ``N`` trivial templates (the identity, which absorb occlusion and noise). The coefficients
``C = [Z; E]`` (``(k + N)`` x ``n``, one column per particle) minimise

    F(C) = ||X - B C||_F^2 + lambda sum_i ||C_i||_2

where ``C_i`` is the i-th row of ``C``: the coefficients of one atom over all particles. The
mixed ``l2,1`` norm makes particles select the same few atoms (joint sparsity); this is the
paper's ``L21`` tracker. Unlike L1-APG's coding (:mod:`nrmlc.lineage.apg`) the problem is not
one per particle: the rows couple them.

The paper solves it by an accelerated proximal gradient method (APG; its Algorithm 1) from
``C = 0``, with a fixed step ``eta``: at step ``k = 1, 2, ...``

    V = C_k + (k - 1) / (k + 2) (C_k - C_{k-1})              (the aggregation step; C_0 = C_{-1} = 0)
    H = V - 2 eta B'(B V - X)                                (a gradient step on the squared error)
    C_{k+1,i} = max(0, 1 - lambda eta / ||H_i||_2) H_i        (the l2,1 proximal map, row by row)

The momentum ``(k - 1) / (k + 2)`` is the paper's ``alpha_k = 2 / (k + 2)`` sequence written out.
The authors' solver (``MTL_APG_new.p`` of the OTB benchmark's ``trackers/MTT/``) is P-code and
cannot be read; ``paraConfig_MTT.m`` gives its settings: ``lambda`` 0.01, ``eta`` 0.01,
``obj_fun_th`` 1e-3 and ``iter_maxi`` 100. How ``obj_fun_th`` ends the loop is not stated; here
the loop stops after the first step whose objective changed by at most ``obj_fun_th`` times the
previous objective (a relative test: ``F(0) = ||X||_F^2`` is 600 for MTT's 600 unit patches, so
an absolute change of 1e-3 would almost never end the loop before ``iter_maxi``); 0 turns the
test off. With ``obj_fun_th = 0``, enough steps and ``eta`` at most ``1 / (2 ||B'B||)``, the
iteration converges to the minimiser (``tests/test_lineage_mtt.py`` checks its optimality
conditions).

:func:`l21_apg` uses the structure of ``B`` instead of the dense ``B'B`` ((k + N)^2, 1034 x 1034
in MTT): the residual ``R = D Z + E - X`` gives the gradient ``2 D'R`` on ``Z`` and ``2 R`` on
``E``; since ``R`` is affine in ``C``, the residual at ``V`` is the same extrapolation of the
residuals at ``C_k`` and ``C_{k-1}``, and one product with ``D`` per step suffices. The two
forms differ by rounding only (:func:`l21_apg_reference` is the dense form, the tests' oracle).

Parallel work and determinism. The rows of ``C`` couple the particles, so the particles cannot be
solved apart as in L1-APG. Each step runs two parallel loops: over fixed blocks of particles (the
products with ``D'``) and over pixels (the trivial rows: extrapolation, gradient, row norm,
shrinkage, the new residual). Every output element is computed by one thread with the same
instructions whatever the thread count, and the objective is summed from per-pixel partial sums
in pixel order, so the result (and where the loop stops) is identical for any thread count.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from nrmlc.config import PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.lineage.checks import check_targets_and_signals
from nrmlc.kernels.checks import check_int, check_nonnegative_real

__all__ = ["l21_apg", "l21_apg_reference", "l21_objective"]

#: Particles per block of the loop over particles. Fixed, not derived from the thread count, so
#: that each element is computed by the same code whatever the number of threads.
_BLOCK = 64


@njit(**PARALLEL_FLAGS)
def _solve(targets, x, lam, eta, tol, max_iter, z_buf, e_buf, r_buf, rv, hz, partial, pen_e):
    """APG steps; returns ``(steps, parity)``: ``z_buf[parity]`` and ``e_buf[parity]`` hold the result.

    ``x`` is (N, n); ``z_buf`` (2, k, n), ``e_buf`` (2, N, n) and ``r_buf`` (2, N, n) hold the
    last two iterates and their residuals (index ``parity`` the newer), ``rv`` (N, n) the residual
    at the extrapolated point, ``hz`` (k, n) the gradient step on the template rows.
    """
    k, size = targets.shape
    n = x.shape[1]
    threshold = lam * eta
    n_blocks = (n + _BLOCK - 1) // _BLOCK
    # C = 0: both iterates zero, every residual -X.
    for j in prange(size):
        total = 0.0
        for col in range(n):
            value = x[j, col]
            total += value * value
            r_buf[0, j, col] = -value
            r_buf[1, j, col] = -value
            rv[j, col] = -value
            e_buf[0, j, col] = 0.0
            e_buf[1, j, col] = 0.0
        partial[j] = total
    for i in range(k):
        for col in range(n):
            z_buf[0, i, col] = 0.0
            z_buf[1, i, col] = 0.0
    previous = 0.0
    for j in range(size):
        previous += partial[j]
    cur = 0
    steps = 0
    for step in range(1, max_iter + 1):
        momentum = (step - 1.0) / (step + 2.0)
        old = 1 - cur
        z_cur = z_buf[cur]
        z_old = z_buf[old]
        # The template rows: H_Z = V_Z - 2 eta D' R(V), by blocks of particles.
        for block in prange(n_blocks):
            start = block * _BLOCK
            stop = min(n, start + _BLOCK)
            width = stop - start
            # Slices indexed from 0: numba then knows the index is not negative, and vectorises.
            for i in range(k):
                hz_row = hz[i, start:stop]
                for col in range(width):
                    hz_row[col] = 0.0
            for j in range(size):
                rv_row = rv[j, start:stop]
                for i in range(k):
                    weight = targets[i, j]
                    hz_row = hz[i, start:stop]
                    for col in range(width):
                        hz_row[col] += weight * rv_row[col]
            for i in range(k):
                hz_row = hz[i, start:stop]
                z_row = z_cur[i, start:stop]
                z_prev = z_old[i, start:stop]
                for col in range(width):
                    v = z_row[col] + momentum * (z_row[col] - z_prev[col])
                    hz_row[col] = v - 2.0 * eta * hz_row[col]
        # Their shrinkage (k rows, sequential); the new Z goes where Z_{k-1} was.
        penalty = 0.0
        for i in range(k):
            norm2 = 0.0
            for col in range(n):
                norm2 += hz[i, col] * hz[i, col]
            norm = np.sqrt(norm2)
            factor = 1.0 - threshold / norm if norm > threshold else 0.0
            for col in range(n):
                z_old[i, col] = factor * hz[i, col]
            penalty += factor * norm
        # The trivial rows, one pixel at a time: gradient step, shrinkage, the new residual and
        # the residual at the next extrapolated point.
        next_momentum = step / (step + 3.0)
        for j in prange(size):
            e_cur = e_buf[cur, j]
            e_new = e_buf[old, j]
            r_cur = r_buf[cur, j]
            r_new = r_buf[old, j]
            rv_row = rv[j]
            x_row = x[j]
            norm2 = 0.0
            for col in range(n):
                v = e_cur[col] + momentum * (e_cur[col] - e_new[col])
                h = v - 2.0 * eta * rv_row[col]
                e_new[col] = h
                norm2 += h * h
            norm = np.sqrt(norm2)
            factor = 1.0 - threshold / norm if norm > threshold else 0.0
            pen_e[j] = factor * norm
            for col in range(n):
                e_new[col] *= factor
                r_new[col] = e_new[col] - x_row[col]
            for i in range(k):
                weight = targets[i, j]
                z_row = z_old[i]
                for col in range(n):
                    r_new[col] += weight * z_row[col]
            total = 0.0
            for col in range(n):
                value = r_new[col]
                total += value * value
                rv_row[col] = value + next_momentum * (value - r_cur[col])
            partial[j] = total
        objective = lam * penalty
        for j in range(size):
            objective += partial[j] + lam * pen_e[j]
        cur = old
        steps = step
        if tol > 0.0 and abs(objective - previous) <= tol * previous:
            break
        previous = objective
    return steps, cur


def l21_apg(targets: np.ndarray, signals: np.ndarray, lam: float, eta: float, tol: float, max_iter: int):
    """MTT's L21 coding of all ``signals`` together (module docstring).

    Parameters
    ----------
    targets : (k, N) float64
        The target templates, one per row (the columns of ``D``). C-contiguous, finite.
    signals : (n, N) float64
        The particles' patches, one per row (the columns of ``X``). C-contiguous, finite.
    lam : float
        ``lambda``, the weight of the ``l2,1`` norm; finite, >= 0.
    eta : float
        The step; finite, > 0.
    tol : float
        ``obj_fun_th``: stop once a step changes the objective by at most ``tol`` times its
        previous value; finite, >= 0 (0: always run ``max_iter`` steps).
    max_iter : int
        ``iter_maxi``, 0..1000000 (0 gives zeros).

    Returns
    -------
    target_coefficients : (n, k) float64
        ``Z'``: row ``p`` holds particle ``p``'s template coefficients.
    trivial_coefficients : (n, N) float64
        ``E'``.
    steps : int
        The steps run.
    """
    k, size = check_targets_and_signals(targets, signals)
    lam = check_nonnegative_real("lam", lam)
    eta = check_nonnegative_real("eta", eta)
    if eta <= 0.0:
        raise ParameterError(f"eta must be > 0, got {eta}")
    tol = check_nonnegative_real("tol", tol)
    max_iter = check_int("max_iter", max_iter, 0, 1_000_000)
    n = signals.shape[0]
    if n == 0 or max_iter == 0:
        return np.zeros((n, k)), np.zeros((n, size)), 0
    x = np.ascontiguousarray(signals.T)
    z_buf = np.empty((2, k, n))
    e_buf = np.empty((2, size, n))
    r_buf = np.empty((2, size, n))
    steps, parity = _solve(targets, x, lam, eta, tol, max_iter, z_buf, e_buf, r_buf, np.empty((size, n)),
                           np.empty((k, n)), np.empty(size), np.empty(size))
    return np.ascontiguousarray(z_buf[parity].T), np.ascontiguousarray(e_buf[parity].T), int(steps)


def warm_up() -> None:
    """Compile (or load from numba's cache) the solver now, so that no tracker's frame is timed with it."""
    l21_apg(np.ones((1, 1)), np.ones((1, 1)), 0.0, 1.0, 0.0, 1)


def l21_objective(dictionary, signals, coefficients, lam: float) -> float:
    """``||X - B C||_F^2 + lambda sum_i ||C_i||_2`` (tests only).

    Parameters
    ----------
    dictionary : (N, p) array_like
        ``B``.
    signals : (N, n) array_like
        ``X``, one signal per column.
    coefficients : (p, n) array_like
        ``C``.
    lam : float
    """
    b = np.asarray(dictionary, dtype=np.float64)
    x = np.asarray(signals, dtype=np.float64)
    c = np.asarray(coefficients, dtype=np.float64)
    residual = x - b @ c
    return float(np.sum(residual * residual) + lam * np.sqrt(np.sum(c * c, axis=1)).sum())


def l21_apg_reference(dictionary, signals, lam: float, eta: float, tol: float, max_iter: int):
    """Plain numpy form of the APG on the dense ``B`` (tests only; module docstring).

    Parameters
    ----------
    dictionary : (N, p) array_like
        ``B``, e.g. ``[D, I]``.
    signals : (N, n) array_like
        ``X``, one signal per column.
    lam, eta, tol : float
    max_iter : int

    Returns
    -------
    coefficients : (p, n) float64
        ``C``.
    steps : int
    """
    b = np.asarray(dictionary, dtype=np.float64)
    x = np.asarray(signals, dtype=np.float64)
    gram = b.T @ b
    correlation = b.T @ x
    c = np.zeros((b.shape[1], x.shape[1]))
    c_prev = c.copy()
    previous = float(np.sum(x * x))
    steps = 0
    for step in range(1, max_iter + 1):
        v = c + (step - 1.0) / (step + 2.0) * (c - c_prev)
        h = v - 2.0 * eta * (gram @ v - correlation)
        norms = np.sqrt(np.sum(h * h, axis=1))
        factor = np.where(norms > lam * eta, 1.0 - lam * eta / np.where(norms > 0, norms, 1.0), 0.0)
        c_prev, c = c, factor[:, None] * h
        steps = step
        objective = l21_objective(b, x, c, lam)
        if tol > 0.0 and abs(objective - previous) <= tol * previous:
            break
        previous = objective
    return c, steps
