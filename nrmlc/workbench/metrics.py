"""OTB one-pass evaluation (OPE): centre error, overlap, success and precision.

This module scores a tracker's boxes against ground truth the way the OTB
benchmark toolkit (Wu, Lim and Yang, "Online Object Tracking: A Benchmark",
CVPR 2013) does. Every convention is listed here; the README points to this
docstring.

Boxes
    Arrays of shape ``(n, 4)`` (or a single ``(4,)`` box), rows ``x, y, w, h``
    in OTB pixel coordinates (1-based, as read by
    :func:`nrmlc.data.boxes.read_box_file`). Both metrics below are invariant
    to a common shift, so 0-based and 1-based boxes give the same scores as
    long as predicted and ground-truth boxes use the same origin.

Centre location error (CLE), :func:`center_errors`
    Euclidean distance in pixels between the box centres, the centre of a box
    being ``(x + w/2, y + h/2)``.

Overlap (IoU), :func:`overlaps`
    Boxes are continuous rectangles ``[x, x+w] x [y, y+h]``, the convention of
    the toolkit's ``calcRectInt``: the area of a box is ``w * h`` (no ``+1``),
    and boxes that only touch along an edge or at a corner have overlap 0.
    ``IoU = area(A & B) / (area(A) + area(B) - area(A & B))``. Negative sizes
    are clamped to 0 (an empty box); if both boxes are empty the overlap is 0.
    Widths and heights are taken as ``(x + w) - x`` so that identical boxes
    give an overlap of exactly 1 in floating point. NaN in either box gives
    NaN (the evaluation turns those into failures, see below).

Success plot, :func:`success_curve`
    For the 21 thresholds ``np.linspace(0, 1, 21)`` (0, 0.05, ..., 1), the
    fraction of frames whose overlap is **strictly greater** than the
    threshold (as the toolkit: ``sum(overlap > t)``). So an overlap of exactly
    0.5 does not count at 0.5, and the value at threshold 1 is always 0.
    The success AUC (:func:`success_auc`) is the plain mean of the 21 values,
    as the toolkit reports it in the plot legends.

Precision plot, :func:`precision_curve`
    For the 51 thresholds ``0, 1, ..., 50`` pixels, the fraction of frames
    whose CLE is **less than or equal** to the threshold (toolkit:
    ``sum(errCenter <= t)``). Precision@20 is the value at 20 px, so a centre
    error of exactly 20 px counts as a success.

Which frames are evaluated, :func:`evaluate`
    A frame is evaluated when its ground-truth row is annotated: finite
    values and ``w > 0`` and ``h > 0`` (rows of NaN, as ``read_box_file``
    returns for ``0,0,0,0`` lines, are skipped). Frame 0 is excluded when
    ``skip_first`` is true (the default), because the tracker is given that
    box. If no frame is left, :class:`~nrmlc.errors.DataError` is raised, and
    so it is for a ground-truth value beyond ``MAX_COORDINATE`` (1e9 px, as
    ``read_box_file`` refuses it: such a box is a broken annotation, and its
    area would overflow).

Missing and failed predictions
    A predicted row with any non-finite value (NaN: the tracker gave no box;
    ``inf``) or any value beyond ``MAX_COORDINATE`` in magnitude (an absurd
    box), and every ground-truth frame beyond the end of a *shorter*
    predicted array, is a *missing prediction*: a failed frame, with overlap
    0 and CLE ``+inf``, so it fails every threshold of both curves. It stays
    in the denominators of the success and precision curves (so it lowers
    both) and in the mean overlap. Extra predicted rows beyond the end of the
    ground truth are ignored. Their number is reported as
    ``Evaluation.n_missing``. A finite predicted box of zero or negative size
    is scored as it is: an empty box (overlap 0) with a centre.

Summary numbers of an :class:`Evaluation`
    ``mean_overlap`` is the mean IoU over all evaluated frames (missing
    predictions count as 0). ``mean_center_error`` is the mean CLE over the
    evaluated frames that have a prediction only (an infinite error would
    make the mean meaningless); it is NaN when every prediction is missing,
    in which case :meth:`Evaluation.as_dict` writes ``None``.
    ``success_auc`` and ``precision_20`` come from the curves above.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from nrmlc.data.boxes import MAX_COORDINATE, read_box_file
from nrmlc.errors import DataError, ParameterError
from nrmlc.geometry import usable_boxes

__all__ = [
    "MAX_COORDINATE",
    "SUCCESS_THRESHOLDS",
    "PRECISION_THRESHOLDS",
    "PRECISION_AT",
    "center_errors",
    "overlaps",
    "success_curve",
    "success_auc",
    "precision_curve",
    "Evaluation",
    "evaluate",
    "evaluate_files",
]

#: Overlap thresholds of the OTB success plot: 0, 0.05, ..., 1 (21 values).
SUCCESS_THRESHOLDS = np.linspace(0.0, 1.0, 21)
SUCCESS_THRESHOLDS.setflags(write=False)

#: Centre-error thresholds (pixels) of the OTB precision plot: 0, 1, ..., 50.
PRECISION_THRESHOLDS = np.arange(0, 51, dtype=np.float64)
PRECISION_THRESHOLDS.setflags(write=False)

#: Threshold (pixels) of the headline precision score.
PRECISION_AT = 20.0


def _boxes(boxes, name: str) -> np.ndarray:
    try:
        arr = np.asarray(boxes, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"{name}: expected numeric boxes of shape (n, 4), got {type(boxes).__name__}") from None
    if arr.ndim not in (1, 2) or arr.shape[-1] != 4:
        raise ParameterError(f"{name}: expected boxes of shape (n, 4) or (4,), got shape {arr.shape}")
    return arr


def _pair(predicted, groundtruth) -> tuple[np.ndarray, np.ndarray]:
    p = _boxes(predicted, "predicted")
    g = _boxes(groundtruth, "groundtruth")
    try:
        np.broadcast_shapes(p.shape, g.shape)
    except ValueError:
        raise ParameterError(
            f"predicted and groundtruth have incompatible shapes {p.shape} and {g.shape}"
        ) from None
    return p, g


def center_errors(predicted, groundtruth) -> np.ndarray:
    """Centre location error (CLE) between boxes.

    Parameters
    ----------
    predicted, groundtruth : array_like, (n, 4) or (4,)
        Boxes ``x, y, w, h``; a single ``(4,)`` box is broadcast against the
        other array.

    Returns
    -------
    errors : (n,) float64 (or a 0-d array for two single boxes)
        Euclidean distance in pixels between the centres ``(x + w/2, y + h/2)``.
        NaN where either box has a NaN.
    """
    p, g = _pair(predicted, groundtruth)
    dx = (p[..., 0] + p[..., 2] / 2.0) - (g[..., 0] + g[..., 2] / 2.0)
    dy = (p[..., 1] + p[..., 3] / 2.0) - (g[..., 1] + g[..., 3] / 2.0)
    return np.hypot(dx, dy)


def overlaps(predicted, groundtruth) -> np.ndarray:
    """Intersection over union of axis-aligned boxes (OTB ``calcRectInt``).

    Parameters
    ----------
    predicted, groundtruth : array_like, (n, 4) or (4,)
        Boxes ``x, y, w, h``, taken as continuous rectangles
        ``[x, x+w] x [y, y+h]``; a single ``(4,)`` box is broadcast.

    Returns
    -------
    iou : (n,) float64 in [0, 1] (or a 0-d array for two single boxes)
        Area of the intersection over area of the union; 0 for disjoint or
        edge-touching boxes and when both boxes are empty; NaN where either
        box has a NaN.
    """
    p, g = _pair(predicted, groundtruth)
    p_left, p_top = p[..., 0], p[..., 1]
    g_left, g_top = g[..., 0], g[..., 1]
    # Clamp negative sizes: a box with w < 0 is empty, not a mirrored box.
    p_right = np.maximum(p_left + p[..., 2], p_left)
    p_bottom = np.maximum(p_top + p[..., 3], p_top)
    g_right = np.maximum(g_left + g[..., 2], g_left)
    g_bottom = np.maximum(g_top + g[..., 3], g_top)
    inter_w = np.clip(np.minimum(p_right, g_right) - np.maximum(p_left, g_left), 0.0, None)
    inter_h = np.clip(np.minimum(p_bottom, g_bottom) - np.maximum(p_top, g_top), 0.0, None)
    inter = inter_w * inter_h
    # Areas from the same edge differences as the intersection, so that
    # identical boxes give inter == area exactly and IoU == 1.0.
    union = (p_right - p_left) * (p_bottom - p_top) + (g_right - g_left) * (g_bottom - g_top) - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        iou = np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)
    iou = np.clip(iou, 0.0, 1.0)
    nan = np.isnan(p).any(axis=-1) | np.isnan(g).any(axis=-1)
    return np.where(nan, np.nan, iou)


#: A result belongs to a sequence only when its first box overlaps the sequence's box on that frame this much.
FIRST_BOX_MIN_IOU = 0.5


def first_box_mismatch(boxes, reference) -> tuple[list, list, float] | None:
    """None when the first of ``boxes`` is the sequence's ``reference`` box (IoU >= :data:`FIRST_BOX_MIN_IOU`);
    else (that first box, the reference, rounded to 0.1 px, and their IoU) for the note that refuses the result
    (results on another version of the sequence)."""
    iou = float(overlaps(boxes[0], reference))
    if iou >= FIRST_BOX_MIN_IOU:
        return None
    return np.round(boxes[0], 1).tolist(), np.round(reference, 1).tolist(), iou


def _thresholds(thresholds, default: np.ndarray, name: str) -> np.ndarray:
    if thresholds is None:
        return default
    t = np.asarray(thresholds, dtype=np.float64)
    if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)):
        raise ParameterError(f"{name}: expected a non-empty 1-D array of finite thresholds")
    return t


def _values(values, name: str) -> np.ndarray:
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 1:
        raise ParameterError(f"{name}: expected a 1-D array, got shape {v.shape}")
    if v.size == 0:
        raise DataError(f"{name}: no frames to score")
    return v


def success_curve(overlaps, thresholds=None) -> np.ndarray:
    """OTB success plot: fraction of frames with overlap above each threshold.

    Parameters
    ----------
    overlaps : array_like, (n,)
        Per-frame IoU. NaN counts as a failure (it is not ``> t``).
    thresholds : array_like, (k,), optional
        Default :data:`SUCCESS_THRESHOLDS` = ``np.linspace(0, 1, 21)``.

    Returns
    -------
    curve : (k,) float64
        ``curve[i] = mean(overlaps > thresholds[i])`` (strictly greater).
    """
    v = _values(overlaps, "overlaps")
    t = _thresholds(thresholds, SUCCESS_THRESHOLDS, "thresholds")
    return (v[None, :] > t[:, None]).mean(axis=1)


def success_auc(overlaps, thresholds=None) -> float:
    """Area under the success plot: the mean of :func:`success_curve`.

    Parameters
    ----------
    overlaps : array_like, (n,)
    thresholds : array_like, (k,), optional

    Returns
    -------
    auc : float in [0, 1]
    """
    return float(np.mean(success_curve(overlaps, thresholds)))


def precision_curve(errors, thresholds=None) -> np.ndarray:
    """OTB precision plot: fraction of frames with centre error within each threshold.

    Parameters
    ----------
    errors : array_like, (n,)
        Per-frame centre location error in pixels; ``+inf`` and NaN count
        as failures.
    thresholds : array_like, (k,), optional
        Default :data:`PRECISION_THRESHOLDS` = ``0, 1, ..., 50`` pixels.

    Returns
    -------
    curve : (k,) float64
        ``curve[i] = mean(errors <= thresholds[i])``; with the default
        thresholds, ``curve[20]`` is precision@20.
    """
    v = _values(errors, "errors")
    t = _thresholds(thresholds, PRECISION_THRESHOLDS, "thresholds")
    return (v[None, :] <= t[:, None]).mean(axis=1)


@dataclass(frozen=True, eq=False)
class Evaluation:
    """Result of a one-pass evaluation of one sequence.

    Attributes
    ----------
    n_frames : int
        Number of evaluated frames (annotated, minus frame 0 if skipped).
    n_missing : int
        Evaluated frames without a usable predicted box (missing or failed predictions).
    mean_center_error : float
        Mean CLE in pixels over evaluated frames with a prediction (NaN if none).
    mean_overlap : float
        Mean IoU over all evaluated frames (missing predictions count as 0).
    success_auc : float
        Mean of :attr:`success`.
    precision_20 : float
        Fraction of evaluated frames with CLE <= 20 px.
    success : (21,) float64
        Success curve at ``np.linspace(0, 1, 21)``.
    precision : (51,) float64
        Precision curve at 0, 1, ..., 50 px.
    overlaps : (n_frames,) float64
        Per-frame IoU of the evaluated frames (0 where missing).
    center_errors : (n_frames,) float64
        Per-frame CLE of the evaluated frames (``+inf`` where missing).
    frames : (n_frames,) int64
        0-based indices of the evaluated frames.
    """

    n_frames: int
    n_missing: int
    mean_center_error: float
    mean_overlap: float
    success_auc: float
    precision_20: float
    success: np.ndarray
    precision: np.ndarray
    overlaps: np.ndarray
    center_errors: np.ndarray
    frames: np.ndarray

    def as_dict(self) -> dict:
        """Scalar fields as a JSON-ready dict (NaN written as ``None``)."""

        def clean(x: float) -> float | None:
            x = float(x)
            return None if math.isnan(x) else x

        return {
            "n_frames": int(self.n_frames),
            "n_missing": int(self.n_missing),
            "mean_center_error": clean(self.mean_center_error),
            "mean_overlap": clean(self.mean_overlap),
            "success_auc": clean(self.success_auc),
            "precision_20": clean(self.precision_20),
        }


def evaluate(predicted, groundtruth, skip_first: bool = True) -> Evaluation:
    """Score predicted boxes against ground truth (OTB one-pass evaluation).

    Parameters
    ----------
    predicted : array_like, (m, 4)
        Tracker boxes ``x, y, w, h``, one row per frame starting at frame 0.
        Rows with a non-finite value or a value beyond ``MAX_COORDINATE`` are
        missing predictions (failed frames). If ``m`` is smaller than ``n``,
        the missing rows are failures; extra rows are ignored.
    groundtruth : array_like, (n, 4)
        Annotated boxes; rows with a non-finite value or ``w <= 0`` or
        ``h <= 0`` are not evaluated.
    skip_first : bool, default True
        Do not evaluate frame 0 (the initial box given to the tracker).

    Returns
    -------
    Evaluation

    Raises
    ------
    DataError
        When no frame is left to evaluate, or a ground-truth value is beyond
        ``MAX_COORDINATE``.
    ParameterError
        When an array is not of shape ``(k, 4)``.
    """
    g = _boxes(groundtruth, "groundtruth")
    p = _boxes(predicted, "predicted")
    if g.ndim != 2 or p.ndim != 2:
        raise ParameterError("evaluate: predicted and groundtruth must be 2-D arrays of shape (n, 4)")
    n = g.shape[0]
    if p.shape[0] >= n:
        p = p[:n]
    else:
        p = np.vstack([p, np.full((n - p.shape[0], 4), np.nan)])

    with np.errstate(invalid="ignore"):
        absurd = np.flatnonzero((np.abs(g) > MAX_COORDINATE).any(axis=1))
    if absurd.size:
        raise DataError(f"groundtruth row {absurd[0] + 1}: value beyond {MAX_COORDINATE:g} px "
                        f"in {g[absurd[0]].tolist()}")
    annotated = usable_boxes(g)
    if skip_first and n > 0:
        annotated[0] = False
    frames = np.flatnonzero(annotated)
    if frames.size == 0:
        raise DataError(
            f"no annotated frames to evaluate ({n} ground-truth rows"
            f"{', frame 0 skipped' if skip_first else ''})"
        )
    g = g[frames]
    p = p[frames]
    with np.errstate(invalid="ignore"):
        have = np.isfinite(p).all(axis=1) & (np.abs(p) <= MAX_COORDINATE).all(axis=1)

    iou = np.where(have, overlaps(np.where(have[:, None], p, 0.0), g), 0.0)
    cle = np.where(have, center_errors(np.where(have[:, None], p, 0.0), g), np.inf)
    iou.setflags(write=False)
    cle.setflags(write=False)

    success = success_curve(iou)
    precision = precision_curve(cle)
    mean_cle = float(np.mean(cle[have])) if have.any() else math.nan
    frames = frames.astype(np.int64)
    for arr in (success, precision, frames):
        arr.setflags(write=False)
    return Evaluation(
        n_frames=int(frames.size),
        n_missing=int(np.count_nonzero(~have)),
        mean_center_error=mean_cle,
        mean_overlap=float(np.mean(iou)),
        success_auc=float(np.mean(success)),
        precision_20=float(np.mean(cle <= PRECISION_AT)),
        success=success,
        precision=precision,
        overlaps=iou,
        center_errors=cle,
        frames=frames,
    )


def evaluate_files(
    result_path: str | os.PathLike,
    groundtruth_path: str | os.PathLike,
    skip_first: bool = True,
) -> Evaluation:
    """Score a result box file against a ground-truth box file.

    Parameters
    ----------
    result_path : path
        Tracker output, one ``x,y,w,h`` line per frame (read with
        :func:`nrmlc.data.boxes.read_box_file` with ``predictions=True``:
        ``0,0,0,0``, NaN, infinite and absurd lines are missing predictions).
    groundtruth_path : path
        OTB ``groundtruth_rect.txt``.
    skip_first : bool, default True
        Do not evaluate frame 0.

    Returns the :class:`Evaluation`, as :func:`evaluate` does; raises :class:`DataError` on an
    unreadable file, or when no frame is left to evaluate.
    """
    predicted = read_box_file(result_path, predictions=True)
    groundtruth = read_box_file(groundtruth_path)
    try:
        return evaluate(predicted, groundtruth, skip_first=skip_first)
    except DataError as exc:
        raise DataError(f"{os.fspath(groundtruth_path)}: {exc}") from None
