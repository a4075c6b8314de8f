"""Bilinear affine warping of many particles from one frame.

Each particle's warp ``[A | c]`` (see :mod:`nrmlc.geometry`) is sampled on the centred
``P x P`` template grid, bilinearly, and the patch becomes a unit-l2-norm vector of
length ``P*P`` (row-major). That normalisation is why the paper's Fig. 2 finds a
mean element of about 0.029: a unit-norm vector of n = 1024 non-negative entries has
mean at most ``sqrt(n)/n = 1/32 = 0.03125``, reached by a flat patch.

Samples outside the frame. Coordinates are clamped to the frame,
``x in [0, W-1], y in [0, H-1]``, before interpolation: the border pixels are
replicated outwards (OpenCV's ``BORDER_REPLICATE``). Zero filling (IVT's choice)
would paint a dark band into the patch of any particle touching the border, and
its appearance would then depend on how far outside it is, not on the scene.

Patches of zero norm (black or empty frames) cannot be normalised; they become
the flat unit vector ``1/P`` (the limit of a constant patch), so no NaN ever
leaves the kernel.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from nrmlc.config import PARALLEL_FLAGS, PATCH_SIZE
from nrmlc.errors import ParameterError
from nrmlc.kernels.checks import check_array, check_finite, check_int


@njit(**PARALLEL_FLAGS)
def _warp_patches(frame, affines, patch_size, n_rows, n_cols, allow_fast_path, column_index, column_fraction,
                  row_values, patches):
    """Fill ``patches``; the other arrays are per-particle work buffers.

    The ``n_rows x n_cols`` samples are the centres of equal cells tiling the
    ``P x P`` template square (for ``n_rows = n_cols = P`` exactly the integer
    template grid). ``column_index`` (n, n_cols) uint64, ``column_fraction``
    (n, n_cols) float64 and ``row_values`` (n, n_cols) float64 are scratch
    space, one row per particle.
    ``allow_fast_path=False`` forces the general path (for tests).

    Fast path (``A`` diagonal, i.e. rotation = skew = 0, the tracker's usual
    case): ``x`` depends only on the column and ``y`` only on the row, so the
    left neighbour and weight of each column are computed once per particle
    and the inner loop is four loads and three lerps. Unsigned indices skip
    numba's negative-index wrap-around, and the per-row sum of squares runs in
    its own (vectorised) loop. The arithmetic per sample is the general path's
    (same operands, same order, float32 pixel differences); only the order of
    the sum of squares differs, so the two paths agree to within one float32
    ulp for a diagonal ``A`` (tests check both paths against the reference).
    """
    height, width = frame.shape
    pixels = frame.ravel()
    half = patch_size / 2.0
    step_x = patch_size / n_cols
    step_y = patch_size / n_rows
    n_values = n_rows * n_cols
    flat = 1.0 / math.sqrt(n_values)
    last_x = max(width - 2, 0)
    last_y = max(height - 2, 0)
    one = np.uint64(1)
    for particle in prange(affines.shape[0]):
        a00 = affines[particle, 0, 0]
        a01 = affines[particle, 0, 1]
        a10 = affines[particle, 1, 0]
        a11 = affines[particle, 1, 1]
        centre_x = affines[particle, 0, 2]
        centre_y = affines[particle, 1, 2]
        out = patches[particle]
        sum_sq = 0.0
        if allow_fast_path and a01 == 0.0 and a10 == 0.0 and width >= 2 and height >= 2:
            x0s = column_index[particle]
            fxs = column_fraction[particle]
            values = row_values[particle]
            for col in range(n_cols):
                x = min(max(a00 * ((col + 0.5) * step_x - half) + centre_x, 0.0), width - 1.0)
                x0 = min(int(x), last_x)
                x0s[col] = np.uint64(x0)
                fxs[col] = x - x0
            for row in range(n_rows):
                y = min(max(a11 * ((row + 0.5) * step_y - half) + centre_y, 0.0), height - 1.0)
                y0 = min(int(y), last_y)
                fy = y - y0
                top_row = np.uint64(y0 * width)
                bottom_row = top_row + np.uint64(width)
                for col in range(n_cols):
                    x0 = x0s[col]
                    fx = fxs[col]
                    top_left = pixels[top_row + x0]
                    bottom_left = pixels[bottom_row + x0]
                    top = top_left + fx * (pixels[top_row + x0 + one] - top_left)
                    bottom = bottom_left + fx * (pixels[bottom_row + x0 + one] - bottom_left)
                    values[col] = top + fy * (bottom - top)
                row_sq = 0.0
                base = row * n_cols
                for col in range(n_cols):
                    value = values[col]
                    row_sq += value * value
                    out[base + col] = value
                sum_sq += row_sq
        else:
            for row in range(n_rows):
                v = (row + 0.5) * step_y - half
                for col in range(n_cols):
                    u = (col + 0.5) * step_x - half
                    x = min(max(a00 * u + a01 * v + centre_x, 0.0), width - 1.0)
                    y = min(max(a10 * u + a11 * v + centre_y, 0.0), height - 1.0)
                    # The top-left neighbour stays inside the frame so that x1 = x0 + 1
                    # is valid; on the last column the weight of x1 is then exactly 0.
                    x0 = min(int(x), last_x)
                    y0 = min(int(y), last_y)
                    x1 = min(x0 + 1, width - 1)
                    y1 = min(y0 + 1, height - 1)
                    fx = x - x0
                    fy = y - y0
                    top = frame[y0, x0] + fx * (frame[y0, x1] - frame[y0, x0])
                    bottom = frame[y1, x0] + fx * (frame[y1, x1] - frame[y1, x0])
                    value = top + fy * (bottom - top)
                    out[row * n_cols + col] = value
                    sum_sq += value * value
        norm = math.sqrt(sum_sq)
        if norm > 1e-12:
            inv = 1.0 / norm
            for k in range(n_values):
                out[k] = out[k] * inv
        else:
            for k in range(n_values):
                out[k] = flat


def warp_patches(frame: np.ndarray, affines: np.ndarray, patch_size: int = PATCH_SIZE,
                 grid: tuple[int, int] | None = None) -> np.ndarray:
    """Warp one frame into unit-norm patch vectors, one per particle.

    Parameters
    ----------
    frame : (height, width) float32, C-contiguous
        Grayscale frame (any range; the output is normalised).
    affines : (n_particles, 2, 3) float64, C-contiguous
        Warps ``[A | c]`` from :func:`nrmlc.geometry.state_to_affine`.
    patch_size : int
        Side P of the template square the warps map from.
    grid : (n_rows, n_cols), optional
        How many samples across the template square's height and width; default ``(P, P)``.

    Returns
    -------
    patches : (n_particles, n_rows * n_cols) float32
        Row-major patches, each of unit l2 norm.
    """
    check_array("frame", frame, np.float32, 2)
    if frame.shape[0] < 1 or frame.shape[1] < 1:
        raise ParameterError(f"frame must be non-empty, got shape {frame.shape}")
    check_array("affines", affines, np.float64, 3)
    if affines.shape[1:] != (2, 3):
        raise ParameterError(f"affines must have shape (n_particles, 2, 3), got {affines.shape}")
    check_finite("affines", affines)
    check_finite("frame", frame)
    patch_size = check_int("patch_size", patch_size, 2)
    n_rows, n_cols = (patch_size, patch_size) if grid is None else grid
    n_rows = check_int("grid[0]", n_rows, 2)
    n_cols = check_int("grid[1]", n_cols, 2)
    n_particles = affines.shape[0]
    patches = np.empty((n_particles, n_rows * n_cols), dtype=np.float32)
    # Per-particle work buffers, allocated once outside the parallel loop.
    column_index = np.empty((n_particles, n_cols), dtype=np.uint64)
    column_fraction = np.empty((n_particles, n_cols), dtype=np.float64)
    row_values = np.empty((n_particles, n_cols), dtype=np.float64)
    _warp_patches(frame, affines, float(patch_size), n_rows, n_cols, True, column_index, column_fraction, row_values,
                  patches)
    return patches
