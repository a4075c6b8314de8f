"""L1: the L1 tracker (Mei and Ling, ICCV 2009; TPAMI 2011), as its authors' released code runs it.

The state is an affine map from template pixels to image pixels; each frame, 600 particles are
drawn around the last frame's resampled particles and cropped to 12x15 gray patches, each
whitened and scaled to unit norm. A patch ``y`` is coded over ten target templates ``T`` (each
scaled to its importance weight), a fixed template ``f`` (the first template over ten) and the
180 trivial templates (the identity) by the lasso

    minimise  0.5 ||y - T a - f b - e||^2 + lambda (||a||_1 + |b| + ||e||_1)

with ``lambda`` 0.01 and no sign constraint; its likelihood is ``exp(-alpha ||y - T a - f b||)``
(the norm, not its square, of the target part's error), and the most likely particle whose
template coefficients do not sum below zero is the answer. Every frame the weights are multiplied
by ``exp(a)``; when the answer's angle to the template with the largest coefficient exceeds 60
degrees, the template of least weight is replaced by the answer and given the weights' median;
the weights are then normalised to sum 1, none above 0.3, and each template is rescaled to its
weight.

Sources. The authors' release, "version 3 of the distribution" (``ReadMe``: Xue Mei and Haibin
Ling, July 2010, last updated Sep 30 2010, SPAMS' ``mexLasso`` as its solver), found as public
copies in the stored GitHub code index (the index gave the files, not their repository's name):
``L1Tracking_release.m`` (the loop and every constant not named below), ``demo.m`` (600
particles, template 12x15), ``InitTemplates.m``, ``corner2image.m``, ``gly_zmuv.m``,
``normalizeTemplates.m``, ``normalizeWeights.m``, ``Seg_gly_crop.m``, ``Seg_resample.m`` (its
original body, kept as a comment in a later copy) and ``images_angle.m`` (the original, without
the ``eps`` a 2012 edit added to L1-APG's copy). Three helpers were not among the copies found;
the same authors' later L1-APG files of the same interface stand in for them (the OTB
benchmark's ``trackers/L1APG/``): ``corners2affine.m`` for ``corners2afnv.m``, ``IMGaffine_r.m``
for the release's ``IMGaffine_r.m``, and ``draw_sample.m`` for ``Seg_draw_sample.m`` (a later
three-argument copy of which has the same body). Each step:

- parameters: ``L1Tracking_release.m`` (``nT`` 10, ``lambda`` 0.01 with ``lambda2`` 0 and
  ``mode`` 2, ``alpha`` 30, ``rel_std_afnv`` (0.005, 0.0005, 0.0005, 0.005, 1, 1), the angle 60,
  the weights starting at 1) and ``demo.m`` (``n_sample`` 600, ``sz_T`` [12 15]);
- the first state and templates: the box's corners as ``run_L1APG.m`` gives them to the same
  authors' later tracker (:func:`~nrmlc.lineage.l1apg.box_corners`; the release's ``demo.m``
  takes hand-picked corners), the affine map of ``corners2afnv.m``
  (:func:`~nrmlc.lineage.l1apg.corners_to_state`), and ``InitTemplates.m``: the first template at
  the corners, nine more with one corner coordinate moved by one pixel (no random numbers), each
  cropped, whitened (``gly_zmuv.m``: zero mean, standard deviation plus 1e-14) and divided by its
  norm (``corner2image.m``);
- the frame: ``double(rgb2gray(...))``, gray levels 0..255 (:func:`~nrmlc.lineage.l1apg.gray_levels`);
- every frame, the first included: ``L1Tracking_release.m``'s loop runs from ``t = 1``, so the
  first frame is tracked from particles all at the first state and its answer already updates
  the weights (``init`` does that step; the box of the first frame stays the given one);
- sampling: ``Seg_draw_sample.m`` (Gaussian noise on ``log a11``, ``a12``, ``a21``, ``log a22``,
  ``tr``, ``tc``; deviations ``rel_std_afnv`` times ``(1, s, s, 1, s, s)``, ``s`` the RMS of the
  last answer's 2x2 part; :func:`~nrmlc.lineage.l1apg.draw_states`);
- the crop: ``Seg_gly_crop.m`` with ``IMGaffine_r.m`` (nearest neighbour at MATLAB's rounding;
  pixels outside the frame, where the last column counts as outside, take the patch's mean; a
  patch wholly outside is zeros), which is :func:`~nrmlc.lineage.l1apg.crop_patches`; then ``gly_zmuv.m`` and
  ``normalizeTemplates.m`` on every patch (:func:`~nrmlc.lineage.l1apg.whiten`);
- the coding: ``mexLasso`` with ``mode`` 2 and ``lambda2`` 0 minimises the lasso above plus
  SPAMS' ridge ``0.5 * 1e-10 ||c||^2`` (:data:`~nrmlc.lineage.lasso.SPAMS_RIDGE`), a strictly
  convex problem solved exactly by :func:`trivial_lasso`; out-of-frame and constant patches are
  skipped (likelihood 0);
- the choice: the first particle of largest likelihood among those whose ``sum(a) >= 0``
  (``sum(c(1:nT)) < 0`` is skipped as an "inverse intensity pattern", but its likelihood still
  counts in the resampling); ``Seg_resample.m`` (:func:`~nrmlc.lineage.l1apg.resample_states`);
- the template step: ``W = W .* exp(a)``; above the angle (``images_angle.m``: the plain angle of
  the two vectors, :func:`images_angle`), the smallest weight's template becomes the answer's
  patch and that weight the median of the weights with it set to 0; ``normalizeWeights.m``
  (:func:`normalize_weights`); ``normalizeTemplates.m``, then each template times its weight;
- boxes: the toolkit's box of an ``L1Aff`` state with ``tmplsize`` 12x15
  (:func:`~nrmlc.workbench.otb_results.l1_affine_boxes`).

Where the code does something unexpected, it is followed: the coefficients are signed (the
release calls ``mexLasso`` without ``pos``; the paper's non-negative coefficients over ``T``,
``I`` and ``-I`` are the same as signed trivial coefficients, but its target coefficients are
non-negative where the code's are not); the weights multiply by ``exp`` of signed coefficients;
the angle is measured to the template of largest coefficient, the replaced one is the template of
least weight. When no particle qualifies on a frame, the answer is the new particle at the
previous frame's index with the previous coefficients (MATLAB keeps ``id_max`` and ``c_max``); on
the first frame, where MATLAB stops with an error, the state stays.

Departures, none of them a choice of method: the random numbers (numpy's generator, not MATLAB's
stream; the release seeds nothing); the gray conversion (OpenCV's, which can differ from
``rgb2gray`` by one level on some pixels); SPAMS' LARS replaced by the exact solver of the same
problem (the same minimiser, up to rounding); and ``normalizeWeights.m``'s loop, which in
MATLAB never ends when exactly three weights are capped and the others are zero, stopped after
:data:`_MAX_CAP_ROUNDS` rounds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from nrmlc.config import NUMBA_FLAGS, PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.lineage.checks import bounded, check_targets_and_signals, check_weight_cap
from nrmlc.kernels.checks import check_nonnegative_real
from nrmlc.lineage.l1apg import (TemplateTracker, TemplateTrackerParams, box_corners, corners_to_state, crop_patches, gray_levels, resample_states, whiten)
from nrmlc.lineage.lasso import SPAMS_RIDGE
from nrmlc.lineage.blocks import problem_blocks
from nrmlc.lineage.triangular import cholesky_pivot, cholesky_solve

__all__ = ["L1Params", "L1Tracker", "trivial_lasso", "trivial_lasso_reference", "images_angle",
           "normalize_weights", "shifted_template_states", "TEMPLATE_SHIFTS"]

#: ``InitTemplates.m``'s corner moves of the ten templates, in pixels: (row, column) of each of
#: the corners top-left, bottom-left, top-right.
TEMPLATE_SHIFTS = np.array([
    [[0, 0, 0], [0, 0, 0]],
    [[-1, 0, 0], [0, 0, 0]],
    [[1, 0, 0], [0, 0, 0]],
    [[0, -1, 0], [0, 0, 0]],
    [[0, 1, 0], [0, 0, 0]],
    [[0, 0, 1], [0, 0, 0]],
    [[0, 0, 0], [-1, 0, 0]],
    [[0, 0, 0], [1, 0, 0]],
    [[0, 0, 0], [0, -1, 0]],
    [[0, 0, 0], [0, 1, 0]],
], dtype=np.float64)



def shifted_template_states(corners: np.ndarray, n_templates: int, template_size) -> np.ndarray:
    """``InitTemplates.m``'s states: the first ``n_templates`` of :data:`TEMPLATE_SHIFTS` applied to
    the (2, 3) ``corners``; (n_templates, 6) float64."""
    return np.array([corners_to_state(corners + shift, template_size) for shift in TEMPLATE_SHIFTS[:n_templates]])


#: ``gly_zmuv.m`` adds this to the standard deviation, ``normalizeTemplates.m`` to the norm.
TINY = 1e-14

#: ``normalizeWeights.m`` caps the weights and renormalises until none exceeds the cap; with three
#: capped weights and the rest 0 that never ends in MATLAB. Elsewhere it ends within a few hundred
#: rounds (the excess shrinks by at least 0.9 a round).
_MAX_CAP_ROUNDS = 100_000

#: The solver stops when the largest violation of the optimality conditions is below this
#: fraction of ``1 + max |T y|``: above the rounding of the gradients, far below anything that
#: moves the coefficients.
_KKT_TOLERANCE = 1e-12

#: Newton steps per problem before the solver gives up (a rounding-induced stall; -1 is returned).
_MAX_STEPS = 200



@dataclass(frozen=True)
class L1Params(TemplateTrackerParams):
    """L1's parameters (the release's ``L1Tracking_release.m`` and ``demo.m``; the shared fields:
    :class:`~nrmlc.lineage.l1apg.TemplateTrackerParams`)."""

    template_size: tuple = (12, 15)
    n_templates: int = bounded(10, 1, len(TEMPLATE_SHIFTS))
    affine_sigma: tuple = (0.005, 0.0005, 0.0005, 0.005, 1.0, 1.0)
    #: The lasso's l1 weight (``param.lambda``).
    lam: float = bounded(0.01, 0.0, 1e3, low_open=True)
    #: The likelihood's ``alpha``: ``exp(-alpha * ||error||)``.
    alpha: float = bounded(30.0, 0.0, 1e6, low_open=True)
    #: Degrees between the answer and its template of largest coefficient above which a template is replaced.
    angle_threshold: float = bounded(60.0, 0.0, 180.0)
    #: ``normalizeWeights.m``'s cap on a template's share of the weights.
    weight_cap: float = 0.3

    def check_group(self) -> None:
        super().check_group()
        check_weight_cap(self, "weight_cap")


# ------------------------------------------------------------------------------------------------
# The lasso over target and trivial templates.
#
# With the identity as atoms, the trivial coefficients of any target coefficients ``a`` are
# ``e = soft(r, lam) / (1 + ridge)`` with ``r = y - T'a``, and what is left to minimise over ``a``
# (k numbers, not k + N) is the convex piecewise quadratic
#
#     F(a) = sum_i h(r_i) + lam ||a||_1 + 0.5 ridge ||a||^2,
#     h(r) = r^2 / 2 (|r| <= lam),  r^2 / 2 - (|r| - lam)^2 / (2 (1 + ridge)) (otherwise),
#
# h being C^1 with h'(r) = r - e(r). The solver takes Newton steps on the piece at ``a`` (the
# pixels inside the band count with curvature 1, the others with ridge / (1 + ridge)) over the
# free coefficients (non-zero, or zero with a gradient beyond ``lam``), then the exact minimum of
# F along the step (F is piecewise quadratic on the line, its derivative piecewise linear and
# increasing; its breakpoints are where a pixel enters or leaves the band and where a
# coefficient crosses 0). Each step lowers F; on the optimal piece the Newton step is exact.
# ------------------------------------------------------------------------------------------------


@njit(**NUMBA_FLAGS)
def _pseudo_gradient(a, gradient, lam, k, out):
    """The minimum-norm subgradient of F (0 at the optimum); returns its largest magnitude."""
    largest = 0.0
    for j in range(k):
        if a[j] > 0.0:
            value = gradient[j] + lam
        elif a[j] < 0.0:
            value = gradient[j] - lam
        elif gradient[j] + lam < 0.0:
            value = gradient[j] + lam
        elif gradient[j] - lam > 0.0:
            value = gradient[j] - lam
        else:
            value = 0.0
        out[j] = value
        largest = max(largest, abs(value))
    return largest


@njit(**NUMBA_FLAGS)
def _solve_problem(targets, signal, lam, ridge, a, e, k_work, n_work, hessian, free, bp_time, bp_kind, bp_delta):
    """One problem (module comment above); ``a`` (k,) and ``e`` (N,) receive the solution. Returns
    the Newton steps taken, or -1 when the step cap stopped a stalled run (the last point is kept)."""
    k, size = targets.shape
    gradient, pg, direction, sign, column = k_work
    residual, along = n_work
    outside_curvature = ridge / (1.0 + ridge)
    inside_extra = 1.0 / (1.0 + ridge)  # inside curvature 1 = outside_curvature + inside_extra
    scale = 0.0
    for j in range(k):
        a[j] = 0.0
        total = 0.0
        for i in range(size):
            total += targets[j, i] * signal[i]
        scale = max(scale, abs(total))
    tolerance = _KKT_TOLERANCE * (1.0 + scale)
    steps = 0
    while True:
        # residual, trivial part and gradient of the smooth part at a
        for i in range(size):
            residual[i] = signal[i]
        for j in range(k):
            if a[j] != 0.0:
                for i in range(size):
                    residual[i] -= a[j] * targets[j, i]
        for j in range(k):
            total = 0.0
            for i in range(size):
                r = residual[i]
                z = r
                if r > lam:
                    z = r - (r - lam) * inside_extra
                elif r < -lam:
                    z = r - (r + lam) * inside_extra
                total += targets[j, i] * z
            gradient[j] = -total + ridge * a[j]
        largest = _pseudo_gradient(a, gradient, lam, k, pg)
        if largest <= tolerance:
            break
        if steps >= _MAX_STEPS:
            steps = -1
            break
        steps += 1
        # Newton step over the free coefficients: the non-zero ones, and the zero ones whose
        # subgradient lets them leave 0; a zero one whose step points the other way stays at 0
        # and the step is solved again without it.
        for j in range(k):
            direction[j] = 0.0
            sign[j] = 0.0
            if a[j] > 0.0 or (a[j] == 0.0 and pg[j] < 0.0):
                sign[j] = 1.0
            elif a[j] < 0.0 or pg[j] > 0.0:
                sign[j] = -1.0
        good = True
        while True:
            m = 0
            for j in range(k):
                if sign[j] != 0.0:
                    free[m] = j
                    m += 1
            if m == 0:
                good = False
                break
            for p in range(m):
                row_p = targets[free[p]]
                for s in range(p + 1):
                    row_s = targets[free[s]]
                    total = 0.0
                    for i in range(size):
                        weight = 1.0 if abs(residual[i]) <= lam else outside_curvature
                        total += weight * row_p[i] * row_s[i]
                    if p == s:
                        total += ridge
                    hessian[p, s] = total
            for p in range(m):  # Cholesky in place (lower triangle), row by row
                pivot = cholesky_pivot(hessian, p, hessian[p], hessian[p, p])
                if not (pivot > 0.0):
                    good = False
                    break
                hessian[p, p] = math.sqrt(pivot)
            if not good:
                break
            for p in range(m):
                column[p] = -pg[free[p]]
            cholesky_solve(hessian, m, column)
            dropped = False
            for p in range(m):
                j = free[p]
                if a[j] == 0.0 and column[p] * sign[j] <= 0.0:
                    sign[j] = 0.0
                    dropped = True
            if not dropped:
                for p in range(m):
                    direction[free[p]] = column[p]
                break
        slope = 0.0
        for attempt in range(2):
            slope = 0.0
            for j in range(k):
                d = direction[j]
                slope += gradient[j] * d
                if a[j] > 0.0:
                    slope += lam * d
                elif a[j] < 0.0:
                    slope -= lam * d
                else:
                    slope += lam * abs(d)
            if slope < 0.0 or attempt == 1:
                break
            for j in range(k):  # the Newton step is no descent: steepest descent instead
                direction[j] = -pg[j]
        if not (slope < 0.0):
            steps = -1
            break
        # exact line search on t >= 0
        curvature = 0.0
        for j in range(k):
            curvature += ridge * direction[j] * direction[j]
        n_bp = 0
        for i in range(size):
            total = 0.0
            for j in range(k):
                total += direction[j] * targets[j, i]
            along[i] = total
            q = total
            if q == 0.0:
                continue
            r = residual[i]
            curvature += outside_curvature * q * q
            extra = inside_extra * q * q
            # r(t) = r - t q moves towards -q's sign; record where it enters and leaves [-lam, lam]
            if q > 0.0:
                if r > lam:
                    bp_time[n_bp] = (r - lam) / q
                    bp_kind[n_bp] = -1
                    bp_delta[n_bp] = extra
                    n_bp += 1
                if r > -lam:
                    if r <= lam:
                        curvature += extra
                    bp_time[n_bp] = (r + lam) / q
                    bp_kind[n_bp] = -1
                    bp_delta[n_bp] = -extra
                    n_bp += 1
            else:
                if r < -lam:
                    bp_time[n_bp] = (r + lam) / q
                    bp_kind[n_bp] = -1
                    bp_delta[n_bp] = extra
                    n_bp += 1
                if r < lam:
                    if r >= -lam:
                        curvature += extra
                    bp_time[n_bp] = (r - lam) / q
                    bp_kind[n_bp] = -1
                    bp_delta[n_bp] = -extra
                    n_bp += 1
        for j in range(k):
            if a[j] * direction[j] < 0.0:
                bp_time[n_bp] = -a[j] / direction[j]
                bp_kind[n_bp] = j
                bp_delta[n_bp] = 2.0 * lam * abs(direction[j])
                n_bp += 1
        order = np.argsort(bp_time[:n_bp])
        t_now = 0.0
        t_star = -1.0
        landed = -1
        for index in range(n_bp):
            b = order[index]
            t_next = bp_time[b]
            at_next = slope + curvature * (t_next - t_now)
            if at_next >= 0.0 and curvature > 0.0:
                t_star = t_now - slope / curvature
                break
            slope = at_next
            t_now = t_next
            if bp_kind[b] >= 0:
                slope += bp_delta[b]
                if slope >= 0.0:
                    t_star = t_now
                    landed = bp_kind[b]
                    break
            else:
                curvature += bp_delta[b]
        if t_star < 0.0:
            if not (curvature > 0.0):
                steps = -1
                break
            t_star = t_now - slope / curvature
        if not (t_star > 0.0):
            steps = -1
            break
        for j in range(k):
            a[j] += t_star * direction[j]
        if landed >= 0:
            a[landed] = 0.0
    for i in range(size):
        r = residual[i]
        if r > lam:
            e[i] = (r - lam) * inside_extra
        elif r < -lam:
            e[i] = (r + lam) * inside_extra
        else:
            e[i] = 0.0
    return steps


@njit(**PARALLEL_FLAGS)
def _solve_problems(targets, signals, lam, ridge, block_size, k_work, n_work, hessians, frees, bp_times,
                    bp_kinds, bp_deltas, a, e, steps):
    n = signals.shape[0]
    for block in prange(k_work.shape[0]):
        stop = min(n, (block + 1) * block_size)
        for problem in range(block * block_size, stop):
            steps[problem] = _solve_problem(targets, signals[problem], lam, ridge, a[problem], e[problem],
                                            k_work[block], n_work[block], hessians[block], frees[block],
                                            bp_times[block], bp_kinds[block], bp_deltas[block])


def trivial_lasso(targets: np.ndarray, signals: np.ndarray, lam: float, ridge: float = SPAMS_RIDGE,
                  return_steps: bool = False):
    """``mexLasso(y, [T, I, f], struct('mode', 2, 'lambda', lam, 'lambda2', 0))`` for every signal,
    exactly (the comment above :func:`_pseudo_gradient`), in parallel over the signals.

    Parameters
    ----------
    targets : (k, N) float64
        The target atoms, one per row (L1's ten weighted templates, then its fixed template).
        C-contiguous, finite.
    signals : (n, N) float64
        One signal per row, C-contiguous, finite.
    lam : float
        The l1 weight, > 0.
    ridge : float
        Added to the Gram matrix's diagonal; :data:`~nrmlc.lineage.lasso.SPAMS_RIDGE` is SPAMS'.
    return_steps : bool
        Also return the Newton steps of each problem (-1: stopped by the step cap).

    Returns
    -------
    target_coefficients : (n, k) float64
    trivial_coefficients : (n, N) float64
        Row ``i`` of each minimises ``0.5 ||y_i - a T - e||^2 + lam (||a||_1 + ||e||_1)
        + 0.5 ridge (||a||^2 + ||e||^2)``, signed.
    steps : (n,) int64
        Only with ``return_steps``.
    """
    k, size = check_targets_and_signals(targets, signals)
    lam = check_nonnegative_real("lam", lam)
    if lam <= 0.0:
        raise ParameterError(f"lam must be > 0, got {lam}")
    ridge = check_nonnegative_real("ridge", ridge)
    n = signals.shape[0]
    a = np.empty((n, k), dtype=np.float64)
    e = np.empty((n, size), dtype=np.float64)
    steps = np.empty(n, dtype=np.int64)
    if n:
        n_blocks, block_size = problem_blocks(n)
        n_bp = 2 * size + k
        _solve_problems(targets, signals, lam, ridge, block_size, np.empty((n_blocks, 5, k)),
                        np.empty((n_blocks, 2, size)), np.empty((n_blocks, k, k)),
                        np.empty((n_blocks, k), dtype=np.int64), np.empty((n_blocks, n_bp)),
                        np.empty((n_blocks, n_bp), dtype=np.int64), np.empty((n_blocks, n_bp)), a, e, steps)
    return (a, e, steps) if return_steps else (a, e)


def warm_up() -> None:
    """Compile (or load from numba's cache) the solver now, so that no tracker's frame is timed with it."""
    trivial_lasso(np.ones((1, 2)), np.ones((1, 2)), 0.1)


def trivial_lasso_reference(targets, signals, lam: float, ridge: float = SPAMS_RIDGE, max_steps: int = _MAX_STEPS):
    """Plain numpy float64 form of :func:`trivial_lasso`'s method (tests only; same arguments).

    Returns
    -------
    target_coefficients : (n, k) float64
    trivial_coefficients : (n, N) float64
    """
    targets = np.asarray(targets, dtype=np.float64)
    signals = np.atleast_2d(np.asarray(signals, dtype=np.float64))
    k = targets.shape[0]
    inside_extra = 1.0 / (1.0 + ridge)
    outside_curvature = ridge / (1.0 + ridge)

    def soft(r):
        return np.sign(r) * np.maximum(np.abs(r) - lam, 0.0) * inside_extra

    def pseudo(a, gradient):
        return np.where(a > 0, gradient + lam, np.where(a < 0, gradient - lam, np.where(
            gradient + lam < 0, gradient + lam, np.where(gradient - lam > 0, gradient - lam, 0.0))))

    out_a = np.zeros((len(signals), k))
    out_e = np.zeros_like(signals)
    for row, y in enumerate(signals):
        tolerance = _KKT_TOLERANCE * (1.0 + np.abs(targets @ y).max())
        a = np.zeros(k)
        for _ in range(max_steps + 1):
            r = y - a @ targets
            gradient = -(targets @ (r - soft(r))) + ridge * a
            pg = pseudo(a, gradient)
            if np.abs(pg).max() <= tolerance:
                break
            free = (a != 0) | (pg != 0)
            sign = np.where((a > 0) | ((a == 0) & (pg < 0)), 1.0, -1.0)
            weight = np.where(np.abs(r) <= lam, 1.0, outside_curvature)
            d = np.zeros(k)
            while free.any():
                hessian = (targets[free] * weight) @ targets[free].T + ridge * np.eye(free.sum())
                d = np.zeros(k)
                d[free] = np.linalg.solve(hessian, -pg[free])
                wrong = free & (a == 0) & (d * sign <= 0)
                if not wrong.any():
                    break
                free &= ~wrong
                d = np.zeros(k)

            def slope_of(d):
                return gradient @ d + lam * np.sum(np.where(a != 0, np.sign(a) * d, np.abs(d)))

            if not slope_of(d) < 0:
                d = -pg
            q = d @ targets

            def derivative(t):
                """phi' at a point t > 0 where no coefficient is 0 (inside a segment)."""
                at = a + t * d
                rt = r - t * q
                l1 = np.where(at != 0, np.sign(at) * d, np.abs(d))
                return -(rt - soft(rt)) @ q + ridge * at @ d + lam * l1.sum()

            # phi' is linear between breakpoints and increasing: read each segment's line from two
            # inner points, and stop in the first whose line reaches 0 (at its left end: a jump)
            with np.errstate(divide="ignore", invalid="ignore"):
                crossings = -a / d
                times = np.concatenate([(r - lam) / q, (r + lam) / q, crossings])
            points = np.concatenate([[0.0], np.unique(times[np.isfinite(times) & (times > 0)])])
            for index, start in enumerate(points):
                end = points[index + 1] if index + 1 < len(points) else None
                width = 1.0 if end is None else end - start
                t1, t2 = start + width / 3, start + 2 * width / 3
                g1, g2 = derivative(t1), derivative(t2)
                rate = (g2 - g1) / (t2 - t1)
                at_start = g1 - rate * (t1 - start)
                if at_start >= 0:
                    t_star = start
                    break
                if end is None or at_start + rate * width >= 0:
                    t_star = start - at_start / rate
                    break
            landed = (a * d < 0) & (crossings == t_star)
            a = a + t_star * d
            a[landed] = 0.0
        out_a[row] = a
        out_e[row] = soft(y - a @ targets)
    return out_a, out_e


# ------------------------------------------------------------------------------------------------
# The template step.
# ------------------------------------------------------------------------------------------------


def images_angle(first: np.ndarray, second: np.ndarray) -> float:
    """The release's ``images_angle.m``: the angle in degrees between two vectors (NaN when one is
    zero; MATLAB's ``acosd`` of a cosine rounded past 1 is complex with real part 0, here 0).

    Parameters
    ----------
    first, second : (N,) float64
    """
    first = np.asarray(first, dtype=np.float64).ravel()
    second = np.asarray(second, dtype=np.float64).ravel()
    with np.errstate(invalid="ignore", divide="ignore"):
        cosine = (first / np.sqrt(np.sum(first * first))) @ (second / np.sqrt(np.sum(second * second)))
    if np.isnan(cosine):
        return float("nan")
    return float(np.degrees(np.arccos(min(1.0, max(-1.0, cosine)))))


def _sum(values) -> float:
    """A left-to-right sum, as MATLAB's ``sum`` of a short row."""
    total = 0.0
    for value in values:
        total += float(value)
    return total


def normalize_weights(weights: np.ndarray, cap: float) -> np.ndarray:
    """``normalizeWeights.m`` with ``s = 1``: divide by the sum, then, while any exceeds ``cap``,
    set those to ``cap`` and divide by the sum again.

    Parameters
    ----------
    weights : (n,) float64
        Positive.
    cap : float

    Returns
    -------
    (n,) float64
    """
    weights = np.asarray(weights, dtype=np.float64) / _sum(weights)
    for _ in range(_MAX_CAP_ROUNDS):
        if not weights.max() > cap:
            break
        weights = weights.copy()
        weights[weights > cap] = cap
        weights = weights / _sum(weights)
    return weights


def _zmuv_unit(patches: np.ndarray) -> np.ndarray:
    """``corner2image.m``: ``gly_zmuv.m`` (zero mean, standard deviation plus 1e-14) then the norm
    (no constant). (n, N) -> (n, N)."""
    out = patches - patches.mean(axis=1, keepdims=True)
    out /= patches.std(axis=1, ddof=1, keepdims=True) + TINY
    out /= np.sqrt(np.einsum("ij,ij->i", out, out))[:, None]
    return out


class L1Tracker(TemplateTracker):
    """L1 with ``init(frame, box)`` and ``update(frame) -> box`` (boxes 1-based ``x, y, w, h``);
    :class:`~nrmlc.lineage.l1apg.TemplateTracker`'s parameters, ``L1Params``; the seed draws the
    particles' noise (the templates need none)."""

    name = "L1"
    params_class = L1Params
    warm_up = staticmethod(warm_up)
    #: Problems the solver's step cap stopped, over the run (expected 0).
    unconverged = 0

    def init(self, frame: np.ndarray, box) -> None:
        """Start on ``frame`` ((H, W, 3) BGR or (H, W) uint8) at ``box``, then track that frame
        once, as the release's loop does (the box of this frame stays ``box``)."""
        p = self.params
        box, gray = self._start(frame, box)
        corners = box_corners(box)
        states = shifted_template_states(corners, p.n_templates, p.template_size)
        patches, in_range = crop_patches(gray, states, p.template_size)
        if not in_range.all():
            raise ParameterError(f"box {box.tolist()} must overlap the frame")
        with np.errstate(invalid="ignore", divide="ignore"):
            templates = _zmuv_unit(patches.reshape(p.n_templates, -1))
        if not np.isfinite(templates).all():
            raise ParameterError(f"box {box.tolist()} covers a patch of constant gray: no template can be made")
        self.templates = templates  # each row scaled to its weight (the release's A(:, 1:nT))
        self.fixed = templates[0] / p.n_templates
        self.weights = np.ones(p.n_templates)
        self.state = states[0].copy()
        self.samples = np.repeat(self.state[None], p.n_particles, axis=0)
        self._previous_choice = None  # MATLAB's id_max and c_max, kept across frames
        self._step(gray)

    def update(self, frame: np.ndarray) -> np.ndarray:
        """Track into ``frame``; the new box, (4,) float64."""
        self._step(gray_levels(frame))
        return self.box()

    def _step(self, gray: np.ndarray) -> None:
        """One pass of ``L1Tracking_release.m``'s loop on a gray frame (module docstring)."""
        p = self.params
        self._draw_particles()
        patches, in_range = crop_patches(gray, self.samples, p.template_size, out=self._patches)
        candidates = patches.reshape(p.n_particles, -1)
        candidates[~in_range] = 0.0  # IMGaffine_r.m returns zeros for a patch wholly outside
        candidates, _, _, _ = whiten(candidates)
        usable = in_range & (np.abs(candidates).sum(axis=1) != 0)
        likelihoods = np.zeros(p.n_particles)
        choice = None
        if usable.any():
            targets = np.ascontiguousarray(np.vstack([self.templates, self.fixed[None]]))
            coded = np.ascontiguousarray(candidates[usable])
            target_coefficients, _, steps = trivial_lasso(targets, coded, p.lam, return_steps=True)
            self.unconverged += int(np.count_nonzero(steps < 0))
            error = coded - target_coefficients @ targets
            likelihoods[usable] = np.exp(-p.alpha * np.sqrt(np.einsum("ij,ij->i", error, error)))
            # 'sum(c(1:nT)) < 0' skips a particle for the choice only; the first largest wins
            eligible = target_coefficients[:, :p.n_templates].sum(axis=1) >= 0
            if eligible.any():
                ranked = np.where(eligible, likelihoods[usable], -np.inf)
                row = int(np.argmax(ranked))
                choice = (int(np.flatnonzero(usable)[row]), target_coefficients[row].copy())
        if choice is None:
            choice = self._previous_choice
            if choice is None:
                return
        self._previous_choice = choice
        best, coefficients = choice
        self.state = self.samples[best].copy()
        self.samples = resample_states(self.samples, likelihoods, self.state)
        self._update_templates(candidates[best], coefficients[:p.n_templates])

    def _update_templates(self, answer: np.ndarray, coefficients: np.ndarray) -> None:
        """The release's template step (module docstring).

        Parameters
        ----------
        answer : (N,) float64
            The answer's whitened, normalised patch.
        coefficients : (nT,) float64
            Its target templates' coefficients.
        """
        p = self.params
        strongest = int(np.argmax(coefficients))
        angle = images_angle(answer, self.templates[strongest])
        weights = self.weights * np.exp(coefficients)
        templates = self.templates.copy()
        if angle > p.angle_threshold:
            weakest = int(np.argmin(weights))
            weights[weakest] = 0.0
            weights[weakest] = np.median(weights)
            templates[weakest] = answer
        weights = normalize_weights(weights, p.weight_cap)
        templates /= (np.sqrt(np.einsum("ij,ij->i", templates, templates)) + TINY)[:, None]
        self.templates = templates * weights[:, None]
        self.weights = weights
