"""Gradient-orientation cells of warped patches: a HOG-like view of each candidate.

Each ``P x P`` patch (as :func:`nrmlc.kernels.warp.warp_patches` gives it) becomes a grid of
``cell x cell`` pixel cells, each a histogram of unsigned gradient orientation in ``bins`` bins
over [0, pi), every pixel voting its gradient magnitude, split linearly between the two nearest
bin centres. The histograms are square-rooted (so one strong edge does not drown the rest) and
the whole vector is scaled to unit l2 norm, as a patch is. Gradients are central differences,
one-sided on the patch's border.

The orientation comes from :func:`unsigned_orientation`, a polynomial arctangent within
:data:`ORIENTATION_ERROR` radians of ``atan2``: its passes over a patch have no branch, so they
run on the CPU's vector units, where ``atan2`` costs most of the kernel.

A flat patch (no gradient anywhere) becomes the flat unit vector, so no NaN ever leaves the kernel.
"""
from __future__ import annotations

import math

import numpy as np
import numba
from numba import njit, prange

from nrmlc.config import NUMBA_FLAGS, PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.kernels.checks import check_array, check_int

#: Side of a cell in template pixels, and orientation bins per cell (Dalal and Triggs' 9).
CELL_SIZE = 4
N_BINS = 9

#: atan(t) / t on [0, 1] as a polynomial in t**2 (lowest power first): a least-squares fit on
#: Chebyshev nodes refined towards minimax (Lawson's iteration), largest error 5.8e-9 rad.
_ATAN_COEFFICIENTS = (0.9999998863836137, -0.33332597030296346, 0.19985906791432112, -0.1416122933144456,
                      0.10498946485996967, -0.07234858067084741, 0.039781230446868536, -0.014401361536994825,
                      0.002456725374156043)
#: The largest distance (radians, modulo pi) between :func:`unsigned_orientation` and ``atan2``.
ORIENTATION_ERROR = 1e-8
_C0, _C1, _C2, _C3, _C4, _C5, _C6, _C7, _C8 = _ATAN_COEFFICIENTS
_HALF_PI = 0.5 * math.pi


@njit(**NUMBA_FLAGS)
def unsigned_orientation(gx, gy):
    """The orientation of the gradient (gx, gy) modulo pi, in [0, pi]; 0 for (0, 0).

    ``atan2`` folded onto [0, pi] from an arctangent on [0, 1] by the octant's symmetries, with
    selects in place of branches.
    """
    ax = abs(gx)
    ay = abs(gy)
    t = min(ax, ay) / max(max(ax, ay), 1e-300)
    s = t * t
    p = _C8
    p = p * s + _C7
    p = p * s + _C6
    p = p * s + _C5
    p = p * s + _C4
    p = p * s + _C3
    p = p * s + _C2
    p = p * s + _C1
    p = p * s + _C0
    angle = p * t
    angle = _HALF_PI - angle if ay > ax else angle
    # (gx, gy) and (-gx, -gy) share an orientation: the one with gy >= 0 lies in [0, pi].
    folded_gx = -gx if gy < 0.0 else gx
    return math.pi - angle if folded_gx < 0.0 else angle


@njit(**PARALLEL_FLAGS)
def _gradient_cells(patches, patch_size, cell, bins, features, scratch):
    cells_per_side = patch_size // cell
    length = cells_per_side * cells_per_side * bins
    flat = 1.0 / math.sqrt(length)
    per_radian = bins / math.pi
    last = patch_size - 1
    for particle in prange(patches.shape[0]):
        pixels = patches[particle]
        out = features[particle]
        # Each thread's own rows, rewritten in full for every particle before they are read.
        gx = scratch[numba.get_thread_id(), 0]  # the x gradient, then the magnitude
        gy = scratch[numba.get_thread_id(), 1]  # the y gradient, then the position among the bins
        for row in range(patch_size):
            start = row * patch_size
            gx[start] = pixels[start + 1] - pixels[start]
            for col in range(1, last):
                gx[start + col] = 0.5 * (pixels[start + col + 1] - pixels[start + col - 1])
            gx[start + last] = pixels[start + last] - pixels[start + last - 1]
        for col in range(patch_size):
            gy[col] = pixels[patch_size + col] - pixels[col]
        for row in range(1, last):
            start = row * patch_size
            for col in range(patch_size):
                gy[start + col] = 0.5 * (pixels[start + patch_size + col] - pixels[start - patch_size + col])
        start = last * patch_size
        for col in range(patch_size):
            gy[start + col] = pixels[start + col] - pixels[start - patch_size + col]
        for i in range(patch_size * patch_size):
            x = gx[i]
            y = gy[i]
            gx[i] = math.sqrt(x * x + y * y)
            gy[i] = unsigned_orientation(x, y) * per_radian - 0.5  # bin b's centre is at b + 0.5
        for k in range(length):
            out[k] = 0.0
        for row in range(patch_size):
            cell_row = row // cell
            start = row * patch_size
            for col in range(patch_size):
                magnitude = gx[start + col]
                if magnitude == 0.0:
                    continue
                position = gy[start + col]
                low = int(math.floor(position))  # in [-1, bins - 1]: the bins wrap around
                share = position - low
                base = (cell_row * cells_per_side + col // cell) * bins
                out[base + (low if low >= 0 else bins - 1)] += magnitude * (1.0 - share)
                out[base + (low + 1 if low + 1 < bins else 0)] += magnitude * share
        sum_sq = 0.0
        for k in range(length):
            value = math.sqrt(out[k])
            out[k] = value
            sum_sq += value * value
        if sum_sq > 1e-24:
            inv = 1.0 / math.sqrt(sum_sq)
            for k in range(length):
                out[k] = out[k] * inv
        else:
            for k in range(length):
                out[k] = flat


def gradient_cells(patches: np.ndarray, patch_size: int, cell: int = CELL_SIZE, bins: int = N_BINS) -> np.ndarray:
    """The gradient-orientation cells of each patch.

    Parameters
    ----------
    patches : (n, patch_size**2) float32, C-contiguous
        Row-major patches (any scale).
    patch_size : int
        Side P of the patches; a multiple of ``cell``.
    cell : int
        Side of a cell in pixels.
    bins : int
        Orientation bins over [0, pi).

    Returns
    -------
    features : (n, (P // cell)**2 * bins) float32
        Unit-l2-norm rows, non-negative.
    """
    check_array("patches", patches, np.float32, 2)
    patch_size = check_int("patch_size", patch_size, 2)
    cell = check_int("cell", cell, 1, patch_size)
    bins = check_int("bins", bins, 2)
    if patches.shape[1] != patch_size * patch_size:
        raise ParameterError(f"patches must have patch_size**2 = {patch_size**2} columns, got {patches.shape[1]}")
    if patch_size % cell:
        raise ParameterError(f"patch_size ({patch_size}) must be a multiple of cell ({cell})")
    features = np.empty((patches.shape[0], (patch_size // cell) ** 2 * bins), dtype=np.float32)
    # One small workspace per thread rather than per particle: a fresh (n, P*P) buffer costs more
    # in page faults than the kernel does.
    scratch = np.empty((numba.config.NUMBA_NUM_THREADS, 2, patch_size * patch_size), dtype=np.float64)
    _gradient_cells(patches, patch_size, cell, bins, features, scratch)
    return features
