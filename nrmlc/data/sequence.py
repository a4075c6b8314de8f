"""Image sequences with ground truth: the OTB folder layout and its variants.

OTB layout::

    Folder/
        img/0001.jpg ...           frames (jpg, jpeg, png or bmp)
        groundtruth_rect.txt       one x,y,w,h line per frame (1-based)

Variants handled here:

- several targets: ``groundtruth_rect.1.txt``, ``groundtruth_rect.2.txt``, ...
  give one sequence per target, named ``Folder-1``, ``Folder-2`` (OTB's own
  convention, e.g. Jogging-1, Jogging-2);
- sparse-tracker packs (``datainfo.txt`` + ``*_gt.mat``, see
  :mod:`nrmlc.data.sparsepack`): the mat file is the fallback when
  ``groundtruth_rect.txt`` is absent;
- no ground truth at all: every box is NaN, and the caller must give the
  initial box (``init_box=`` or :meth:`Sequence.with_init_box`).

Frames are read on demand, never cached, so a long sequence costs no memory.
"""
from __future__ import annotations

import copy
import os
import re
import warnings
from pathlib import Path
from typing import Iterator, Sequence as SequenceType

import cv2
import numpy as np

from nrmlc.data.boxes import read_box_file
from nrmlc.data.image import to_gray_float32
from nrmlc.data.sparsepack import (
    DATAINFO_NAME,
    find_groundtruth_mat,
    is_sparsepack,
    read_datainfo,
    read_sparsepack_groundtruth,
)
from nrmlc.errors import DataError, ParameterError

IMAGE_FOLDER = "img"
IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp")
GROUNDTRUTH_NAME = "groundtruth_rect.txt"
_TARGET_GROUNDTRUTH = re.compile(r"^groundtruth_rect\.(\d+)\.txt$")
_TARGET_SUFFIX = re.compile(r"^(.+)-(\d+)$")
_DIGITS = re.compile(r"\d+")


class Sequence:
    """A video with per-frame ground-truth boxes; frames are read lazily.

    Parameters
    ----------
    name : sequence name (``Car4``, ``Jogging-2``, ``synth-01``).
    image_paths : (n_frames,) image files in frame order, or None when a
        subclass renders the frames itself (then ``n_frames`` is required).
    groundtruth : (m, 4) 1-based ``x, y, w, h`` boxes, NaN rows for
        unannotated frames, or None when there is no ground truth. A
        length that differs from ``n_frames`` is padded with NaN or
        truncated, with a warning naming ``groundtruth_path``.
    path : the sequence folder, or None (synthetic sequences).
    groundtruth_path : the file the boxes came from (for messages).
    n_frames : number of frames, only when ``image_paths`` is None.
    init_box : (4,) initial box overriding ``groundtruth[0]``.

    Notes
    -----
    Frame 0 is read on construction to learn the frame size and to catch an
    unreadable first image early; later frames are checked when read.
    """

    def __init__(
        self,
        name: str,
        image_paths: SequenceType[Path] | None,
        groundtruth: np.ndarray | None = None,
        *,
        path: Path | None = None,
        groundtruth_path: Path | None = None,
        n_frames: int | None = None,
        init_box: SequenceType[float] | None = None,
    ) -> None:
        self.name = name
        self.path = Path(path) if path is not None else None
        self.groundtruth_path = Path(groundtruth_path) if groundtruth_path is not None else None
        self.image_paths = [Path(p) for p in image_paths] if image_paths is not None else None
        if self.image_paths is not None:
            n_frames = len(self.image_paths)
        if n_frames is None or n_frames < 1:
            raise DataError(f"{self._where}: sequence has no frames")
        self._n_frames = int(n_frames)
        self._has_groundtruth = groundtruth is not None
        self._groundtruth = self._fit_groundtruth(groundtruth)
        self._init_box_override = None if init_box is None else _check_init_box(init_box, self._where)
        # The size is fixed by frame 0; every later frame is compared with it.
        self._frame_size: tuple[int, int] | None = None
        first = self.raw_frame(0)
        self._frame_size = (int(first.shape[0]), int(first.shape[1]))

    # ----------------------------------------------------------------- basics
    def __len__(self) -> int:
        return self._n_frames

    def __repr__(self) -> str:
        height, width = self.frame_size
        where = f", path={str(self.path)!r}" if self.path is not None else ""
        return f"{type(self).__name__}(name={self.name!r}, n_frames={len(self)}, size={height}x{width}{where})"

    @property
    def _where(self) -> str:
        """The folder (or the name) used in messages."""
        return str(self.path) if self.path is not None else self.name

    @property
    def frame_size(self) -> tuple[int, int]:
        """``(height, width)`` of every frame, in pixels."""
        assert self._frame_size is not None
        return self._frame_size

    @property
    def groundtruth(self) -> np.ndarray:
        """(n_frames, 4) float64 1-based ``x, y, w, h`` boxes; NaN rows = unannotated."""
        return self._groundtruth.copy()

    @property
    def annotated(self) -> np.ndarray:
        """(n_frames,) bool: True where the frame has a ground-truth box."""
        return ~np.isnan(self._groundtruth).any(axis=1)

    @property
    def init_box(self) -> np.ndarray:
        """(4,) float64 initial box: the override if given, else ``groundtruth[0]``.

        Raises
        ------
        DataError
            If frame 0 has no usable box (no ground truth, unannotated or
            non-positive size) and no override was given.
        """
        if self._init_box_override is not None:
            return self._init_box_override.copy()
        if not self._has_groundtruth:
            raise DataError(f"{self._where}: no ground truth file; give the initial box (init_box=x,y,w,h)")
        source = self.groundtruth_path if self.groundtruth_path is not None else self._where
        box = self._groundtruth[0]
        if np.isnan(box).any():
            raise DataError(f"{source}: frame 1 is not annotated (0,0,0,0 or NaN); give the initial box")
        if box[2] <= 0 or box[3] <= 0:
            raise DataError(f"{source}: frame 1 box has a non-positive size {box.tolist()}")
        return box.copy()

    def with_init_box(self, box: SequenceType[float]) -> "Sequence":
        """Return a copy of this sequence whose ``init_box`` is ``box``.

        Parameters
        ----------
        box : (4,) 1-based ``x, y, w, h`` with positive size.
        """
        clone = copy.copy(self)
        clone._init_box_override = _check_init_box(box, self._where)
        return clone

    # ----------------------------------------------------------------- frames
    def _read_image(self, index: int) -> np.ndarray:
        """Read frame ``index`` as stored (subclasses may render it instead)."""
        assert self.image_paths is not None
        file = self.image_paths[index]
        try:
            data = file.read_bytes()
        except OSError as exc:
            raise DataError(f"{file}: cannot read image ({exc.strerror or exc})") from None
        if not data:
            raise DataError(f"{file}: cannot read image (empty file)")
        if file.suffix.lower() in (".jpg", ".jpeg") and not _jpeg_is_complete(data):
            # libjpeg decodes a truncated file without error (grey bottom rows): refuse it.
            raise DataError(f"{file}: cannot read image (truncated JPEG: no end-of-image marker)")
        image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise DataError(f"{file}: cannot read image (missing, corrupt or unsupported format)")
        return image

    def _describe_frame(self, index: int) -> str:
        return str(self.image_paths[index]) if self.image_paths is not None else f"{self.name} frame {index + 1}"

    def _check_index(self, index: int) -> int:
        index = int(index)
        if index < 0:
            index += self._n_frames
        if not 0 <= index < self._n_frames:
            raise IndexError(f"{self.name}: frame index {index} outside 0..{self._n_frames - 1}")
        return index

    def raw_frame(self, index: int) -> np.ndarray:
        """Frame ``index`` as stored: uint8/uint16, (H, W) gray, (H, W, 3) BGR or (H, W, 4) BGRA.

        Raises
        ------
        DataError
            If the image cannot be read, has an unsupported pixel type, or its
            size differs from frame 0's (the message names the file).
        """
        index = self._check_index(index)
        image = self._read_image(index)
        if image.ndim == 3 and image.shape[2] == 1:
            image = image[:, :, 0]
        if image.dtype not in (np.uint8, np.uint16) or not (image.ndim == 2 or image.shape[2] in (2, 3, 4)):
            raise DataError(
                f"{self._describe_frame(index)}: unsupported pixel format {image.dtype} with shape {image.shape}"
            )
        if image.ndim == 3 and image.shape[2] == 2:  # gray + alpha: the alpha is of no use here
            image = np.ascontiguousarray(image[:, :, 0])
        if self._frame_size is not None and image.shape[:2] != self._frame_size:
            height, width = self._frame_size
            raise DataError(
                f"{self._describe_frame(index)}: image is {image.shape[0]}x{image.shape[1]} (HxW) "
                f"but frame 1 is {height}x{width}"
            )
        return image

    def frame(self, index: int) -> np.ndarray:
        """Frame ``index`` as (H, W) float32 grayscale in [0, 1].

        uint8 is divided by 255, uint16 by 65535; colour (BGR/BGRA) is
        converted with OpenCV's luma weights, in float so no precision is lost.
        """
        return to_gray_float32(self.raw_frame(index))

    def color_frame(self, index: int) -> np.ndarray:
        """Frame ``index`` as (H, W, 3) uint8 BGR (for drawing and video output)."""
        image = self.raw_frame(index)
        if image.dtype == np.uint16:
            image = cv2.convertScaleAbs(image, alpha=1.0 / 257.0)  # 65535 -> 255, rounded
        if image.ndim == 2:
            return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        if image.shape[2] == 4:
            return cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
        return image

    def __iter__(self) -> Iterator[np.ndarray]:
        """Yield the (H, W) float32 gray frames one at a time, read on demand."""
        for index in range(self._n_frames):
            yield self.frame(index)

    # ------------------------------------------------------------ ground truth
    def _fit_groundtruth(self, groundtruth: np.ndarray | None) -> np.ndarray:
        """Pad (NaN) or truncate the boxes to ``n_frames`` rows, warning on a mismatch."""
        n_frames = self._n_frames
        if groundtruth is None:
            return np.full((n_frames, 4), np.nan)
        boxes = np.asarray(groundtruth, dtype=np.float64)
        if boxes.ndim != 2 or boxes.shape[1] != 4:
            raise DataError(f"{self._where}: ground truth must be an (n, 4) array, got shape {boxes.shape}")
        source = self.groundtruth_path if self.groundtruth_path is not None else self._where
        if len(boxes) < n_frames:
            warnings.warn(
                f"{source}: {len(boxes)} ground-truth boxes for {n_frames} frames; "
                f"the last {n_frames - len(boxes)} frames count as unannotated",
                stacklevel=3,
            )
            boxes = np.vstack([boxes, np.full((n_frames - len(boxes), 4), np.nan)])
        elif len(boxes) > n_frames:
            warnings.warn(
                f"{source}: {len(boxes)} ground-truth boxes for {n_frames} frames; extra boxes ignored",
                stacklevel=3,
            )
            boxes = boxes[:n_frames]
        return boxes.copy()


def _jpeg_is_complete(data: bytes) -> bool:
    """True when the JPEG's last scan (SOS marker FFDA) is followed by an end-of-image marker (FFD9).

    Inside entropy-coded data every 0xFF byte is stuffed (FF00), so FFD9 after the
    last FFDA can only be the real end marker; an embedded EXIF thumbnail's EOI
    comes before the main image's scans and does not count.
    """
    return data.rfind(b"\xff\xd9") > data.rfind(b"\xff\xda") >= 0


def _check_init_box(box: SequenceType[float], where: str) -> np.ndarray:
    values = np.asarray(box, dtype=np.float64).ravel()
    if values.shape != (4,) or not np.isfinite(values).all() or values[2] <= 0 or values[3] <= 0:
        raise ParameterError(f"{where}: initial box must be 4 finite numbers x,y,w,h with w,h > 0, got {box!r}")
    return values


# ------------------------------------------------------------------ layouts
def _frame_sort_key(path: Path) -> tuple[int, int, str]:
    """Sort by the last integer in the file name (``2.png`` before ``10.png``)."""
    numbers = _DIGITS.findall(path.stem)
    if numbers:
        return (0, int(numbers[-1]), path.name)
    return (1, 0, path.name)  # names without a number go last, alphabetically


def find_images(folder: str | os.PathLike) -> list[Path]:
    """Image files of ``folder/img`` sorted by frame number.

    Raises
    ------
    DataError
        If there is no ``img`` folder or it holds no jpg/jpeg/png/bmp file.
    """
    image_folder = Path(folder) / IMAGE_FOLDER
    if not image_folder.is_dir():
        raise DataError(f"{folder}: no '{IMAGE_FOLDER}' folder with the frames")
    images = [
        p for p in image_folder.iterdir()
        if p.suffix.lower() in IMAGE_EXTENSIONS and not p.name.startswith(".") and p.is_file()
    ]
    if not images:
        raise DataError(f"{image_folder}: no images ({', '.join(IMAGE_EXTENSIONS)})")
    return sorted(images, key=_frame_sort_key)


def find_target_groundtruths(folder: str | os.PathLike) -> dict[int, Path]:
    """Per-target ground-truth files ``groundtruth_rect.<k>.txt``, keyed by ``k``."""
    found = {}
    for path in Path(folder).iterdir():
        match = _TARGET_GROUNDTRUTH.match(path.name)
        if match and path.is_file():
            found[int(match.group(1))] = path
    return dict(sorted(found.items()))


def _split_target_name(path: Path) -> tuple[Path, int] | None:
    """``root/Jogging-2`` -> ``(root/Jogging, 2)`` when that folder has target 2."""
    match = _TARGET_SUFFIX.match(path.name)
    if not match:
        return None
    folder = path.with_name(match.group(1))
    target = int(match.group(2))
    if folder.is_dir() and target in find_target_groundtruths(folder):
        return folder, target
    return None


def open_sequence(
    path: str | os.PathLike,
    target: int | None = None,
    init_box: SequenceType[float] | None = None,
) -> Sequence:
    """Open a sequence folder.

    Parameters
    ----------
    path : the sequence folder; a name like ``root/Jogging-2`` (no such
        folder) means target 2 of ``root/Jogging``.
    target : for multi-target folders, which target (1, 2, ...); default
        the first one.
    init_box : (4,) 1-based ``x, y, w, h`` overriding the first box (needed
        when the sequence has no ground truth or frame 1 is unannotated).

    Returns
    -------
    Sequence

    Raises
    ------
    DataError
        Folder missing or not a folder, no images, first image unreadable,
        unknown target, malformed ground truth (the message names the file).
    """
    folder = Path(path)
    if not folder.exists():
        split = _split_target_name(folder)
        if split is None:
            raise DataError(f"{folder}: sequence folder not found")
        folder, named_target = split
        if target is not None and target != named_target:
            raise DataError(f"{path}: the name says target {named_target} but target={target} was given")
        target = named_target
    if not folder.is_dir():
        raise DataError(f"{folder}: not a folder")
    images = find_images(folder)

    name = folder.name
    groundtruth_path: Path | None = None
    targets = find_target_groundtruths(folder)
    if target is not None:
        if target not in targets:
            available = ", ".join(str(k) for k in targets) or "none (single-target folder)"
            raise DataError(f"{folder}: no groundtruth_rect.{target}.txt (targets: {available})")
        groundtruth_path = targets[target]
        name = f"{folder.name}-{target}"
    elif (folder / GROUNDTRUTH_NAME).is_file():
        groundtruth_path = folder / GROUNDTRUTH_NAME
    elif targets:
        first_target = next(iter(targets))
        groundtruth_path = targets[first_target]
        name = f"{folder.name}-{first_target}"

    from_sparsepack = groundtruth_path is None and is_sparsepack(folder)
    if groundtruth_path is not None:
        groundtruth = read_box_file(groundtruth_path)
    elif from_sparsepack:
        groundtruth = read_sparsepack_groundtruth(folder)
        groundtruth_path = find_groundtruth_mat(folder)
    else:
        groundtruth = None

    sequence = Sequence(
        name, images, groundtruth, path=folder, groundtruth_path=groundtruth_path, init_box=init_box
    )
    if from_sparsepack:
        # The mat boxes are in the pixel frame datainfo.txt describes: check it is the images'.
        width, height, _ = read_datainfo(folder)
        if (height, width) != sequence.frame_size:
            raise DataError(
                f"{folder / DATAINFO_NAME}: says {width}x{height} (WxH) but the frames are "
                f"{sequence.frame_size[1]}x{sequence.frame_size[0]}"
            )
    return sequence


def list_sequences(root: str | os.PathLike) -> list[Sequence]:
    """Every sequence under ``root``, sorted by name.

    A subfolder counts as a sequence when it has an ``img`` folder; other
    subfolders are skipped silently. Multi-target folders give one sequence
    per target (``Jogging-1``, ``Jogging-2``).

    Returns
    -------
    list of Sequence

    Raises
    ------
    DataError
        If ``root`` is missing or not a folder, if it holds no sequence, or
        if a sequence folder is broken (the message names the file).
    """
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"{root}: data root {'is not a folder' if root.exists() else 'not found'}")
    sequences = []
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        if not (folder / IMAGE_FOLDER).is_dir():
            continue
        targets = find_target_groundtruths(folder)
        if targets and not (folder / GROUNDTRUTH_NAME).is_file():
            sequences.extend(open_sequence(folder, target) for target in targets)
        else:
            sequences.append(open_sequence(folder))
    if not sequences:
        raise DataError(f"{root}: no sequences (subfolders with an '{IMAGE_FOLDER}' folder)")
    return sorted(sequences, key=lambda s: s.name)
