"""Affine target state, in the convention of the IVT / L1APG / SCM trackers.

The state of a target is the 6-vector ``[cx, cy, scale, rotation, aspect, skew]``:

- ``cx, cy``: centre in 0-based pixel coordinates (pixel centres at integers);
- the 2x2 part of the warp is ``A = scale * R(rotation) @ R(-skew) @ diag(1, aspect) @ R(skew)``
  with ``R(t)`` the counter-clockwise rotation by ``t`` radians;
- A maps the centred template grid (a ``PATCH_SIZE`` x ``PATCH_SIZE`` grid whose
  sample ``(row i, column j)`` sits at ``u = j - (P-1)/2, v = i - (P-1)/2``) into the
  image: ``[x, y] = A @ [u, v] + [cx, cy]``.

So at initialisation from a box of size w x h, ``scale = w / P`` and ``aspect = h / w``
(for P = 32: ``scale = w/32``), and rotation = skew = 0.

Boxes are OTB boxes ``(x, y, w, h)``, 1-based (pixel (1, 1) is top-left), and a box's
0-based centre is ``(x - 1 + w/2, y - 1 + h/2)`` (IVT's ``x + w/2`` in MATLAB's 1-based
coordinates). A state's box is the axis-aligned bounding box of the template's corners
``(+-P/2, +-P/2)``: exact for rotation = skew = 0, enclosing otherwise.

Canonical states. ``affine_to_state`` returns the unique state with ``scale > 0``,
``aspect > 0``, ``rotation`` in (-pi, pi], ``skew`` in (-pi/4, pi/4] (and skew = 0 when
aspect = 1; a skew within 1e-12 of -pi/4, where rounding cannot tell the two ends
apart, is returned as its +pi/4 twin). Every matrix with positive determinant has one; ``state -> matrix -> state``
is the identity on canonical states, ``matrix -> state -> matrix`` everywhere.
"""
from __future__ import annotations

import warnings

import numpy as np

from nrmlc.config import PATCH_SIZE
from nrmlc.errors import ParameterError

STATE_FIELDS = ("cx", "cy", "scale", "rotation", "aspect", "skew")


def _rotation(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def state_to_affine(states: np.ndarray) -> np.ndarray:
    """Affine warps of states.

    Parameters
    ----------
    states : (..., 6) float
        ``[cx, cy, scale, rotation, aspect, skew]``.

    Returns
    -------
    matrices : (..., 2, 3) float64
        ``[A | c]`` mapping centred template coordinates ``(u, v, 1)`` to image ``(x, y)``.
    """
    states = np.asarray(states, dtype=np.float64)
    if states.shape[-1:] != (6,):
        raise ParameterError(f"states must have shape (..., 6), got {states.shape}")
    scale, rotation, aspect, skew = (states[..., k] for k in range(2, 6))
    if not rotation.any() and not skew.any():
        # The usual case (the default motion model has no rotation or skew): A is
        # diagonal. Same bits as the general product below, ~10x faster for 600 states.
        matrices = np.zeros(states.shape[:-1] + (2, 3))
        matrices[..., 0, 0] = scale
        matrices[..., 1, 1] = scale * aspect
        matrices[..., :, 2] = states[..., :2]
        return matrices
    stretch = np.zeros(states.shape[:-1] + (2, 2))
    stretch[..., 0, 0] = 1.0
    stretch[..., 1, 1] = aspect
    linear = scale[..., None, None] * (_rotation(rotation) @ _rotation(-skew) @ stretch @ _rotation(skew))
    return np.concatenate([linear, states[..., :2, None]], axis=-1)


def affine_to_state(matrices: np.ndarray) -> np.ndarray:
    """Canonical states of affine warps (inverse of :func:`state_to_affine`).

    Parameters
    ----------
    matrices : (..., 2, 3) float
        Warps with a positive-determinant 2x2 part.

    Returns
    -------
    states : (..., 6) float64
    """
    matrices = np.asarray(matrices, dtype=np.float64)
    if matrices.shape[-2:] != (2, 3):
        raise ParameterError(f"matrices must have shape (..., 2, 3), got {matrices.shape}")
    linear = matrices[..., :2]
    det = linear[..., 0, 0] * linear[..., 1, 1] - linear[..., 0, 1] * linear[..., 1, 0]
    if np.any(~(det > 0)):
        raise ParameterError("affine matrix must have a positive determinant (no reflection, non-degenerate)")
    # Polar decomposition A = R(theta) P, P symmetric positive definite. For 2x2
    # matrices with det > 0 the rotation angle has this closed form.
    rotation = np.arctan2(linear[..., 1, 0] - linear[..., 0, 1], linear[..., 0, 0] + linear[..., 1, 1])
    sym = _rotation(-rotation) @ linear
    p, q, t = sym[..., 0, 0], 0.5 * (sym[..., 0, 1] + sym[..., 1, 0]), sym[..., 1, 1]
    # P = R(-skew) diag(a, b) R(skew) gives (p - t, -2q) = (a - b) (cos 2 skew, sin 2 skew);
    # choosing the sign of (a - b) so that cos(2 skew) >= 0 puts skew in (-pi/4, pi/4].
    spread = np.hypot(p - t, 2 * q)
    sign = np.where((p - t > 0) | ((p - t == 0) & (q <= 0)), 1.0, -1.0)
    diff = sign * spread
    with np.errstate(invalid="ignore", divide="ignore"):
        skew = np.where(spread > 1e-12 * (p + t), 0.5 * np.arctan2(-2 * q / diff, (p - t) / diff), 0.0)
    first = 0.5 * (p + t + diff)
    second = 0.5 * (p + t - diff)
    # At skew = +-pi/4, cos(2 skew) = 0 and rounding alone picks the sign above, so
    # skew = pi/4 can come out as -pi/4. Both name the same warp, since
    # (a, b, skew) = (b, a, skew + pi/2); fold onto the documented end, +pi/4.
    folded = skew <= -np.pi / 4 + 1e-12
    skew = np.where(folded, skew + np.pi / 2, skew)
    first, second = np.where(folded, second, first), np.where(folded, first, second)
    aspect = np.where(spread > 1e-12 * (p + t), second / first, 1.0)
    rotation = np.where(rotation <= -np.pi, rotation + 2 * np.pi, rotation)
    return np.stack([matrices[..., 0, 2], matrices[..., 1, 2], first, rotation, aspect, skew], axis=-1)


def usable_boxes(boxes: np.ndarray) -> np.ndarray:
    """Which boxes name a region: finite values and ``w > 0``, ``h > 0``.

    One rule for every reader of boxes: the metrics evaluate exactly these
    ground-truth rows, and the tracker accepts only such boxes to move to.

    Parameters
    ----------
    boxes : (..., 4) float
        ``(x, y, w, h)``; NaN rows (unannotated frames) are allowed.

    Returns
    -------
    usable : (...) bool
    """
    boxes = np.asarray(boxes, dtype=np.float64)
    if boxes.shape[-1:] != (4,):
        raise ParameterError(f"boxes must have shape (..., 4), got {boxes.shape}")
    with np.errstate(invalid="ignore"):
        return np.isfinite(boxes).all(axis=-1) & (boxes[..., 2] > 0) & (boxes[..., 3] > 0)


def box_iou(first: np.ndarray, second: np.ndarray) -> float:
    """Intersection over union of two boxes ``(x, y, w, h)`` with ``w, h > 0``, as continuous
    rectangles (what :func:`nrmlc.workbench.metrics.overlaps` gives them; the tracker's own, for
    ``expert_blend_iou``)."""
    width = min(first[0] + first[2], second[0] + second[2]) - max(first[0], second[0])
    height = min(first[1] + first[3], second[1] + second[3]) - max(first[1], second[1])
    inter = max(width, 0.0) * max(height, 0.0)
    return float(inter / (first[2] * first[3] + second[2] * second[3] - inter))


def box_to_state(boxes: np.ndarray, patch_size: int = PATCH_SIZE) -> np.ndarray:
    """States of 1-based OTB boxes (rotation = skew = 0).

    Parameters
    ----------
    boxes : (..., 4) float
        ``(x, y, w, h)`` with ``w, h > 0``.

    Returns
    -------
    states : (..., 6) float64
    """
    boxes = np.asarray(boxes, dtype=np.float64)
    if boxes.shape[-1:] != (4,):
        raise ParameterError(f"boxes must have shape (..., 4), got {boxes.shape}")
    x, y, w, h = (boxes[..., k] for k in range(4))
    if np.any(~(w > 0)) or np.any(~(h > 0)):
        raise ParameterError("box width and height must be positive")
    zeros = np.zeros_like(x)
    return np.stack([x - 1 + w / 2, y - 1 + h / 2, w / patch_size, zeros, h / w, zeros], axis=-1)


def state_to_box(states: np.ndarray, patch_size: int = PATCH_SIZE) -> np.ndarray:
    """1-based OTB boxes enclosing the warped template of each state.

    Parameters
    ----------
    states : (..., 6) float

    Returns
    -------
    boxes : (..., 4) float64
        ``(x, y, w, h)``, the axis-aligned bounding box of the template corners.
    """
    matrices = state_to_affine(states)
    half = patch_size / 2.0
    corners = np.array([[-half, -half], [half, -half], [half, half], [-half, half]]).T  # (2, 4)
    points = matrices[..., :2] @ corners + matrices[..., 2:]  # (..., 2, 4)
    low, high = points.min(axis=-1), points.max(axis=-1)
    return np.concatenate([low + 1.0, high - low], axis=-1)


def affine_for_opencv(matrices: np.ndarray, patch_size: int = PATCH_SIZE) -> np.ndarray:
    """Convert warps to OpenCV's inverse-map form for ``cv2.warpAffine``.

    ``cv2.warpAffine(frame, M, (P, P), flags=INTER_LINEAR | WARP_INVERSE_MAP)`` samples
    ``frame`` at ``M @ [col, row, 1]``; our warp samples at ``A @ [col - c, row - c] + t``
    with ``c = (P - 1)/2``. So ``M = [A | t - A @ [c, c]]``.

    Parameters
    ----------
    matrices : (..., 2, 3) float

    Returns
    -------
    opencv_matrices : (..., 2, 3) float64
    """
    matrices = np.array(matrices, dtype=np.float64)
    centre = (patch_size - 1) / 2.0
    matrices[..., 2] -= matrices[..., :2] @ np.array([centre, centre])
    return matrices


def clamp_states(states: np.ndarray, frame_shape: tuple[int, int], min_size: float,
                 patch_size: int = PATCH_SIZE) -> np.ndarray:
    """Keep states in a meaningful range for a frame, in place.

    The centre stays inside the frame (so a box never leaves it entirely), and the
    template grid's width ``patch_size * scale`` and height ``patch_size * scale * aspect``
    stay between ``min_size`` and twice the frame's larger side, whatever the motion
    model drew.

    Parameters
    ----------
    states : (n, 6) float64
    frame_shape : (height, width)

    Returns
    -------
    states : (n, 6) float64, the same array
    """
    height, width = frame_shape
    largest = 2.0 * max(height, width)
    np.clip(states[:, 0], 0.0, width - 1.0, out=states[:, 0])
    np.clip(states[:, 1], 0.0, height - 1.0, out=states[:, 1])
    np.clip(states[:, 2], min_size / patch_size, largest / patch_size, out=states[:, 2])
    side = patch_size * states[:, 2]
    np.clip(states[:, 4], min_size / side, largest / side, out=states[:, 4])
    return states


#: Smallest initial box side accepted, in pixels.
MIN_BOX_SIZE = 4.0


def as_box(box, name: str = "box") -> np.ndarray:
    """A box given as any sequence of 4 numbers, as a (4,) float64 array.

    Raises ParameterError for strings, mappings and anything not 4 finite numbers.
    """
    if isinstance(box, (str, bytes, dict)) or not hasattr(box, "__len__"):
        raise ParameterError(f"{name} must be 4 numbers (x, y, w, h), got {type(box).__name__} {box!r}")
    try:
        array = np.asarray(box, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be 4 numbers (x, y, w, h), got {box!r}") from None
    if array.shape != (4,) or not np.all(np.isfinite(array)):
        raise ParameterError(f"{name} must be 4 finite numbers (x, y, w, h), got {array.tolist()}")
    return array


def clip_initial_box(box, frame_shape) -> np.ndarray:
    """Validate the initial box against the frame: clip it (with a warning) when it is
    partly outside; refuse it when it is wholly outside or smaller than 4 px.

    Returns
    -------
    box : (4,) float64, 1-based OTB ``(x, y, w, h)``
    """
    box = as_box(box, "initial box")
    height, width = frame_shape
    x0, y0 = box[0], box[1]
    x1, y1 = x0 + box[2], y0 + box[3]
    if box[2] <= 0 or box[3] <= 0:
        raise ParameterError(f"initial box {box.tolist()} has a non-positive size")
    # 1-based boxes: the frame spans [1, width + 1) x [1, height + 1).
    cx0, cy0, cx1, cy1 = max(x0, 1.0), max(y0, 1.0), min(x1, width + 1.0), min(y1, height + 1.0)
    if cx1 <= cx0 or cy1 <= cy0:
        raise ParameterError(f"initial box {box.tolist()} lies wholly outside the {width}x{height} frame")
    if (cx0, cy0, cx1, cy1) == (x0, y0, x1, y1):
        clipped = box.copy()  # inside: keep the values as given ((x + w) - x need not equal w in floating point)
    else:
        clipped = np.array([cx0, cy0, cx1 - cx0, cy1 - cy0])
        warnings.warn(f"initial box {box.tolist()} is partly outside the {width}x{height} frame; "
                      f"clipped to {clipped.round(2).tolist()}")
    if clipped[2] < MIN_BOX_SIZE or clipped[3] < MIN_BOX_SIZE:
        raise ParameterError(f"initial box {clipped.round(2).tolist()} is smaller than {MIN_BOX_SIZE:g} px")
    return clipped
