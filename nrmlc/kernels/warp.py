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


@njit(**PARALLEL_FLAGS)
def _warp_patches(frame, affines, patch_size, patches):
    height, width = frame.shape
    half = (patch_size - 1) / 2.0
    flat = 1.0 / patch_size
    for particle in prange(affines.shape[0]):
        a00 = affines[particle, 0, 0]
        a01 = affines[particle, 0, 1]
        a10 = affines[particle, 1, 0]
        a11 = affines[particle, 1, 1]
        centre_x = affines[particle, 0, 2]
        centre_y = affines[particle, 1, 2]
        sum_sq = 0.0
        for row in range(patch_size):
            v = row - half
            for col in range(patch_size):
                u = col - half
                x = min(max(a00 * u + a01 * v + centre_x, 0.0), width - 1.0)
                y = min(max(a10 * u + a11 * v + centre_y, 0.0), height - 1.0)
                # The top-left neighbour stays inside the frame so that x1 = x0 + 1
                # is valid; on the last column the weight of x1 is then exactly 0.
                x0 = min(int(x), max(width - 2, 0))
                y0 = min(int(y), max(height - 2, 0))
                x1 = min(x0 + 1, width - 1)
                y1 = min(y0 + 1, height - 1)
                fx = x - x0
                fy = y - y0
                top = frame[y0, x0] + fx * (frame[y0, x1] - frame[y0, x0])
                bottom = frame[y1, x0] + fx * (frame[y1, x1] - frame[y1, x0])
                value = top + fy * (bottom - top)
                patches[particle, row * patch_size + col] = value
                sum_sq += value * value
        norm = math.sqrt(sum_sq)
        if norm > 1e-12:
            inv = 1.0 / norm
            for k in range(patch_size * patch_size):
                patches[particle, k] = patches[particle, k] * inv
        else:
            for k in range(patch_size * patch_size):
                patches[particle, k] = flat


def warp_patches(frame: np.ndarray, affines: np.ndarray, patch_size: int = PATCH_SIZE) -> np.ndarray:
    """Warp one frame into unit-norm patch vectors, one per particle.

    Parameters
    ----------
    frame : (height, width) float32, C-contiguous
        Grayscale frame (any range; the output is normalised).
    affines : (n_particles, 2, 3) float64, C-contiguous
        Warps ``[A | c]`` from :func:`nrmlc.geometry.state_to_affine`.
    patch_size : int
        Side P of the template grid.

    Returns
    -------
    patches : (n_particles, patch_size**2) float32
        Row-major patches, each of unit l2 norm.
    """
    if not isinstance(frame, np.ndarray) or frame.dtype != np.float32 or frame.ndim != 2:
        raise ParameterError("frame must be a 2-D float32 array")
    if frame.shape[0] < 1 or frame.shape[1] < 1:
        raise ParameterError(f"frame must be non-empty, got shape {frame.shape}")
    if not frame.flags.c_contiguous:
        raise ParameterError("frame must be C-contiguous (use np.ascontiguousarray)")
    if not isinstance(affines, np.ndarray) or affines.dtype != np.float64 or affines.ndim != 3 or affines.shape[1:] != (2, 3):
        raise ParameterError("affines must be a float64 array of shape (n_particles, 2, 3)")
    if not affines.flags.c_contiguous:
        raise ParameterError("affines must be C-contiguous")
    if not np.all(np.isfinite(affines)):
        raise ParameterError("affines contain NaN or infinite values")
    if not np.all(np.isfinite(frame)):
        raise ParameterError("frame contains NaN or infinite values")
    if int(patch_size) < 2:
        raise ParameterError(f"patch_size must be >= 2, got {patch_size}")
    patches = np.empty((affines.shape[0], int(patch_size) ** 2), dtype=np.float32)
    _warp_patches(frame, affines, int(patch_size), patches)
    return patches
