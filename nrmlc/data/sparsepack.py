"""Reading the "sparse-tracker pack" ground-truth layout.

Some sequences (Caviar1, Occlusion1, Occlusion2) come from the sparse
tracking benchmarks packed as::

    Folder/
        datainfo.txt      width, height, n_frames (one per line or on one line)
        <name>_gt.mat     frameIndex, gtCornersAll (and gtCenterAll, unused)
        img/0001.jpg ...

``frameIndex`` holds the 1-based indices of the annotated keyframes and
``gtCornersAll`` a 1xK cell of 2x5 corner arrays (TL, BL, BR, TR, TL; row 0
is x, row 1 is y, MATLAB 1-based pixel coordinates). The mat file name does
not always follow the folder (Occlusion2 ships ``faceocc2_gt.mat``), so the
file is found by the ``*_gt.mat`` pattern.

A keyframe box is the axis-aligned bounding box of its corners, which is
how the OTB ``groundtruth_rect.txt`` files of these sequences were derived;
frames without a keyframe are unannotated (NaN rows).
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from nrmlc.errors import DataError

DATAINFO_NAME = "datainfo.txt"
GROUNDTRUTH_MAT_PATTERN = "*_gt.mat"
#: Bounds on datainfo.txt beyond which the file is taken as corrupt (a frame
#: count of 1e12 would otherwise allocate its boxes).
MAX_FRAMES = 10_000_000
MAX_FRAME_SIDE = 100_000
# An integer, possibly written as a float with a zero fraction ("320.0", as MATLAB may).
_INTEGER = re.compile(r"[0-9]+(\.0*)?")


def read_datainfo(folder: str | os.PathLike) -> tuple[int, int, int]:
    """Read ``datainfo.txt`` of a sparse-tracker pack.

    Parameters
    ----------
    folder : the sequence folder.

    Returns
    -------
    width, height, n_frames : int
    """
    path = Path(folder) / DATAINFO_NAME
    if not path.is_file():
        raise DataError(f"{path}: datainfo file not found")
    fields = path.read_text(encoding="utf-8", errors="replace").split()
    if len(fields) != 3 or not all(_INTEGER.fullmatch(f) for f in fields):
        raise DataError(f"{path}: expected 3 positive integers (width height n_frames), got {fields}")
    values = [int(float(f)) for f in fields]
    if min(values) <= 0:
        raise DataError(f"{path}: expected 3 positive integers (width height n_frames), got {fields}")
    width, height, n_frames = values
    if max(width, height) > MAX_FRAME_SIDE or n_frames > MAX_FRAMES:
        raise DataError(f"{path}: implausible size {width}x{height} or frame count {n_frames} "
                        f"(at most {MAX_FRAME_SIDE} px per side and {MAX_FRAMES} frames)")
    return width, height, n_frames


def find_groundtruth_mat(folder: str | os.PathLike) -> Path | None:
    """Return the single ``*_gt.mat`` file of ``folder``, or None if there is none.

    Raises
    ------
    DataError
        If several ``*_gt.mat`` files make the choice ambiguous.
    """
    matches = groundtruth_mats(folder)
    if len(matches) > 1:
        names = ", ".join(m.name for m in matches)
        raise DataError(f"{folder}: several ground-truth mat files ({names}); keep one")
    return matches[0] if matches else None


def groundtruth_mats(folder: str | os.PathLike) -> list[Path]:
    """The ``*_gt.mat`` files of ``folder``, by name: the extension in any case (``_GT.MAT``), and
    never a hidden name (``._faceocc2_gt.mat``, the metadata file a Mac leaves beside a copy, is
    no second ground truth)."""
    suffix = GROUNDTRUTH_MAT_PATTERN.lstrip("*")
    return sorted(p for p in Path(folder).iterdir()
                  if not p.name.startswith(".") and p.name.lower().endswith(suffix) and len(p.name) > len(suffix))


def is_sparsepack(folder: str | os.PathLike) -> bool:
    """True when ``folder`` has a ``datainfo.txt`` and a ``*_gt.mat`` file."""
    folder = Path(folder)
    return (folder / DATAINFO_NAME).is_file() and bool(groundtruth_mats(folder))


def corners_to_box(corners: np.ndarray) -> np.ndarray:
    """Axis-aligned bounding box of a polygon.

    Parameters
    ----------
    corners : (2, m) array; row 0 holds x, row 1 holds y (1-based coordinates).

    Returns
    -------
    box : (4,) float64 ``x, y, w, h`` (1-based, like the corners).
    """
    xs, ys = np.asarray(corners, dtype=np.float64)
    return np.array([xs.min(), ys.min(), xs.max() - xs.min(), ys.max() - ys.min()])


def read_sparsepack_groundtruth(folder: str | os.PathLike, n_images: int | None = None) -> np.ndarray:
    """Read the keyframe ground truth of a sparse-tracker pack.

    Parameters
    ----------
    folder : sequence folder holding ``datainfo.txt`` and one ``*_gt.mat``.
    n_images : the number of frames in ``img/``, when known: ``datainfo.txt``
        must give the same count.

    Returns
    -------
    boxes : (n_frames, 4) float64
        1-based OTB ``x, y, w, h`` boxes, with ``n_frames`` from
        ``datainfo.txt``; NaN rows for frames that are not keyframes.

    Raises
    ------
    DataError
        On a missing/ambiguous/unreadable mat file, missing variables, a
        keyframe index that is not an integer in ``1..n_frames`` or appears
        twice, a corner array that is malformed or holds text, NaN or
        infinite values, corners more than a frame's width (height) outside
        the frame ``datainfo.txt`` gives, a box of zero width or height, or
        a frame count that disagrees with ``n_images``.
    """
    import scipy.io  # deferred: scipy.io is slow to import and rarely needed

    width, height, n_frames = read_datainfo(folder)
    if n_images is not None and n_frames != n_images:
        raise DataError(f"{Path(folder) / DATAINFO_NAME}: says {n_frames} frames but the img folder holds {n_images}")
    mat_path = find_groundtruth_mat(folder)
    if mat_path is None:
        raise DataError(f"{folder}: no {GROUNDTRUTH_MAT_PATTERN} ground-truth file")
    try:
        contents = scipy.io.loadmat(str(mat_path))
    except Exception as exc:  # scipy raises several unrelated types on bad files
        raise DataError(f"{mat_path}: cannot read mat file ({exc})") from None
    for variable in ("frameIndex", "gtCornersAll"):
        if variable not in contents:
            raise DataError(f"{mat_path}: variable {variable!r} not found")
    frame_indices = np.asarray(contents["frameIndex"]).ravel()
    corner_cells = np.asarray(contents["gtCornersAll"], dtype=object).ravel()
    if len(frame_indices) != len(corner_cells):
        raise DataError(
            f"{mat_path}: frameIndex has {len(frame_indices)} entries but "
            f"gtCornersAll has {len(corner_cells)}"
        )

    if frame_indices.dtype.kind not in "biuf":
        raise DataError(f"{mat_path}: frameIndex must hold numbers, got {frame_indices.dtype}")
    boxes = np.full((n_frames, 4), np.nan)
    seen = set()
    for raw_index, corners in zip(frame_indices, corner_cells):
        if not np.isfinite(raw_index) or raw_index != np.round(raw_index):
            raise DataError(f"{mat_path}: frameIndex {raw_index.item()!r} is not an integer")
        frame_index = int(raw_index)
        if not 1 <= frame_index <= n_frames:
            raise DataError(f"{mat_path}: keyframe {frame_index} outside 1..{n_frames}")
        if frame_index in seen:
            raise DataError(f"{mat_path}: keyframe {frame_index} appears twice in frameIndex")
        seen.add(frame_index)
        corners = np.asarray(corners)
        if corners.dtype.kind not in "biuf":
            raise DataError(f"{mat_path}: keyframe {frame_index}: corners must be numbers, got {corners.dtype}")
        corners = corners.astype(np.float64)
        if corners.ndim != 2 or corners.shape[0] != 2 or corners.shape[1] < 3:
            raise DataError(
                f"{mat_path}: keyframe {frame_index}: corners must be a 2 x m array, got shape {corners.shape}"
            )
        if not np.isfinite(corners).all():
            raise DataError(f"{mat_path}: keyframe {frame_index}: NaN or infinite corner coordinates")
        xs, ys = corners
        # More than a frame's size outside the frame is no annotation of this video (a box may
        # stick out of the frame a little, as a target leaving it does).
        if xs.min() < 1 - width or xs.max() > 2 * width + 1 or ys.min() < 1 - height or ys.max() > 2 * height + 1:
            raise DataError(f"{mat_path}: keyframe {frame_index}: corners x {xs.min():g}..{xs.max():g}, "
                            f"y {ys.min():g}..{ys.max():g} lie far beyond the {width}x{height} frame")
        box = corners_to_box(corners)
        if box[2] <= 0 or box[3] <= 0:
            raise DataError(f"{mat_path}: keyframe {frame_index}: a box of zero size ({box[2]:g}x{box[3]:g} px)")
        boxes[frame_index - 1] = box
    return boxes
