"""The :class:`Sequence`: a video with per-frame ground-truth boxes, frames read lazily.

Readers of folder layouts build one: :mod:`nrmlc.data.otb` (OTB folders, with
:mod:`nrmlc.data.sparsepack` for the sparse-tracker packs' ground truth);
:class:`nrmlc.data.synthetic.SyntheticSequence` renders its frames instead.
With no ground truth every box is NaN, and the caller must give the initial
box (``init_box=`` or :meth:`Sequence.with_init_box`).

Frames are read on demand, never cached, so a long sequence costs no memory.
"""
from __future__ import annotations

import copy
import hashlib
import operator
import re
import warnings
from pathlib import Path
from typing import Iterator, Sequence as SequenceType

import cv2
import numpy as np

from nrmlc.data.image import native_messages, native_summary, to_gray_float32
from nrmlc.errors import DataError, ParameterError

#: Smallest frame (pixels per side) the tracker accepts.
MIN_FRAME_SIDE = 2
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"  # the IEND chunk's type and its fixed CRC
_JPEG_SIGNATURE = b"\xff\xd8\xff"
#: What OpenCV decodes by content, whatever the name says (a PNG named .jpg still reads).
_IMAGE_SIGNATURES = (_JPEG_SIGNATURE, _PNG_SIGNATURE, b"BM", b"II*\x00", b"MM\x00*", b"RIFF", b"\x00\x00\x00\x0cjP",
                     b"P1", b"P2", b"P3", b"P4", b"P5", b"P6")
#: libjpeg's warnings that mean image data is missing or garbled (it decodes the rest and
#: fills the hole with grey). "N extraneous bytes before marker 0xd9" is one of them: it is
#: what a scan with flipped bytes ends with (the decoder desynchronises, fills the blocks it
#: has left and stops early), and the message cannot tell that from padding before the end
#: marker, which no encoder of the data we know writes (none of 18,699 OTB frames warns).
_JPEG_DAMAGE = re.compile(r"corrupt jpeg data|premature end|invalid sos|bogus|huffman", re.IGNORECASE)


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
        self._identity: str | None = None  # computed on first use (see identity)
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
    def identity(self) -> str:
        """What the sequence holds, as a string for cache keys: the one definition of it.

        For a folder, ``frames:<n>:sha256=<digest>`` where the digest covers
        every frame's bytes, in frame order, and the ground-truth boxes as
        read (so an edited ``groundtruth_rect.txt`` or a regenerated frame
        gives a new key, and a moved or copied folder keeps its key). Each
        file is hashed once per process while its size and times stay the
        same (:mod:`nrmlc.data.fingerprint`); the string is computed once per
        sequence object. A synthetic sequence returns its generating spec, a
        video file the digest of its bytes. ``:init_box=x,y,w,h`` is appended
        when the initial box was overridden, so that runs from another initial
        box never share a key with ordinary ones.

        Raises
        ------
        DataError
            If a frame can no longer be read (the message names it).
        """
        if self._identity is None:
            self._identity = self._content_identity()
        identity = self._identity
        if self._init_box_override is not None:
            identity += ":init_box=" + ",".join(repr(float(v)) for v in self._init_box_override)
        return identity

    def _content_identity(self) -> str:
        if self.image_paths is None:
            # A subclass that renders its own frames and does not say what they are: its class
            # and name stand in for the frames (as before content keys), never a bare digest of
            # the ground truth that another such sequence could share.
            digest = hashlib.sha256()
            self._hash_groundtruth(digest)
            return f"{type(self).__name__}:{self.name}:{len(self)}:sha256={digest.hexdigest()[:32]}"
        digest = hashlib.sha256()
        for path in self.image_paths:
            digest.update(_digest_of(path).encode())
        self._hash_groundtruth(digest)
        return f"frames:{len(self)}:sha256={digest.hexdigest()[:32]}"

    def _hash_groundtruth(self, digest) -> None:
        """Add the ground truth the runs see (padded or cut to the frame count) to ``digest``."""
        digest.update(b"groundtruth" if self._has_groundtruth else b"no groundtruth")
        digest.update(np.ascontiguousarray(self._groundtruth, dtype=np.float64).tobytes())

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
            raise DataError(f"{self._where}: no ground truth file; give the initial box "
                            f"(--init-box X,Y,W,H on the command line, init_box=(x, y, w, h) in Python)")
        source = self.groundtruth_path if self.groundtruth_path is not None else self._where
        box = self._groundtruth[0]
        if np.isnan(box).any():
            raise DataError(f"{source}: frame 1 is not annotated (0,0,0,0 or NaN); "
                            f"give the initial box (--init-box X,Y,W,H)")
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
        if not data.startswith(_IMAGE_SIGNATURES):
            raise DataError(f"{file}: cannot read image (not an image: no JPEG, PNG or BMP signature; "
                            f"it starts with {data[:12]!r})")
        jpeg = data.startswith(_JPEG_SIGNATURE)
        if jpeg and not _jpeg_is_complete(data):
            # libjpeg decodes a truncated file without error (grey bottom rows): refuse it.
            raise DataError(f"{file}: cannot read image (truncated JPEG: no end-of-image marker)")
        if data.startswith(_PNG_SIGNATURE) and _PNG_END not in data[-16:]:
            # Refused here, before libpng prints its own lines on stderr.
            raise DataError(f"{file}: cannot read image (truncated PNG: no IEND chunk)")
        if data.startswith(b"BM") and len(data) >= 6 and len(data) < int.from_bytes(data[2:6], "little"):
            # OpenCV decodes a short BMP without a word, the missing rows as black.
            raise DataError(f"{file}: cannot read image (truncated BMP: {len(data)} of "
                            f"{int.from_bytes(data[2:6], 'little')} bytes)")
        # libjpeg and libpng print their complaints on stderr: collected here, so that ours stands alone.
        with native_messages() as messages:
            image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
        if image is None:
            detail = f": {native_summary(messages)}" if messages else ""
            raise DataError(f"{file}: cannot read image (corrupt or unsupported format{detail})")
        damage = [m for m in messages if _JPEG_DAMAGE.search(m)] if jpeg else []
        if damage:
            # libjpeg fills what it could not decode with grey and carries on: a frame with a hole.
            raise DataError(f"{file}: cannot read image (damaged JPEG data: {native_summary(damage)})")
        return image

    def _describe_frame(self, index: int) -> str:
        return str(self.image_paths[index]) if self.image_paths is not None else f"{self.name} frame {index + 1}"

    def _check_index(self, index: int) -> int:
        index = operator.index(index)  # 1.5 or "2" is a TypeError, not frame 1 or 2
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
        if min(image.shape[:2]) < MIN_FRAME_SIDE:
            raise DataError(
                f"{self._describe_frame(index)}: image is {image.shape[0]}x{image.shape[1]} (HxW); "
                f"frames must be at least {MIN_FRAME_SIDE}x{MIN_FRAME_SIDE} px"
            )
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


def _digest_of(path: Path) -> str:
    from nrmlc.data.fingerprint import file_digest

    try:
        return file_digest(path)
    except OSError as exc:
        raise DataError(f"{path}: cannot read image ({exc.strerror or exc})") from None


def _jpeg_is_complete(data: bytes) -> bool:
    """True when the JPEG's last scan (SOS marker FFDA) is followed by an end-of-image marker (FFD9).

    Inside entropy-coded data every 0xFF byte is stuffed (FF00), so FFD9 after the
    last FFDA can only be the real end marker; an embedded EXIF thumbnail's EOI
    comes before the main image's scans and does not count.
    """
    return data.rfind(b"\xff\xd9") > data.rfind(b"\xff\xda") >= 0


def _check_init_box(box: SequenceType[float], where: str) -> np.ndarray:
    try:
        values = np.asarray(box, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        values = np.empty(0)
    if (isinstance(box, (str, bytes, dict)) or values.shape != (4,) or not np.isfinite(values).all()
            or values[2] <= 0 or values[3] <= 0):
        raise ParameterError(f"{where}: initial box must be 4 finite numbers x,y,w,h with w,h > 0, got {box!r}")
    return values
