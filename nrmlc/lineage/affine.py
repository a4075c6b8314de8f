"""The lineage's affine states and its patch warp, as IVT's MATLAB code defines them.

IVT (Ross et al. 2008), and after it ASLA and SCM, keep a target's state in two forms
(``trackers/IVT/affparam2mat.m`` and ``affparam2geom.m`` of the OTB benchmark's code,
github.com/jwlim/tracker_benchmark):

- *geometric*: ``(x, y, scale, theta, aspect, skew)``: the centre in 1-based pixels, the
  template's scale (box width over the template's width), rotation, height/width ratio and skew;
  the particle filter adds Gaussian noise in this form;
- *matrix*: ``(tx, ty, a11, a12, a21, a22)``: the template point ``(u, v)`` goes to the image point
  ``(tx + a11 u + a12 v, ty + a21 u + a22 v)`` (1-based, x to the right, y down).

:func:`warp_patches` samples every particle's patch as ``warpimg.m`` with the ``interp2`` mex
does: the template grid is ``u = 1 - w/2, ..., w/2`` (and ``v`` likewise), each sample is
bilinear in the gray frame, and neighbours outside the frame count as 0 (a patch running off the
frame darkens). The patch is raw intensity, not normalised: IVT's subspace models brightness.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from nrmlc.config import PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.lineage.checks import check_patch_arguments
from nrmlc.workbench.otb_results import ivt_affine_boxes, matlab_round

#: :data:`nrmlc.config.PARALLEL_FLAGS` without fastmath, for a kernel that must round as a MATLAB
#: mex does: no fused multiply-add may move a coordinate across a half before it is rounded.
EXACT_PARALLEL_FLAGS = dict(PARALLEL_FLAGS, fastmath=False)


def geom_to_matrix(geom) -> np.ndarray:
    """Matrix states of geometric ones (``affparam2mat.m``).

    Parameters
    ----------
    geom : (n, 6) or (6,) array_like
        ``x, y, scale, theta, aspect, skew``.

    Returns
    -------
    (n, 6) or (6,) float64
        ``tx, ty, a11, a12, a21, a22``.
    """
    p = np.asarray(geom, dtype=np.float64)
    single = p.ndim == 1
    p = p.reshape(-1, 6)
    s, th, r, phi = p[:, 2], p[:, 3], p[:, 4], p[:, 5]
    cth, sth, cph, sph = np.cos(th), np.sin(th), np.cos(phi), np.sin(phi)
    ccc, ccs, css = cth * cph * cph, cth * cph * sph, cth * sph * sph
    scc, scs, sss = sth * cph * cph, sth * cph * sph, sth * sph * sph
    q = np.empty_like(p)
    q[:, 0], q[:, 1] = p[:, 0], p[:, 1]
    q[:, 2] = s * (ccc + scs + r * (css - scs))
    q[:, 3] = s * (r * (ccs - scc) - ccs - sss)
    q[:, 4] = s * (scc - ccs + r * (ccs + sss))
    q[:, 5] = s * (r * (ccc + scs) - scs + css)
    return q[0] if single else q


def matrix_to_geom(matrix) -> np.ndarray:
    """The geometric state of one matrix state (``affparam2geom.m``: an SVD of the 2x2 part).

    Parameters
    ----------
    matrix : (6,) array_like
        ``tx, ty, a11, a12, a21, a22``.

    Returns
    -------
    (6,) float64
        ``x, y, scale, theta, aspect, skew``; ``geom_to_matrix`` of it gives ``matrix`` back.
    """
    q = np.asarray(matrix, dtype=np.float64).ravel()
    u, s, vt = np.linalg.svd(np.array([[q[2], q[3]], [q[4], q[5]]]))
    v = vt.T
    s = np.diag(s)
    if np.linalg.det(u) < 0:
        u, v, s = u[:, ::-1], v[:, ::-1], s[::-1, ::-1]
    theta = math.atan2(u[1, 0] * v[0, 0] + u[1, 1] * v[0, 1], u[0, 0] * v[0, 0] + u[0, 1] * v[0, 1])
    phi = math.atan2(v[0, 1], v[0, 0])
    if phi <= -math.pi / 2 or phi >= math.pi / 2:
        angle = -math.pi / 2 if phi <= -math.pi / 2 else math.pi / 2
        rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
        v = v @ rotation
        s = rotation.T @ s @ rotation
    return np.array([q[0], q[1], s[0, 0], theta, s[1, 1] / s[0, 0], math.atan2(v[0, 1], v[0, 0])])


def box_to_geom(box, template_width: int, round_centre: bool) -> np.ndarray:
    """The geometric state of a 1-based ``x, y, w, h`` box (``run_IVT.m``, ``run_ASLA.m``).

    Parameters
    ----------
    box : (4,) array_like
    template_width : int
        The template's width in pixels (its scale is ``w / template_width``).
    round_centre : bool
        IVT rounds ``(cx, cy, w, h)`` first (``run_IVT.m``); ASLA does not.

    Returns
    -------
    (6,) float64
        ``cx, cy, w / template_width, 0, h / w, 0``.
    """
    x, y, w, h = (float(v) for v in np.asarray(box, dtype=np.float64).ravel())
    centre = np.array([x + w / 2, y + h / 2, w, h])
    if round_centre:
        centre = matlab_round(centre)
    return np.array([centre[0], centre[1], centre[2] / template_width, 0.0, centre[3] / centre[2], 0.0])


#: The OTB toolkit's box of matrix states (``calcRectCenter.m``), the one the benchmark's files are
#: scored with: (n, 6) matrices and the template's ``(w, h)`` -> (n, 4) 1-based ``x, y, w, h``.
matrix_to_box = ivt_affine_boxes


@njit(**PARALLEL_FLAGS)
def _warp_patches(frame, matrices, patches):
    height, width = frame.shape
    rows, cols = patches.shape[1], patches.shape[2]
    for particle in prange(matrices.shape[0]):
        tx, ty, a11, a12, a21, a22 = matrices[particle]
        for row in range(rows):
            v = row + 1 - rows / 2.0
            for col in range(cols):
                u = col + 1 - cols / 2.0
                # 1-based image point -> 0-based; int() truncates towards zero as the mex's (int)
                x = tx + a11 * u + a12 * v - 1.0
                y = ty + a21 * u + a22 * v - 1.0
                x0 = int(x)
                y0 = int(y)
                fx = x - x0
                fy = y - y0
                top = 0.0
                bottom = 0.0
                if 0 <= y0 < height:
                    if 0 <= x0 < width:
                        top += (1.0 - fx) * frame[y0, x0]
                    if 0 <= x0 + 1 < width:
                        top += fx * frame[y0, x0 + 1]
                if 0 <= y0 + 1 < height:
                    if 0 <= x0 < width:
                        bottom += (1.0 - fx) * frame[y0 + 1, x0]
                    if 0 <= x0 + 1 < width:
                        bottom += fx * frame[y0 + 1, x0 + 1]
                patches[particle, row, col] = top * (1.0 - fy) + bottom * fy


def warp_patches(frame: np.ndarray, matrices: np.ndarray, template_size, out: np.ndarray | None = None) -> np.ndarray:
    """Every particle's ``h x w`` patch of ``frame`` (``warpimg.m`` with the ``interp2`` mex).

    Parameters
    ----------
    frame : (H, W) float64
        Gray frame, C-contiguous, finite.
    matrices : (n, 6) float64
        Matrix states (module docstring), C-contiguous, finite.
    template_size : (2,) int
        ``(h, w)``.
    out : (n, h, w) float64, optional
        Filled and returned when given.

    Returns
    -------
    (n, h, w) float64
    """
    out = check_patch_arguments(frame, matrices, "matrices", "tx, ty, a11, a12, a21, a22", template_size, out)
    _warp_patches(frame, matrices, out)
    return out


def warm_up() -> None:
    """Compile (or load from numba's cache) the warp kernel now, so that no tracker's first frame
    is timed with it."""
    _warp_patches(np.zeros((2, 2)), np.zeros((1, 6)), np.empty((1, 1, 1)))


def warp_patches_reference(frame, matrices, template_size) -> np.ndarray:
    """Plain numpy oracle of :func:`warp_patches` (same arguments; tests only)."""
    frame = np.asarray(frame, dtype=np.float64)
    h, w = (int(v) for v in template_size)
    v, u = np.meshgrid(np.arange(1, h + 1) - h / 2, np.arange(1, w + 1) - w / 2, indexing="ij")
    out = np.empty((len(matrices), h, w))
    padded = np.zeros((frame.shape[0] + 2, frame.shape[1] + 2))
    padded[1:-1, 1:-1] = frame
    for k, (tx, ty, a11, a12, a21, a22) in enumerate(np.asarray(matrices, dtype=np.float64)):
        x = tx + a11 * u + a12 * v - 1.0
        y = ty + a21 * u + a22 * v - 1.0
        x0, y0 = np.trunc(x).astype(np.int64), np.trunc(y).astype(np.int64)
        fx, fy = x - x0, y - y0

        def pixel(r, c):
            inside = (r >= 0) & (r < frame.shape[0]) & (c >= 0) & (c < frame.shape[1])
            return np.where(inside, padded[np.clip(r, -1, frame.shape[0]) + 1, np.clip(c, -1, frame.shape[1]) + 1], 0.0)

        top = (1 - fx) * pixel(y0, x0) + fx * pixel(y0, x0 + 1)
        bottom = (1 - fx) * pixel(y0 + 1, x0) + fx * pixel(y0 + 1, x0 + 1)
        out[k] = top * (1 - fy) + bottom * fy
    return out


def gray_frame(frame: np.ndarray, scale: float) -> np.ndarray:
    """A BGR or gray uint8 frame as the lineage's MATLAB reads it: ``rgb2gray`` (OpenCV's luma
    weights, the same to one gray level), as float64 divided by ``scale`` (IVT 256, ASLA 255).

    Parameters
    ----------
    frame : (H, W, 3) or (H, W) uint8
    scale : float

    Returns
    -------
    (H, W) float64, C-contiguous
    """
    import cv2

    array = np.asarray(frame)
    if not (array.ndim == 2 or (array.ndim == 3 and array.shape[2] == 3)):
        raise ParameterError(f"frame must be (H, W) or (H, W, 3), got shape {array.shape}")
    if array.ndim == 3:
        array = cv2.cvtColor(array, cv2.COLOR_BGR2GRAY)
    return np.ascontiguousarray(array, dtype=np.float64) / scale
