"""A video file (``.mp4``, ``.avi``, anything OpenCV decodes) as a :class:`Sequence`.

A video file has no ground truth: the caller gives the initial box
(``--init-box X,Y,W,H`` on the command line, ``init_box=`` in Python).

The frame count stored in a container's header is an estimate (it is
computed from the duration and the frame rate, and is wrong or missing for
many files), so it is never used: the file is read through once when it is
opened and the frames that decode are counted. Frames are then decoded on
demand: reading frames in order (what tracking does) decodes each frame
once; a backward jump reopens the file and skips forward, because seeking by
frame number (``CAP_PROP_POS_FRAMES``) lands on the nearest key frame in
some containers and would return the wrong frame.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence as SequenceType

import cv2
import numpy as np

from nrmlc.data.image import native_messages
from nrmlc.data.sequence import Sequence
from nrmlc.errors import DataError

class _Reader:
    """One open ``cv2.VideoCapture`` and the index of the frame it reads next.

    Copies of a sequence (``Sequence.with_init_box``) share the reader, so
    they share its position too. It is dropped when pickled (a capture cannot
    be) and reopened on the next read, in the worker process.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        self.capture: cv2.VideoCapture | None = None
        self.position = 0

    def __getstate__(self) -> dict:
        return {"path": self.path}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["path"])

    def open(self) -> None:
        self.close()
        # FFmpeg prints its own lines ("moov atom not found"): collected, so that ours stands alone.
        with native_messages():
            capture = cv2.VideoCapture(str(self.path))
        if not capture.isOpened():
            capture.release()
            raise DataError(f"{self.path}: not a folder, and not a video file OpenCV can read")
        self.capture = capture
        self.position = 0

    def close(self) -> None:
        if self.capture is not None:
            self.capture.release()
        self.capture = None

    def read(self, index: int) -> np.ndarray | None:
        """Frame ``index`` (BGR as OpenCV decodes it), or None if the stream ends before it."""
        if self.capture is None or index < self.position:
            self.open()
        assert self.capture is not None
        with native_messages():
            while self.position < index:  # skip forward without converting the skipped frames
                if not self.capture.grab():
                    return None
                self.position += 1
            ok, image = self.capture.read()
        if not ok or image is None:
            return None
        self.position += 1
        return image

    def count(self) -> int:
        """Number of frames that decode, from the start of the file (reads it through once)."""
        self.open()
        assert self.capture is not None
        n = 0
        with native_messages():
            while self.capture.grab():
                n += 1
        self.close()
        return n


class VideoFileSequence(Sequence):
    """The frames of a video file, without ground truth.

    Parameters
    ----------
    path : the video file.
    init_box : (4,) 1-based ``x, y, w, h`` of the target in frame 1. Without
        it the sequence opens, but :attr:`init_box` raises a
        :class:`~nrmlc.errors.DataError` that says how to give one.
    name : sequence name (default: the file name without its extension).

    Attributes
    ----------
    groundtruth : (n_frames, 4) all NaN (no frame is annotated).

    Raises
    ------
    DataError
        If the file is missing, does not decode, or holds no frame.
    """

    def __init__(self, path: str | os.PathLike, init_box: SequenceType[float] | None = None,
                 name: str | None = None) -> None:
        path = Path(path)
        if not path.is_file():
            raise DataError(f"{path}: video file not found" if not path.exists() else f"{path}: not a file")
        self._reader = _Reader(path)
        n_frames = self._reader.count()
        if n_frames == 0:
            raise DataError(f"{path}: no frame decodes (corrupt video, or a codec this OpenCV build lacks)")
        super().__init__(name or path.stem, None, None, path=path, n_frames=n_frames, init_box=init_box)

    def _content_identity(self) -> str:
        # The file's bytes and the frames that decode from them: any re-encoding gets new cache keys.
        from nrmlc.data.sequence import _digest_of

        return f"video:{len(self)}:sha256={_digest_of(self.path)[:32]}"

    def _read_image(self, index: int) -> np.ndarray:
        image = self._reader.read(index)
        if image is None:
            raise DataError(f"{self.path}: frame {index + 1} does not decode")
        return image

    def _describe_frame(self, index: int) -> str:
        return f"{self.path} frame {index + 1}"

