"""Gradient-orientation cells of warped patches: a HOG-like view of each candidate.

Each ``P x P`` patch (as :func:`nrmlc.kernels.warp.warp_patches` gives it) becomes a grid of
``cell x cell`` pixel cells, each a histogram of unsigned gradient orientation in ``bins`` bins
over [0, pi), every pixel voting its gradient magnitude, split linearly between the two nearest
bin centres. The histograms are square-rooted (so one strong edge does not drown the rest) and
the whole vector is scaled to unit l2 norm, as a patch is. Gradients are central differences,
one-sided on the patch's border.

A flat patch (no gradient anywhere) becomes the flat unit vector, so no NaN ever leaves the kernel.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from nrmlc.config import PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.kernels.checks import check_array, check_int

#: Side of a cell in template pixels, and orientation bins per cell (Dalal and Triggs' 9).
CELL_SIZE = 4
N_BINS = 9


@njit(**PARALLEL_FLAGS)
def _gradient_cells(patches, patch_size, cell, bins, features):
    cells_per_side = patch_size // cell
    length = cells_per_side * cells_per_side * bins
    flat = 1.0 / math.sqrt(length)
    bin_width = math.pi / bins
    last = patch_size - 1
    for particle in prange(patches.shape[0]):
        pixels = patches[particle]
        out = features[particle]
        for k in range(length):
            out[k] = 0.0
        for row in range(cells_per_side * cell):
            up = max(row - 1, 0)
            down = min(row + 1, last)
            row_span = down - up
            cell_row = row // cell
            for col in range(cells_per_side * cell):
                left = max(col - 1, 0)
                right = min(col + 1, last)
                gx = (pixels[row * patch_size + right] - pixels[row * patch_size + left]) / (right - left)
                gy = (pixels[down * patch_size + col] - pixels[up * patch_size + col]) / row_span
                magnitude = math.sqrt(gx * gx + gy * gy)
                if magnitude == 0.0:
                    continue
                angle = math.atan2(gy, gx)
                if angle < 0.0:
                    angle += math.pi
                position = angle / bin_width - 0.5  # bin b's centre is at (b + 0.5) * bin_width
                low = int(math.floor(position))
                share = position - low
                base = (cell_row * cells_per_side + col // cell) * bins
                out[base + (low % bins)] += magnitude * (1.0 - share)
                out[base + ((low + 1) % bins)] += magnitude * share
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
    _gradient_cells(patches, patch_size, cell, bins, features)
    return features
