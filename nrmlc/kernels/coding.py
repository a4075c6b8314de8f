"""Approximated-LLC coding of candidates over multiple local dictionaries.

Notation (paper Sections 3.1-3.4, Algorithm 1). Candidate ``y`` (one row of
the candidate matrix), template set ``T`` (rows), ``u`` = the candidate's
``k_max`` nearest template indices sorted by ascending distance. Dictionary
``j`` is ``B^j = [t_{u_1}, ..., t_{u_{k_j}}]`` (the first ``k_j``
neighbours). All problems have the form

    minimise  c' (G + ridge I) c   subject to  1'c = 1   [and c >= 0],

where ``G = A'A`` with ``A = B - y 1'``, because ``||y - B c||^2 =
||A c||^2`` whenever ``1'c = 1``. ``G`` is never formed from the
``dim``-length vectors: it is expanded from the template Gram ``TT``, the
inner products ``YT`` and ``|y|^2``,

    G[a, b] = TT[u_a, u_b] - YT[u_a] - YT[u_b] + |y|^2,

which costs ``O(k^2)`` per candidate and dictionary. The expansion cancels
terms of size ``|y|^2`` to produce entries of size ``||t - y||^2``, so
``G`` carries an absolute error of a few ulps of ``|y|^2`` (float64 dots)
or of the dots themselves (~1e-6 with float32 ``sgemm`` dots).

Three solver behaviours, shared by the coefficients ``c`` (kernel 1,
:func:`encode_dictionaries`) and the dictionary weights ``w`` (kernel 2,
:func:`combine_dictionaries`):

* ``ridge > 0``, ``constrained=False`` (the paper's regularised coder, eq.
  allcr/allcw): ``c = (G + ridge I)^{-1} 1 / (1' (G + ridge I)^{-1} 1)``.
  The paper prints the solution without the division; the Lagrangian
  solution of the sum-to-one problem needs it (it is only a rescaling, so
  signs and ratios are the paper's).
* ``ridge == 0``, ``constrained=False`` ("plain" approximated LLC, eq. allc):
  ``G`` may be singular (duplicate templates, ``k`` above the rank). The
  factorisation then uses a diagonal jitter
  ``PLAIN_JITTER * (|y|^2 + max_a |t_{u_a}|^2)`` (see :data:`PLAIN_JITTER`)
  and removes its bias with a few steps of iterated Tikhonov refinement
  (:func:`_solve_sum_to_one`). The result approximates the limit
  ``ridge -> 0+`` (the exact solution for non-singular ``G``, the
  minimum-norm minimiser for singular ``G``): the error along an eigenvalue
  ``e`` of ``G`` is damped by ``(jitter / (e + jitter))^4``, so only
  directions with ``e`` below ~the jitter (rounding-noise level) keep a
  Tikhonov-regularised value. The jitter is scaled by the data (not by ``G``) because it
  must dominate the rounding noise of the expansion, which is proportional
  to ``|y|^2 + |t|^2``; a ``G`` that is zero up to rounding (all templates
  equal to ``y``) then yields the uniform ``1/k`` instead of amplified
  noise. Any ``ridge`` below the jitter is handled the same way.
* ``constrained=True`` (the paper's non-negative problems, eq. allcn/multillc):
  the exact QP with ``c >= 0`` as well, solved by a primal active-set method
  (:func:`_solve_simplex_qp`). With the jitter active it first solves the
  jittered QP (unique minimiser; among tied optima, near the minimum-norm
  one) and then continues with the exact objective to remove the bias.

Every small ``k x k`` system is solved by a hand-written Cholesky
factorisation in per-candidate work buffers. If a pivot falls below half the
diagonal shift (impossible in exact arithmetic for ``G`` PSD, so a sign that
rounding noise made ``G`` indefinite) the shift is multiplied by 10 and the
factorisation retried (without refinement); the result is therefore finite
for any finite input. Non-finite inputs give NaN coefficients rather than a
silent fallback.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from nrmlc.config import NUMBA_FLAGS, PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.kernels.checks import check_array, check_flag, check_indices, check_int, check_length, check_nonnegative_real
from nrmlc.kernels.distance import _nearest_row, _squared_norm

__all__ = ["PLAIN_JITTER", "encode_dictionaries", "combine_dictionaries", "code_candidates", "scatter_codes"]

#: Relative diagonal jitter of the factorisation when ``ridge`` is 0 (or smaller
#: than the jitter), in units of ``|y|^2 + max |t|^2`` over the dictionary. With
#: float64 dots the rounding noise of the expanded Gram is ~1e-16 of that scale,
#: so the jitter dominates it by ~1e6; its bias on the solution is then removed
#: by iterated Tikhonov refinement (``_REFINEMENTS`` steps).
PLAIN_JITTER = 1e-10

#: Absolute lower bound of the diagonal shift, for all-zero data (G == 0 exactly).
#: Small enough to be irrelevant, large enough that ``1/shift`` cannot overflow.
_SHIFT_FLOOR = 1e-290

#: Each failed Cholesky multiplies the shift by 10; 40 retries take the shift
#: from the jitter far beyond any rounding noise of finite data.
_MAX_RETRIES = 40

#: Iterated-Tikhonov steps that remove the jitter's bias when it is active.
_REFINEMENTS = 3

#: Tolerance of the active-set optimality test, relative to the largest diagonal
#: entry of ``G + ridge I`` (the scale of the gradient).
_KKT_TOLERANCE = 1e-11


@njit(**NUMBA_FLAGS)
def _diagonal_shift(ridge, data_scale):
    """Factorisation shift ``max(ridge, PLAIN_JITTER * data_scale, _SHIFT_FLOOR)``."""
    shift = ridge
    jitter = PLAIN_JITTER * data_scale
    if jitter > shift:
        shift = jitter
    if shift < _SHIFT_FLOOR:
        shift = _SHIFT_FLOOR
    return shift


@njit(**NUMBA_FLAGS)
def _substitute(chol, n, solution, refine, rhs_scale):
    """Solve ``L L' x = 1`` or, if ``refine``, ``L L' x = 1 + rhs_scale * x_old``.

    Works in place: ``x_old`` is read from ``solution``; forward substitution
    consumes ``solution[r]`` before overwriting it with ``z[r]``, so no second
    buffer is needed. Without ``refine`` the stale buffer content is not read
    (it may be uninitialised, and ``0 * NaN`` is NaN).
    """
    for r in range(n):
        value = 1.0
        if refine:
            value += rhs_scale * solution[r]
        for p in range(r):
            value -= chol[r, p] * solution[p]
        solution[r] = value / chol[r, r]
    for r in range(n - 1, -1, -1):
        value = solution[r]
        for p in range(r + 1, n):
            value -= chol[p, r] * solution[p]
        solution[r] = value / chol[r, r]


@njit(**NUMBA_FLAGS)
def _solve_sum_to_one(gram, members, n_members, ridge, shift, chol, solution, n_prefactored):
    """Minimise ``c' (G_W + ridge I) c`` subject to ``1'c = 1``.

    Computes ``x = (G_W + ridge I)^{-1} 1`` and returns ``c = x / 1'x``. The
    matrix is factorised as ``L L' = G_W + shift I`` with ``shift >= ridge``;
    when ``shift > ridge`` (the jitter is active) ``x`` is refined by
    ``_REFINEMENTS`` steps of iterated Tikhonov,
    ``x <- (G_W + shift I)^{-1} (1 + (shift - ridge) x)``, which converge to
    ``(G_W + ridge I)^{-1} 1`` (to the minimum-norm limit for singular
    ``G_W`` and ``ridge == 0``), each step shrinking the error component on
    eigenvalue ``e`` by ``(shift - ridge) / (e + shift)``.

    Parameters
    ----------
    gram : ndarray, shape (k_max, k_max)
        Symmetric PSD matrix ``G``; only rows/columns in ``members`` are read.
    members : ndarray, shape (k_max,), int64
        ``members[:n_members]`` is the index set ``W`` of the subproblem.
    n_members : int
        Size of ``W`` (at least 1).
    ridge : float
        The problem's ridge (>= 0).
    shift : float
        Factorisation shift, ``>= ridge`` and > 0.
    chol : ndarray, shape (k_max, k_max)
        Work buffer for the Cholesky factor ``L`` (lower triangle).
    solution : ndarray, shape (k_max,)
        Output: ``solution[:n_members]`` is ``c`` in the order of ``members``.
    n_prefactored : int
        Leading rows of ``chol`` that already hold the factor of this
        ``G_W + shift I`` (same members in the same order, same shift); the
        first factorisation starts after them. The rows of a Cholesky factor
        depend only on the leading block, so the nested dictionaries of one
        candidate share them: the result is bit for bit the same as from a
        factorisation from row 0.

    Returns
    -------
    shift_used : float
        The shift of the accepted factorisation: ``shift`` unless rounding
        made ``G_W + shift I`` numerically indefinite, in which case it was
        multiplied by 10 until the factorisation succeeded and the result is
        the (unrefined) solution for that larger shift.
    n_factored : int
        Leading rows of ``chol`` now holding the factor of ``G_W + shift I``
        (``n_members`` after a first factorisation that succeeded, else 0).
    """
    n = n_members
    for r in range(n):
        for q in range(r + 1):
            if not np.isfinite(gram[members[r], members[q]]):
                # Garbage in, visible garbage out: no silent fallback on NaN/inf.
                for s in range(n):
                    solution[s] = np.nan
                return shift, 0
    current = shift
    for attempt in range(_MAX_RETRIES):
        # In exact arithmetic every pivot of G_W + s I is >= s (G_W is PSD);
        # a pivot below s/2 means rounding made G_W indefinite at this scale.
        threshold = 0.5 * current
        factorised = True
        for r in range(n_prefactored if attempt == 0 else 0, n):
            row = members[r]
            for q in range(r + 1):
                value = gram[row, members[q]]
                for p in range(q):
                    value -= chol[r, p] * chol[q, p]
                if q == r:
                    value += current
                    if not value >= threshold:
                        factorised = False
                        break
                    chol[r, r] = np.sqrt(value)
                else:
                    chol[r, q] = value / chol[q, q]
            if not factorised:
                break
        if factorised:
            _substitute(chol, n, solution, False, 0.0)
            # Refining after a retry would amplify the noise directions that
            # forced the retry (by up to 2 per step), so only refine a clean
            # first factorisation.
            if attempt == 0 and current > ridge:
                for _step in range(_REFINEMENTS):
                    _substitute(chol, n, solution, True, current - ridge)
            total = 0.0
            for r in range(n):
                total += solution[r]
            # 1'F^{-1}1 > 0 for F positive definite; anything else is a failure.
            if total > 0.0 and total < np.inf:
                for r in range(n):
                    solution[r] = solution[r] / total
                return current, (n if attempt == 0 else 0)
        current *= 10.0
    # Unreachable for finite data of sane magnitude; keep the output feasible.
    for r in range(n):
        solution[r] = 1.0 / n
    return current, 0


@njit(**NUMBA_FLAGS)
def _solve_simplex_qp(gram, k, ridge, shift, chol, members, is_free, trial, grad, coef):
    """Minimise ``c' (G + ridge I) c`` subject to ``c >= 0`` and ``1'c = 1``.

    Primal active-set method on the leading ``k x k`` block of ``gram``:

    1. start at the barycentre ``1/k`` with every variable free (feasible).
       When the closed-form solution is already non-negative (the usual case
       at the paper's ``ridge = 1``) this finishes after one solve; a start
       at the best vertex ``e_a`` measured 3.4x slower there, since it adds
       variables one solve at a time;
    2. solve the equality-constrained subproblem on the free set ``W``
       (:func:`_solve_sum_to_one`);
    3. if that point has negative entries, move towards it as far as
       feasibility allows (ratio test) and drop the blocking variable(s);
    4. otherwise accept it and compute the gradient ``g = 2 F c``. On ``W``,
       ``g_a`` equals the multiplier ``mu = c'g`` of the sum constraint; a
       bound variable ``b`` is optimal iff ``g_b - mu >= -tol`` (``tol`` =
       1e-11 of the largest diagonal entry). Release the one with the most
       negative ``g_b - mu`` (lowest index on ties) or stop.

    When ``shift > ridge`` (the jitter is active, e.g. ``ridge == 0``) this
    runs in two phases. Phase 1 uses ``F = G + shift I``: strictly convex,
    so its minimiser is unique and, among tied optima of the ``ridge``
    problem (e.g. identical dictionary reconstructions), close to the
    minimum-norm one, as the ``ridge -> 0+`` limit would pick. Phase 2
    continues from there with the true ``F = G + ridge I`` and refined
    subproblems, removing the jitter's bias (which is ``jitter / curvature``
    and reached 1e-4 on near-degenerate weight problems).

    The objective strictly decreases between accepted points, so each phase
    terminates in exact arithmetic; against cycling on degenerate (rounding
    driven) steps each phase is capped at ``4 k + 10`` subproblem solves,
    after which its current feasible point is kept. Problems with
    ``k <= 16`` take a handful of solves in practice.

    Parameters
    ----------
    gram : ndarray, shape (k_max, k_max)
        Symmetric PSD matrix ``G``.
    k : int
        Number of variables (leading block used).
    ridge : float
        The problem's ridge (>= 0).
    shift : float
        ``max(ridge, jitter)``, the factorisation shift.
    chol : ndarray, shape (k_max, k_max)
        Cholesky work buffer.
    members, is_free : ndarray, shape (k_max,), int64
        Work buffers: free-set list and free-set indicator.
    trial, grad : ndarray, shape (k_max,), float64
        Work buffers: subproblem solution, gradient.
    coef : ndarray, shape (k_max,), float64
        Output ``c`` in ``coef[:k]``.

    Returns
    -------
    n_solves : int
        Number of subproblem solves over both phases.
    """
    largest_diagonal = gram[0, 0]
    for a in range(k):
        coef[a] = 1.0 / k
        is_free[a] = 1
        if gram[a, a] > largest_diagonal:
            largest_diagonal = gram[a, a]
    tolerance = _KKT_TOLERANCE * (abs(largest_diagonal) + shift)

    n_solves = 0
    n_phases = 2 if shift > ridge else 1
    for phase in range(n_phases):
        objective_ridge = shift if phase == 0 else ridge
        phase_solves = 0
        while phase_solves < 4 * k + 10:
            n_free = 0
            for a in range(k):
                if is_free[a] == 1:
                    members[n_free] = a
                    n_free += 1
            _solve_sum_to_one(gram, members, n_free, objective_ridge, shift, chol, trial, 0)
            phase_solves += 1
            if not np.isfinite(trial[0]):
                for a in range(k):
                    coef[a] = np.nan
                return n_solves + phase_solves

            # Ratio test: the largest step towards the subproblem solution
            # that keeps every free variable non-negative.
            step = 1.0
            blocking = -1
            for r in range(n_free):
                if trial[r] < 0.0:
                    a = members[r]
                    ratio = coef[a] / (coef[a] - trial[r])
                    if ratio < step:
                        step = ratio
                        blocking = a
            if blocking >= 0:
                for r in range(n_free):
                    a = members[r]
                    coef[a] += step * (trial[r] - coef[a])
                coef[blocking] = 0.0
                is_free[blocking] = 0
                for r in range(n_free):
                    a = members[r]
                    if coef[a] <= 0.0:  # ties of the ratio test leave them at ~0
                        coef[a] = 0.0
                        is_free[a] = 0
                continue

            for r in range(n_free):
                coef[members[r]] = trial[r]
            multiplier = 0.0
            for a in range(k):
                value = objective_ridge * coef[a]
                for b in range(k):
                    value += gram[a, b] * coef[b]
                grad[a] = 2.0 * value
                multiplier += coef[a] * grad[a]
            entering = -1
            most_negative = -tolerance
            for a in range(k):
                if is_free[a] == 0:
                    slack = grad[a] - multiplier
                    if slack < most_negative:
                        most_negative = slack
                        entering = a
            if entering < 0:
                break
            is_free[entering] = 1
        n_solves += phase_solves

    # Steps accumulate rounding; restore exact feasibility.
    total = 0.0
    for a in range(k):
        if coef[a] < 0.0:
            coef[a] = 0.0
        total += coef[a]
    for a in range(k):
        coef[a] = coef[a] / total
    return n_solves


@njit(**NUMBA_FLAGS)
def _solve(gram, k, ridge, shift, constrained, chol, members, is_free, trial, grad, out, n_prefactored):
    """Dispatch to the closed form or the QP; writes the solution to ``out[:k]``.

    ``n_prefactored`` (closed form only) leading rows of ``chol`` hold the factor
    of ``G + shift I`` already (see :func:`_solve_sum_to_one`). Returns the
    number of leading rows of ``chol`` that do after the call (0 for the QP).
    """
    if constrained:
        _solve_simplex_qp(gram, k, ridge, shift, chol, members, is_free, trial, grad, out)
        return 0
    for a in range(k):
        members[a] = a
    _, n_factored = _solve_sum_to_one(gram, members, k, ridge, shift, chol, out, n_prefactored)
    return n_factored


@njit(**NUMBA_FLAGS)
def _encode_row(template_gram, dots_row, sq_norm, neighbours, dictionary_sizes, ridge, constrained, gram, chol,
                real_work, int_work, coefficients):
    """Coefficients of one candidate on each of its nested dictionaries (see :func:`encode_dictionaries`).

    ``gram``, ``chol`` (k_max, k_max), ``real_work`` (3, k_max), ``int_work`` (2, k_max)
    are this candidate's work buffers; ``coefficients`` (m, k_max) its output rows.
    """
    k_max = neighbours.shape[0]
    n_dictionaries = dictionary_sizes.shape[0]
    # Gram of A = B - y 1' for the full k_max support; the dictionaries are
    # nested (first k_j neighbours) so each uses its leading block.
    for a in range(k_max):
        ua = neighbours[a]
        for b in range(a + 1):
            ub = neighbours[b]
            # Grouped so that each bracket is a difference of near-equal
            # terms (fastmath may regroup; the error stays a few ulps of
            # |y|^2 + |t|^2 either way, far below the jitter).
            value = (template_gram[ua, ub] - dots_row[ua]) - (dots_row[ub] - sq_norm)
            gram[a, b] = value
            gram[b, a] = value
    # Rows of chol holding the factor of G + factored_shift I: the
    # dictionaries are nested, so with the paper's increasing sizes and one
    # shift each factorisation continues the previous one.
    n_factored = 0
    factored_shift = -1.0
    for j in range(n_dictionaries):
        k = dictionary_sizes[j]
        largest = 0.0
        for a in range(k):
            ua = neighbours[a]
            if template_gram[ua, ua] > largest:
                largest = template_gram[ua, ua]
        shift = _diagonal_shift(ridge, sq_norm + largest)
        reusable = min(n_factored, k) if shift == factored_shift else 0
        out = real_work[2]
        n_now = _solve(gram, k, ridge, shift, constrained, chol, int_work[0], int_work[1],
                       real_work[0], real_work[1], out, reusable)
        if n_now > 0:
            n_factored = max(n_now, reusable)
            factored_shift = shift
        else:
            n_factored = 0
        for a in range(k):
            coefficients[j, a] = out[a]


@njit(**PARALLEL_FLAGS)
def _encode_dictionaries(
    template_gram, dots, candidate_sq_norms, neighbour_indices, dictionary_sizes,
    ridge, constrained, gram_work, chol_work, real_work, int_work, coefficients,
):
    for i in prange(neighbour_indices.shape[0]):
        _encode_row(template_gram, dots[i], candidate_sq_norms[i], neighbour_indices[i], dictionary_sizes, ridge,
                    constrained, gram_work[i], chol_work[i], real_work[i], int_work[i], coefficients[i])


@njit(**NUMBA_FLAGS)
def _combine_row(template_gram, dots_row, sq_norm, neighbours, coefficients, dictionary_sizes, n_positive, ridge,
                 constrained, n_iterations, support_gram, images, gram, chol, real_work, int_work, weights, codes):
    """Weights, code and confidence errors of one candidate (see :func:`combine_dictionaries`).

    ``coefficients`` (m, k_max) are its per-dictionary codes. Work buffers:
    ``support_gram`` (k_max, k_max), TT restricted to the support S; ``images``
    (m, k_max), ``images[j] = TT_S d^j``; ``gram`` (m, m), the Gram of D - y 1';
    ``chol`` (m, m); ``real_work`` (4, m); ``int_work`` (2, m). Outputs: ``weights``
    (m,) and ``codes`` (k_max,). Returns ``(error_positive, error_negative)``.
    """
    k_max = neighbours.shape[0]
    n_dictionaries = dictionary_sizes.shape[0]
    projections = real_work[3]   # projections[j] = d^j . YT_S
    solved = real_work[2]        # the w of eq. allcw
    for a in range(k_max):
        for b in range(a + 1):
            value = template_gram[neighbours[a], neighbours[b]]
            support_gram[a, b] = value
            support_gram[b, a] = value

    # Reconstructions D_j = T d^j, handled through d^j's support coordinates
    # (= coefficients[j, :k_j]); entries beyond k_j are ignored.
    largest = 0.0
    for j in range(n_dictionaries):
        k = dictionary_sizes[j]
        projection = 0.0
        energy = 0.0
        for a in range(k_max):
            value = 0.0
            for b in range(k):
                value += support_gram[a, b] * coefficients[j, b]
            images[j, a] = value
        for a in range(k):
            projection += coefficients[j, a] * dots_row[neighbours[a]]
            energy += coefficients[j, a] * images[j, a]
        projections[j] = projection
        if energy > largest:
            largest = energy
    # (D_j - y).(D_l - y) = d^j' TT_S d^l - d^j.YT_S - d^l.YT_S + |y|^2
    for j in range(n_dictionaries):
        k = dictionary_sizes[j]
        for l in range(j + 1):
            cross = 0.0
            for a in range(k):
                cross += coefficients[j, a] * images[l, a]
            value = (cross - projections[j]) - (projections[l] - sq_norm)
            gram[j, l] = value
            gram[l, j] = value

    # Algorithm 1. Step 3.2 solves eq. allcw, whose Gram does not depend on
    # d, so every pass yields the same w: solve it once. Step 3.1 of pass t
    # combines with the w of pass t-1: uniform on the first pass, the
    # solved w from the second pass on.
    uniform = 1.0 / n_dictionaries
    if n_iterations >= 1:
        shift = _diagonal_shift(ridge, sq_norm + largest)
        _solve(gram, n_dictionaries, ridge, shift, constrained, chol, int_work[0],
               int_work[1], real_work[0], real_work[1], solved, 0)
        for j in range(n_dictionaries):
            weights[j] = solved[j]
    else:
        for j in range(n_dictionaries):
            weights[j] = uniform
    for a in range(k_max):
        value = 0.0
        for j in range(n_dictionaries):
            if a < dictionary_sizes[j]:
                if n_iterations >= 2:
                    value += solved[j] * coefficients[j, a]
                else:
                    value += uniform * coefficients[j, a]
        codes[a] = value

    # eq. conf: reconstruction errors of the positive and negative parts,
    # |y|^2 - 2 d_P.YT_P + d_P' TT_PP d_P for P = positive or negative support.
    linear_positive = 0.0
    quadratic_positive = 0.0
    linear_negative = 0.0
    quadratic_negative = 0.0
    for a in range(k_max):
        positive_a = neighbours[a] < n_positive
        part = 0.0
        for b in range(k_max):
            if (neighbours[b] < n_positive) == positive_a:
                part += support_gram[a, b] * codes[b]
        if positive_a:
            linear_positive += codes[a] * dots_row[neighbours[a]]
            quadratic_positive += codes[a] * part
        else:
            linear_negative += codes[a] * dots_row[neighbours[a]]
            quadratic_negative += codes[a] * part
    positive = (sq_norm - linear_positive) + (quadratic_positive - linear_positive)
    negative = (sq_norm - linear_negative) + (quadratic_negative - linear_negative)
    return (positive if positive > 0.0 else 0.0), (negative if negative > 0.0 else 0.0)


@njit(**PARALLEL_FLAGS)
def _combine_dictionaries(
    template_gram, dots, candidate_sq_norms, neighbour_indices, coefficients,
    dictionary_sizes, n_positive, ridge, constrained, n_iterations,
    support_work, image_work, gram_work, chol_work, real_work, int_work,
    weights, codes, error_positive, error_negative,
):
    for i in prange(neighbour_indices.shape[0]):
        error_positive[i], error_negative[i] = _combine_row(
            template_gram, dots[i], candidate_sq_norms[i], neighbour_indices[i], coefficients[i], dictionary_sizes,
            n_positive, ridge, constrained, n_iterations, support_work[i], image_work[i], gram_work[i], chol_work[i],
            real_work[i], int_work[i], weights[i], codes[i])


@njit(**PARALLEL_FLAGS)
def _code_candidates(
    candidates, dots, template_gram, template_sq_norms, dictionary_sizes, n_positive, ridge_c, ridge_w,
    constrained, n_iterations, sq_norms, neighbour_indices, sq_distances,
    gram_work, chol_work, real_work, int_work, coefficients,
    support_work, image_work, w_gram_work, w_chol_work, w_real_work, w_int_work,
    weights, codes, error_positive, error_negative,
):
    for i in prange(candidates.shape[0]):
        sq_norm = _squared_norm(candidates[i])
        sq_norms[i] = sq_norm
        _nearest_row(dots[i], sq_norm, template_sq_norms, neighbour_indices[i], sq_distances[i])
        _encode_row(template_gram, dots[i], sq_norm, neighbour_indices[i], dictionary_sizes, ridge_c, constrained,
                    gram_work[i], chol_work[i], real_work[i], int_work[i], coefficients[i])
        error_positive[i], error_negative[i] = _combine_row(
            template_gram, dots[i], sq_norm, neighbour_indices[i], coefficients[i], dictionary_sizes, n_positive,
            ridge_w, constrained, n_iterations, support_work[i], image_work[i], w_gram_work[i], w_chol_work[i],
            w_real_work[i], w_int_work[i], weights[i], codes[i])


# ---------------------------------------------------------------------------
# Checked public wrappers
# ---------------------------------------------------------------------------

def _solver_work(n_candidates: int, size: int, n_real: int):
    """Per-candidate work buffers of :func:`_solve` for problems of up to ``size`` variables,
    allocated once outside the parallel loop: Cholesky factor ``(n, size, size)``, ``n_real``
    real vectors (the solver uses two, the caller the rest) and two integer vectors."""
    return (np.empty((n_candidates, size, size), dtype=np.float64),
            np.empty((n_candidates, n_real, size), dtype=np.float64),
            np.empty((n_candidates, 2, size), dtype=np.int64))


def _encode_work(n_candidates: int, k_max: int):
    """Work buffers of :func:`_encode_row`, one set per candidate: gram, chol, real, int."""
    return (np.empty((n_candidates, k_max, k_max), dtype=np.float64), *_solver_work(n_candidates, k_max, 3))


def _combine_work(n_candidates: int, n_dictionaries: int, k_max: int):
    """Work buffers of :func:`_combine_row`, one set per candidate: support Gram, images, gram,
    chol, real, int."""
    return (np.empty((n_candidates, k_max, k_max), dtype=np.float64),
            np.empty((n_candidates, n_dictionaries, k_max), dtype=np.float64),
            np.empty((n_candidates, n_dictionaries, n_dictionaries), dtype=np.float64),
            *_solver_work(n_candidates, n_dictionaries, 4))


def _combine_outputs(n_candidates: int, n_dictionaries: int, k_max: int):
    """weights (n, m), codes (n, k_max), error_positive (n,), error_negative (n,)."""
    return (np.empty((n_candidates, n_dictionaries), dtype=np.float64),
            np.empty((n_candidates, k_max), dtype=np.float64),
            np.empty(n_candidates, dtype=np.float64), np.empty(n_candidates, dtype=np.float64))


def _check_common(template_gram, dots, candidate_sq_norms, neighbour_indices, dictionary_sizes):
    """Validate the inputs shared by both kernels; return (n_candidates, n_templates, k_max)."""
    check_array("template_gram", template_gram, np.float64, 2)
    check_array("dots", dots, np.float64, 2)
    check_array("candidate_sq_norms", candidate_sq_norms, np.float64, 1)
    check_array("neighbour_indices", neighbour_indices, np.int64, 2)
    check_array("dictionary_sizes", dictionary_sizes, np.int64, 1)
    n_candidates, n_templates = dots.shape
    if template_gram.shape != (n_templates, n_templates):
        raise ParameterError(
            f"template_gram must have shape ({n_templates}, {n_templates}), got {template_gram.shape}"
        )
    check_length("candidate_sq_norms", candidate_sq_norms, n_candidates, f"dots has {n_candidates} rows")
    check_length("neighbour_indices", neighbour_indices, n_candidates, f"dots has {n_candidates} rows")
    k_max = neighbour_indices.shape[1]
    if k_max < 1:
        raise ParameterError("neighbour_indices must have at least one column")
    check_indices("neighbour_indices", neighbour_indices, n_templates)
    if dictionary_sizes.shape[0] < 1:
        raise ParameterError("dictionary_sizes must list at least one dictionary")
    if dictionary_sizes.min() < 1 or dictionary_sizes.max() > k_max:
        raise ParameterError(
            f"dictionary_sizes must lie in [1, k_max={k_max}], got {dictionary_sizes.tolist()}"
        )
    return n_candidates, n_templates, k_max


def encode_dictionaries(
    template_gram: np.ndarray,
    dots: np.ndarray,
    candidate_sq_norms: np.ndarray,
    neighbour_indices: np.ndarray,
    dictionary_sizes: np.ndarray,
    ridge: float,
    constrained: bool,
) -> np.ndarray:
    """Approximated-LLC coefficients of every candidate over each local dictionary.

    Dictionary ``j`` of candidate ``i`` is made of its ``dictionary_sizes[j]``
    nearest templates; its coefficients solve (module docstring)
    ``min ||y_i - B^j c||^2 + ridge ||c||^2`` s.t. ``1'c = 1`` (closed form,
    eq. allcr), and also ``c >= 0`` when ``constrained`` (eq. allcn/knn).

    Parameters
    ----------
    template_gram : ndarray, shape (n_templates, n_templates), float64
        ``T T'`` (:func:`nrmlc.kernels.distance.template_gram`), symmetric.
    dots : ndarray, shape (n_candidates, n_templates), float64
        ``Y T'`` (:func:`nrmlc.kernels.distance.candidate_template_dots`).
    candidate_sq_norms : ndarray, shape (n_candidates,), float64
        ``|y_i|^2``.
    neighbour_indices : ndarray, shape (n_candidates, k_max), int64
        Nearest template indices sorted by ascending distance
        (:func:`nrmlc.kernels.distance.nearest_templates`).
    dictionary_sizes : ndarray, shape (n_dictionaries,), int64
        Sizes ``k_j`` (e.g. ``[5, 8, 10]``), each in ``[1, k_max]``.
    ridge : float
        ``lambda >= 0``. Zero selects the plain coder (jitter, see
        :data:`PLAIN_JITTER`).
    constrained : bool
        Solve the exact non-negative QP instead of the closed form.

    Returns
    -------
    coefficients : ndarray, shape (n_candidates, n_dictionaries, k_max), float64
        ``coefficients[i, j, a]`` weighs template ``neighbour_indices[i, a]``
        in dictionary ``j``; entries with ``a >= dictionary_sizes[j]`` are 0.
        Each row over its dictionary sums to 1.
    """
    n_candidates, _, k_max = _check_common(
        template_gram, dots, candidate_sq_norms, neighbour_indices, dictionary_sizes
    )
    ridge = check_nonnegative_real("ridge", ridge)
    constrained = check_flag("constrained", constrained)
    n_dictionaries = dictionary_sizes.shape[0]
    coefficients = np.zeros((n_candidates, n_dictionaries, k_max), dtype=np.float64)
    _encode_dictionaries(template_gram, dots, candidate_sq_norms, neighbour_indices, dictionary_sizes,
                         ridge, constrained, *_encode_work(n_candidates, k_max), coefficients)
    return coefficients


def combine_dictionaries(
    template_gram: np.ndarray,
    dots: np.ndarray,
    candidate_sq_norms: np.ndarray,
    neighbour_indices: np.ndarray,
    coefficients: np.ndarray,
    dictionary_sizes: np.ndarray,
    n_positive: int,
    ridge: float,
    constrained: bool,
    n_iterations: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Dictionary weights, output codes and confidence errors (Algorithm 1, eq. conf).

    With ``d^j`` = the coefficients of dictionary ``j`` scattered onto the
    templates (eq. allocation) and ``D = [T d^1, ..., T d^m]``, the weights
    solve ``min ||y - D w||^2 + ridge ||w||^2`` s.t. ``1'w = 1`` (eq. allcw;
    also ``w >= 0`` when ``constrained``, eq. multillc) with the same solver
    as :func:`encode_dictionaries`. Algorithm 1: ``w = 1/m``; repeat
    ``n_iterations`` times {``d = sum_j w_j d^j``; solve ``w``}. The ``w``
    problem does not depend on ``d``, so ``w`` is solved once and the
    alternation is at its fixed point after one pass.

    Parameters
    ----------
    template_gram, dots, candidate_sq_norms, neighbour_indices, dictionary_sizes
        As in :func:`encode_dictionaries`.
    coefficients : ndarray, shape (n_candidates, n_dictionaries, k_max), float64
        Output of :func:`encode_dictionaries`; entries beyond ``k_j`` are ignored.
    n_positive : int
        Templates ``0 .. n_positive-1`` are positive, the rest negative.
    ridge : float
        ``beta >= 0`` for the weight problem (0: plain, with jitter).
    constrained : bool
        Solve the non-negative QP for ``w`` instead of the closed form.
    n_iterations : int
        Passes ``T >= 0`` of Algorithm 1.

    Returns
    -------
    weights : ndarray, shape (n_candidates, n_dictionaries), float64
        Final ``w`` (uniform ``1/m`` when ``n_iterations == 0``).
    codes : ndarray, shape (n_candidates, k_max), float64
        The output code ``d_i`` in support coordinates: ``codes[i, a]`` weighs
        template ``neighbour_indices[i, a]`` (see :func:`scatter_codes`). It
        is the last step-3.1 combination: uniform ``w`` for
        ``n_iterations <= 1``, the solved ``w`` for ``n_iterations >= 2``.
    error_positive, error_negative : ndarray, shape (n_candidates,), float64
        ``||y - T_pos d_pos||^2`` and ``||y - T_neg d_neg||^2`` (eq. conf),
        clamped at 0 against cancellation.
    """
    n_candidates, n_templates, k_max = _check_common(
        template_gram, dots, candidate_sq_norms, neighbour_indices, dictionary_sizes
    )
    n_dictionaries = dictionary_sizes.shape[0]
    check_array("coefficients", coefficients, np.float64, 3)
    if coefficients.shape != (n_candidates, n_dictionaries, k_max):
        raise ParameterError(
            f"coefficients must have shape ({n_candidates}, {n_dictionaries}, {k_max}), "
            f"got {coefficients.shape}"
        )
    n_positive = check_int("n_positive", n_positive, 0, n_templates)
    ridge = check_nonnegative_real("ridge", ridge)
    constrained = check_flag("constrained", constrained)
    n_iterations = check_int("n_iterations", n_iterations, 0)

    outputs = _combine_outputs(n_candidates, n_dictionaries, k_max)
    _combine_dictionaries(template_gram, dots, candidate_sq_norms, neighbour_indices, coefficients,
                          dictionary_sizes, n_positive, ridge, constrained, n_iterations,
                          *_combine_work(n_candidates, n_dictionaries, k_max), *outputs)
    return outputs


def code_candidates(
    candidates: np.ndarray,
    dots: np.ndarray,
    template_gram: np.ndarray,
    template_sq_norms: np.ndarray,
    dictionary_sizes: np.ndarray,
    n_positive: int,
    ridge_c: float,
    ridge_w: float,
    constrained: bool,
    n_iterations: int,
) -> dict:
    """Everything after the product, for every candidate, in one parallel pass.

    The same results, bit for bit, as :func:`~nrmlc.kernels.distance.squared_norms`,
    :func:`~nrmlc.kernels.distance.nearest_templates` (``k_max =
    max(dictionary_sizes)``), :func:`encode_dictionaries` and
    :func:`combine_dictionaries` called in turn (``tests/test_coding.py``), but each
    candidate goes through the four steps on one thread while its row of ``dots`` is
    in cache, and the threads meet once instead of four times: on a shared machine,
    where a waiting thread may not get its core back at once, each meeting cost up to
    milliseconds.

    Parameters
    ----------
    candidates : ndarray, shape (n_candidates, dim), float32 or float64, C-contiguous
    dots : ndarray, shape (n_candidates, n_templates), float64
        ``candidates @ templates.T`` (:func:`~nrmlc.kernels.distance.candidate_template_dots`).
    template_gram : ndarray, shape (n_templates, n_templates), float64
    template_sq_norms : ndarray, shape (n_templates,), float64
    dictionary_sizes : ndarray, shape (n_dictionaries,), int64
        Sizes ``k_j``; the support is the ``k_max = max(k_j)`` nearest templates.
    n_positive : int
        Templates ``0 .. n_positive-1`` are positive.
    ridge_c, ridge_w : float
        ``lambda`` (coefficients) and ``beta`` (weights), >= 0.
    constrained : bool
    n_iterations : int
        Passes T of Algorithm 1.

    Returns
    -------
    dict with ``sq_norms (n,)``, ``neighbours (n, k_max)`` int64, ``sq_distances
    (n, k_max)``, ``coefficients (n, m, k_max)``, ``weights (n, m)``, ``codes (n, k_max)``,
    ``error_positive (n,)``, ``error_negative (n,)``, as the four functions return them.
    """
    check_array("candidates", candidates, (np.float32, np.float64), 2)
    check_array("dots", dots, np.float64, 2)
    check_array("template_gram", template_gram, np.float64, 2)
    check_array("template_sq_norms", template_sq_norms, np.float64, 1)
    check_array("dictionary_sizes", dictionary_sizes, np.int64, 1)
    n_candidates, n_templates = dots.shape
    check_length("candidates", candidates, n_candidates, f"dots has {n_candidates} rows")
    if template_gram.shape != (n_templates, n_templates):
        raise ParameterError(
            f"template_gram must have shape ({n_templates}, {n_templates}), got {template_gram.shape}")
    check_length("template_sq_norms", template_sq_norms, n_templates, f"dots has {n_templates} columns")
    if dictionary_sizes.shape[0] < 1:
        raise ParameterError("dictionary_sizes must list at least one dictionary")
    k_max = check_int("max(dictionary_sizes)", int(dictionary_sizes.max()), 1, n_templates)
    if dictionary_sizes.min() < 1:
        raise ParameterError(f"dictionary_sizes must be >= 1, got {dictionary_sizes.tolist()}")
    n_positive = check_int("n_positive", n_positive, 0, n_templates)
    ridge_c = check_nonnegative_real("ridge_c", ridge_c)
    ridge_w = check_nonnegative_real("ridge_w", ridge_w)
    constrained = check_flag("constrained", constrained)
    n_iterations = check_int("n_iterations", n_iterations, 0)
    n_dictionaries = dictionary_sizes.shape[0]
    sq_norms = np.empty(n_candidates, dtype=np.float64)
    neighbours = np.empty((n_candidates, k_max), dtype=np.int64)
    sq_distances = np.empty((n_candidates, k_max), dtype=np.float64)
    coefficients = np.zeros((n_candidates, n_dictionaries, k_max), dtype=np.float64)
    outputs = _combine_outputs(n_candidates, n_dictionaries, k_max)
    _code_candidates(candidates, dots, template_gram, template_sq_norms, dictionary_sizes, n_positive, ridge_c,
                     ridge_w, constrained, n_iterations, sq_norms, neighbours, sq_distances,
                     *_encode_work(n_candidates, k_max), coefficients,
                     *_combine_work(n_candidates, n_dictionaries, k_max), *outputs)
    weights, codes, error_positive, error_negative = outputs
    return dict(sq_norms=sq_norms, neighbours=neighbours, sq_distances=sq_distances, coefficients=coefficients,
                weights=weights, codes=codes, error_positive=error_positive, error_negative=error_negative)


def scatter_codes(codes: np.ndarray, neighbour_indices: np.ndarray, n_templates: int) -> np.ndarray:
    """Spread support-coordinate codes over all templates (eq. allocation).

    Parameters
    ----------
    codes : ndarray, shape (n_candidates, k_max), float64
        Codes in support coordinates (:func:`combine_dictionaries`).
    neighbour_indices : ndarray, shape (n_candidates, k_max), int64
        Template index of each support entry.
    n_templates : int
        Total number of templates.

    Returns
    -------
    full_codes : ndarray, shape (n_candidates, n_templates), float64
        The uniform coefficient vectors ``d_i``; templates outside the support
        are 0, and repeated support indices are summed.
    """
    check_array("codes", codes, np.float64, 2)
    check_array("neighbour_indices", neighbour_indices, np.int64, 2)
    if neighbour_indices.shape != codes.shape:
        raise ParameterError(
            f"neighbour_indices shape {neighbour_indices.shape} differs from codes shape {codes.shape}"
        )
    n_templates = check_int("n_templates", n_templates, 1)
    check_indices("neighbour_indices", neighbour_indices, n_templates)
    full_codes = np.zeros((codes.shape[0], n_templates), dtype=np.float64)
    rows = np.arange(codes.shape[0])[:, None]
    np.add.at(full_codes, (rows, neighbour_indices), codes)
    return full_codes
