"""Slow, obvious numpy references (the test oracles) for the compiled kernels.

Used by the tests (``tests/test_warp.py``, ``test_distance.py``,
``test_coding.py``) and by ``make bench``, which times each kernel against them.

Everything here works on the explicit ``dim``-length vectors in float64 and
follows the paper literally: local dictionaries are built as matrices,
systems are solved with ``np.linalg.solve`` / ``lstsq``, Algorithm 1 is a
plain loop. Speed is irrelevant; clarity is the point.

Sections
--------
1. Test data
2. Warp                                   (nrmlc.kernels.warp)
3. Distances and nearest templates        (nrmlc.kernels.distance)
4. Sum-to-one coding problems             (nrmlc.kernels.coding)
5. Multiple dictionaries, Algorithm 1     (nrmlc.kernels.coding)
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

# ===========================================================================
# 1. Test data
# ===========================================================================


def unit_rows(array: np.ndarray) -> np.ndarray:
    """Rows scaled to unit Euclidean norm."""
    return array / np.linalg.norm(array, axis=1, keepdims=True)


def make_problem(seed: int, n_candidates: int = 40, n_templates: int = 60, dim: int = 64,
                 n_positive: int = 20):
    """Small tracking-like problem: float32 unit-norm non-negative rows.

    Positive templates are noisy copies of one "target" patch, negatives are
    unrelated patches; half of the candidates are slightly perturbed copies of
    templates (so their nearest neighbours are close), the rest are noisy
    target patches.

    Returns
    -------
    candidates : ndarray, shape (n_candidates, dim), float32
    templates : ndarray, shape (n_templates, dim), float32
    """
    rng = np.random.default_rng(seed)
    target = rng.random(dim)
    positives = target + 0.15 * rng.random((n_positive, dim))
    negatives = rng.random((n_templates - n_positive, dim))
    templates = unit_rows(np.vstack([positives, negatives])).astype(np.float32)
    n_copies = n_candidates // 2
    sources = rng.integers(0, n_templates, n_copies)
    copies = templates[sources] + 0.02 * rng.random((n_copies, dim))
    targets = target + 0.15 * rng.random((n_candidates - n_copies, dim))
    candidates = unit_rows(np.vstack([copies, targets])).astype(np.float32)
    return candidates, templates


# ===========================================================================
# 2. Warp
# ===========================================================================


def warp_patches_reference(frame, affines, patch_size=32, grid=None):
    """Bilinear sampling with border replication, then unit-norm rows (float64); ``grid``
    (n_rows, n_cols) samples at the centres of equal cells tiling the P x P template square."""
    frame = np.asarray(frame, dtype=np.float64)
    height, width = frame.shape
    n_rows, n_cols = (patch_size, patch_size) if grid is None else grid
    v = (np.arange(n_rows) + 0.5) * patch_size / n_rows - patch_size / 2.0
    u = (np.arange(n_cols) + 0.5) * patch_size / n_cols - patch_size / 2.0
    rows, cols = np.meshgrid(v, u, indexing="ij")
    grid = np.stack([cols.ravel(), rows.ravel()])  # (2, n_rows * n_cols)
    out = np.empty((len(affines), n_rows * n_cols))
    for k, matrix in enumerate(affines):
        x, y = matrix[:, :2] @ grid + matrix[:, 2:]
        x = np.clip(x, 0, width - 1)
        y = np.clip(y, 0, height - 1)
        x0 = np.minimum(np.floor(x).astype(int), max(width - 2, 0))
        y0 = np.minimum(np.floor(y).astype(int), max(height - 2, 0))
        x1 = np.minimum(x0 + 1, width - 1)
        y1 = np.minimum(y0 + 1, height - 1)
        fx, fy = x - x0, y - y0
        values = (frame[y0, x0] * (1 - fx) * (1 - fy) + frame[y0, x1] * fx * (1 - fy)
                  + frame[y1, x0] * (1 - fx) * fy + frame[y1, x1] * fx * fy)
        norm = np.linalg.norm(values)
        out[k] = values / norm if norm > 1e-12 else 1.0 / np.sqrt(n_rows * n_cols)
    return out


def reference_dots(candidates: np.ndarray, templates: np.ndarray) -> np.ndarray:
    """``Y T'`` in float64, element by element definition via einsum."""
    return np.einsum("id,td->it", candidates.astype(np.float64), templates.astype(np.float64))


def reference_sq_distances(candidates: np.ndarray, templates: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances from the explicit differences, float64."""
    y = candidates.astype(np.float64)[:, None, :]
    t = templates.astype(np.float64)[None, :, :]
    return ((y - t) ** 2).sum(axis=2)


def reference_nearest(sq_distances: np.ndarray, k: int):
    """Brute-force k nearest: stable argsort (ties -> lower index), first k."""
    order = np.argsort(sq_distances, axis=1, kind="stable")[:, :k]
    return order, np.take_along_axis(sq_distances, order, axis=1)


# ===========================================================================
# 4. Sum-to-one coding problems
# ===========================================================================


def local_difference_matrix(candidate: np.ndarray, templates: np.ndarray,
                            support: np.ndarray) -> np.ndarray:
    """``A = B - y 1'`` with ``B`` = the templates in ``support`` as columns, float64."""
    basis = templates[support].astype(np.float64).T
    return basis - candidate.astype(np.float64)[:, None]


def reference_sum_to_one(difference: np.ndarray, ridge: float) -> np.ndarray:
    """Minimise ``||A c||^2 + ridge ||c||^2`` subject to ``1'c = 1``.

    ``ridge > 0``: the Lagrangian (KKT) system ``[[2F, 1], [1', 0]]`` with
    ``F = A'A + ridge I``, solved directly. ``ridge == 0``: the minimum-norm
    minimiser, via ``c = 1/k + N z`` with ``N`` an orthonormal basis of
    ``1``'s complement and ``z`` the minimum-norm least-squares solution of
    ``A N z = -A 1/k`` (``||c||^2 = 1/k + ||z||^2``).
    """
    k = difference.shape[1]
    if ridge > 0:
        system = np.zeros((k + 1, k + 1))
        system[:k, :k] = 2.0 * (difference.T @ difference + ridge * np.eye(k))
        system[:k, k] = 1.0
        system[k, :k] = 1.0
        rhs = np.zeros(k + 1)
        rhs[k] = 1.0
        return np.linalg.solve(system, rhs)[:k]
    centre = np.full(k, 1.0 / k)
    if k == 1:
        return centre
    # Orthonormal basis of {v : 1'v = 0}: the last k-1 columns of a QR of [1, I].
    q, _ = np.linalg.qr(np.column_stack([np.ones(k), np.eye(k)[:, : k - 1]]))
    null_basis = q[:, 1:]
    z = np.linalg.lstsq(difference @ null_basis, -difference @ centre, rcond=1e-10)[0]
    return centre + null_basis @ z


def kkt_report(matrix: np.ndarray, c: np.ndarray) -> dict:
    """KKT residuals of ``min c'Fc s.t. c >= 0, 1'c = 1`` at ``c``.

    Returns min(c), |1'c - 1|, the stationarity spread on the support
    (``max |g_a - mu|`` over ``c_a > 0``), the worst dual infeasibility
    (``min (g_b - mu)`` over ``c_b == 0``, should be >= -tol) and the
    complementary slackness ``max |c_a (g_a - mu)|``, with ``g = 2Fc`` and
    ``mu = c'g``.
    """
    gradient = 2.0 * matrix @ c
    multiplier = c @ gradient
    slack = gradient - multiplier
    on_support = c > 0
    return {
        "min_c": float(c.min()),
        "sum_error": float(abs(c.sum() - 1.0)),
        "stationarity": float(np.abs(slack[on_support]).max()) if on_support.any() else 0.0,
        "dual_infeasibility": float(slack[~on_support].min()) if (~on_support).any() else 0.0,
        "complementarity": float(np.abs(c * slack).max()),
    }


def reference_simplex_qp(matrix: np.ndarray) -> np.ndarray:
    """Minimise ``c' F c`` subject to ``c >= 0``, ``1'c = 1`` (F symmetric PSD).

    scipy SLSQP from the barycentre, then polished: the equality-constrained
    problem restricted to SLSQP's support is solved exactly (KKT system,
    least squares) and kept if it is feasible and no worse.
    """
    k = matrix.shape[0]
    result = minimize(
        lambda c: c @ matrix @ c,
        np.full(k, 1.0 / k),
        jac=lambda c: 2.0 * matrix @ c,
        bounds=[(0.0, None)] * k,
        constraints=[{"type": "eq", "fun": lambda c: c.sum() - 1.0,
                      "jac": lambda c: np.ones(k)}],
        method="SLSQP",
        options={"ftol": 1e-16, "maxiter": 1000},
    )
    c = np.clip(result.x, 0.0, None)
    c /= c.sum()
    support = np.flatnonzero(c > 1e-6 * c.max())
    n = support.size
    system = np.zeros((n + 1, n + 1))
    system[:n, :n] = 2.0 * matrix[np.ix_(support, support)]
    system[:n, n] = 1.0
    system[n, :n] = 1.0
    rhs = np.zeros(n + 1)
    rhs[n] = 1.0
    polished = np.zeros(k)
    polished[support] = np.linalg.lstsq(system, rhs, rcond=None)[0][:n]
    if polished.min() >= 0.0 and abs(polished.sum() - 1.0) < 1e-12:
        # Equal up to rounding of the objective (a wrong support costs far more).
        objective = c @ matrix @ c
        if polished @ matrix @ polished <= objective + 1e-12 * (1.0 + abs(objective)):
            return polished
    return c


def reference_solve(difference: np.ndarray, ridge: float, constrained: bool) -> np.ndarray:
    """Coefficients of ``min ||A c||^2 + ridge ||c||^2`` s.t. ``1'c = 1`` [and ``c >= 0``]."""
    if constrained:
        k = difference.shape[1]
        return reference_simplex_qp(difference.T @ difference + ridge * np.eye(k))
    return reference_sum_to_one(difference, ridge)


def reference_encode(candidates, templates, neighbour_indices, dictionary_sizes, ridge,
                     constrained):
    """Coefficients per candidate and dictionary, shape (n_candidates, n_dictionaries, k_max)."""
    n_candidates, k_max = neighbour_indices.shape
    out = np.zeros((n_candidates, len(dictionary_sizes), k_max))
    for i in range(n_candidates):
        for j, k in enumerate(dictionary_sizes):
            difference = local_difference_matrix(candidates[i], templates, neighbour_indices[i, :k])
            out[i, j, :k] = reference_solve(difference, ridge, constrained)
    return out


# ===========================================================================
# 5. Multiple dictionaries, Algorithm 1
# ===========================================================================


def reference_combine(candidates, templates, neighbour_indices, coefficients, dictionary_sizes,
                      n_positive, ridge, constrained, n_iterations):
    """Algorithm 1 and eq. conf, literally, per candidate.

    Returns
    -------
    weights : (n_candidates, n_dictionaries)
    codes : (n_candidates, n_templates) -- the uniform coefficient vectors d_i
    error_positive, error_negative : (n_candidates,)
    """
    n_candidates = candidates.shape[0]
    n_templates = templates.shape[0]
    m = len(dictionary_sizes)
    basis = templates.astype(np.float64).T  # (dim, n_templates)
    weights = np.zeros((n_candidates, m))
    codes = np.zeros((n_candidates, n_templates))
    error_positive = np.zeros(n_candidates)
    error_negative = np.zeros(n_candidates)
    for i in range(n_candidates):
        y = candidates[i].astype(np.float64)
        # Step 2: uniform coefficient vectors d^j (eq. allocation).
        uniform_vectors = np.zeros((m, n_templates))
        for j, k in enumerate(dictionary_sizes):
            for a in range(k):
                uniform_vectors[j, neighbour_indices[i, a]] += coefficients[i, j, a]
        reconstructions = basis @ uniform_vectors.T  # D = [T d^1, ..., T d^m]
        # Step 1 and 3.
        w = np.full(m, 1.0 / m)
        d = w @ uniform_vectors
        for _ in range(n_iterations):
            d = w @ uniform_vectors                                           # 3.1
            w = reference_solve(reconstructions - y[:, None], ridge, constrained)  # 3.2
        weights[i] = w
        codes[i] = d
        # eq. conf
        error_positive[i] = np.sum((y - basis[:, :n_positive] @ d[:n_positive]) ** 2)
        error_negative[i] = np.sum((y - basis[:, n_positive:] @ d[n_positive:]) ** 2)
    return weights, codes, error_positive, error_negative
