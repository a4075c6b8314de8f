"""The accelerated proximal gradient (APG) solver of L1-APG's sparse coding.

L1-APG (Bao, Wu, Ling and Ji, CVPR 2012) codes a candidate patch ``y`` (length ``N``) over the
dictionary ``[T, I, f]``: ``nT`` target templates ``T``, the ``N`` trivial templates ``I`` (the
identity, which absorb occlusion and noise) and a fixed template ``f``. Its coefficients
``x = (x_T, x_I, x_f)`` minimise

    0.5 ||y - T x_T - x_I - f x_f||^2 + lambda1 (sum(x_T) + x_f) + lambda2 ||x_I||_1
        + 0.5 mu ||x_I||^2       subject to  x_T >= 0, x_f >= 0,

and ``APGLASSOup.m`` (``trackers/L1APG/`` of the OTB benchmark's code,
github.com/jwlim/tracker_benchmark) approximates the minimiser by a fixed number of APG (FISTA)
steps from ``x = 0`` with the step ``1 / Lip``: each step extrapolates
``z = x + (t_prev - 1) / t (x - x_prev)``, takes a gradient step on the smooth part
(``0.5 ||y - D z||^2 + lambda1 (sum(z_T) + z_f) + 0.5 mu ||z_I||^2``, whose gradient is
``D'D z - D'y`` plus ``lambda1`` on the target atoms and ``mu z_I`` on the trivial ones), then
projects the target coefficients on ``>= 0`` and soft-thresholds the trivial ones by
``lambda2 / Lip``; ``t <- (1 + sqrt(1 + 4 t^2)) / 2``. L1-APG runs 5 steps with ``Lip = 8``
(``paraConfig_L1_APG.m``): the result is not the minimiser, and it is that result the tracker
uses. With enough steps and ``Lip`` at least the largest eigenvalue of ``D'D`` plus ``mu``, the
iteration converges to the minimiser (``tests/test_lineage_l1apg.py`` checks its optimality
conditions).

``APGLASSOup.m`` is given ``b = D'y`` and the dense Gram matrix ``D'D`` (1035 x 1035 in L1-APG).
:func:`apg_lasso` uses the structure of ``D`` instead: ``D'D z = D'(T z_T + z_I + f z_f)``, which
costs ``2 (nT + 2) N`` operations per step instead of ``(nT + N + 1)^2``; the two differ by
rounding only (:func:`apg_lasso_reference` is the dense form, the tests' oracle). The target
templates and the fixed one are passed together as the rows of one array, since they play the
same part.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from nrmlc.config import NUMBA_FLAGS, PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.lineage.blocks import problem_blocks
from nrmlc.lineage.checks import check_targets_and_signals
from nrmlc.kernels.checks import check_int, check_nonnegative_real

__all__ = ["apg_lasso", "apg_lasso_reference"]



@njit(**NUMBA_FLAGS)
def _solve_problem(targets, signal, lam_target, lam_trivial, mu, lipschitz, max_iter,
                   x_target, x_trivial, target_work, trivial_work):
    """APG steps for one signal; ``x_target`` (k,) and ``x_trivial`` (N,) receive the result."""
    k, size = targets.shape
    prev_target, z_target, correlation = target_work
    prev_trivial, z_trivial, fitted = trivial_work
    for j in range(k):
        total = 0.0
        row = targets[j]
        for i in range(size):
            total += row[i] * signal[i]
        correlation[j] = total
        x_target[j] = 0.0
        prev_target[j] = 0.0
    for i in range(size):
        x_trivial[i] = 0.0
        prev_trivial[i] = 0.0
    threshold = lam_trivial / lipschitz
    t_prev = 1.0
    t = 1.0
    for _ in range(max_iter):
        momentum = (t_prev - 1.0) / t
        for j in range(k):
            z_target[j] = (1.0 + momentum) * x_target[j] - momentum * prev_target[j]
        for i in range(size):
            z_trivial[i] = (1.0 + momentum) * x_trivial[i] - momentum * prev_trivial[i]
        # D z, the fit of the extrapolated point; D'D z is then D' of it.
        for i in range(size):
            fitted[i] = z_trivial[i]
        for j in range(k):
            weight = z_target[j]
            row = targets[j]
            for i in range(size):
                fitted[i] += weight * row[i]
        for j in range(k):
            total = 0.0
            row = targets[j]
            for i in range(size):
                total += row[i] * fitted[i]
            prev_target[j] = x_target[j]
            step = z_target[j] - (total - correlation[j] + lam_target) / lipschitz
            x_target[j] = step if step > 0.0 else 0.0
        for i in range(size):
            prev_trivial[i] = x_trivial[i]
            step = z_trivial[i] - (fitted[i] - signal[i] + mu * z_trivial[i]) / lipschitz
            if step > threshold:
                x_trivial[i] = step - threshold
            elif step < -threshold:
                x_trivial[i] = step + threshold
            else:
                x_trivial[i] = 0.0
        t_prev = t
        t = (1.0 + math.sqrt(1.0 + 4.0 * t * t)) / 2.0


@njit(**PARALLEL_FLAGS)
def _solve_problems(targets, signals, lam_target, lam_trivial, mu, lipschitz, max_iter, block_size,
                    target_work, trivial_work, x_target, x_trivial):
    n = signals.shape[0]
    for block in prange(target_work.shape[0]):
        stop = min(n, (block + 1) * block_size)
        for problem in range(block * block_size, stop):
            _solve_problem(targets, signals[problem], lam_target, lam_trivial, mu, lipschitz, max_iter,
                           x_target[problem], x_trivial[problem], target_work[block], trivial_work[block])


def apg_lasso(targets: np.ndarray, signals: np.ndarray, lambdas, lipschitz: float, max_iter: int):
    """``APGLASSOup.m`` for every signal (module docstring), in parallel over the signals.

    Parameters
    ----------
    targets : (k, N) float64
        The atoms with non-negative coefficients, one per row: L1-APG's ``nT`` templates, then
        its fixed template. C-contiguous, finite.
    signals : (n, N) float64
        One signal per row, C-contiguous, finite.
    lambdas : (3,) sequence of float
        ``(lambda1, lambda2, mu)``: the weight on the target coefficients, the l1 weight on the
        trivial ones, and the weight of their squared norm; each finite and >= 0.
    lipschitz : float
        ``Lip``: the step is ``1 / Lip``; > 0.
    max_iter : int
        ``Maxit``: the number of steps, 0..1000000 (0 gives zeros).

    Returns
    -------
    target_coefficients : (n, k) float64
        ``x_T`` then ``x_f`` of each signal, >= 0.
    trivial_coefficients : (n, N) float64
        ``x_I`` of each signal.
    """
    k, size = check_targets_and_signals(targets, signals)
    values = tuple(lambdas) if isinstance(lambdas, (tuple, list, np.ndarray)) else ()
    if len(values) != 3:
        raise ParameterError(f"lambdas must be 3 numbers (lambda1, lambda2, mu), got {lambdas!r}")
    lam_target, lam_trivial, mu = (check_nonnegative_real(name, value)
                                   for name, value in zip(("lambda1", "lambda2", "mu"), values))
    lipschitz = check_nonnegative_real("lipschitz", lipschitz)
    if lipschitz <= 0.0:
        raise ParameterError(f"lipschitz must be > 0, got {lipschitz}")
    max_iter = check_int("max_iter", max_iter, 0, 1_000_000)
    n = signals.shape[0]
    x_target = np.empty((n, k), dtype=np.float64)
    x_trivial = np.empty((n, size), dtype=np.float64)
    if n:
        n_blocks, block_size = problem_blocks(n)
        target_work = np.empty((n_blocks, 3, k), dtype=np.float64)
        trivial_work = np.empty((n_blocks, 3, size), dtype=np.float64)
        _solve_problems(targets, signals, lam_target, lam_trivial, mu, lipschitz, max_iter, block_size,
                        target_work, trivial_work, x_target, x_trivial)
    return x_target, x_trivial


def warm_up() -> None:
    """Compile (or load from numba's cache) the solver now, so that no tracker's frame is timed with it."""
    apg_lasso(np.ones((1, 1)), np.ones((1, 1)), (0.0, 0.0, 0.0), 1.0, 1)


def apg_lasso_reference(b, gram, n_templates: int, lambdas, lipschitz: float, max_iter: int) -> np.ndarray:
    """Plain numpy form of ``APGLASSOup.m`` on the dense Gram matrix (tests only).

    Parameters
    ----------
    b : (p,) array_like
        ``D'y`` with ``D = [T, I, f]``: ``n_templates`` target atoms, the trivial ones, then the
        fixed template last.
    gram : (p, p) array_like
        ``D'D``.
    n_templates : int
        ``nT``.
    lambdas : (3,) array_like
        ``(lambda1, lambda2, mu)``.
    lipschitz : float
    max_iter : int

    Returns
    -------
    (p,) float64
        ``x`` in ``D``'s column order.
    """
    b = np.asarray(b, dtype=np.float64)
    gram = np.asarray(gram, dtype=np.float64)
    lam_target, lam_trivial, mu = (float(v) for v in lambdas)
    p = b.size
    target = np.zeros(p, dtype=bool)
    target[:n_templates] = True
    target[-1] = True
    trivial = ~target
    x = np.zeros(p)
    x_prev = np.zeros(p)
    t_prev, t = 1.0, 1.0
    linear = np.where(target, lam_target, 0.0)
    for _ in range(max_iter):
        momentum = (t_prev - 1.0) / t
        z = (1.0 + momentum) * x - momentum * x_prev
        linear[trivial] = mu * z[trivial]
        z = z - (gram @ z - b + linear) / lipschitz
        x_prev = x
        x = np.empty(p)
        x[target] = np.maximum(z[target], 0.0)
        shrink = lam_trivial / lipschitz
        x[trivial] = np.maximum(z[trivial] - shrink, 0.0) - np.maximum(-z[trivial] - shrink, 0.0)
        t_prev, t = t, (1.0 + np.sqrt(1.0 + 4.0 * t * t)) / 2.0
    return x
