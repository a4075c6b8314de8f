"""Writing a tracking video: the frames with the tracked (and true) box drawn.

The video is written like every other output (:mod:`nrmlc.io`): to a
uniquely named temporary file beside the destination, renamed over it only
by :meth:`BoxVideoWriter.close` (or with the run's other outputs, see
:meth:`BoxVideoWriter.finish`) after a successful run; :meth:`abort`
(an exception, Ctrl-C) removes it and leaves an earlier video untouched.
"""
from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from nrmlc import io
from nrmlc.data.image import native_messages
from nrmlc.errors import OutputError, ParameterError

#: Containers that OpenCV writes with the mp4v codec (checked before opening, so
#: that an unknown extension gives our message, not OpenCV's).
VIDEO_EXTENSIONS = (".mp4", ".m4v", ".mov", ".avi", ".mkv")


def check_video_path(path: str | os.PathLike, option: str = "--video") -> None:
    """Refuse a video file name whose extension OpenCV cannot write."""
    suffix = Path(path).suffix.lower()
    if suffix not in VIDEO_EXTENSIONS:
        raise ParameterError(f"{option} {os.fspath(path)}: unknown video extension {suffix or '(none)'!r}; "
                             f"use one of {', '.join(VIDEO_EXTENSIONS)}")


def _quiet_stderr():
    """Keep C-level stderr (OpenCV/FFmpeg print their own lines there) from the user."""
    return native_messages()


def count_decodable_frames(path: str | os.PathLike) -> int:
    """How many frames decode from the start of the video file ``path`` (0 if it does not open)."""
    with native_messages():
        capture = cv2.VideoCapture(str(path))
        try:
            if not capture.isOpened():
                return 0
            n = 0
            while capture.grab():
                n += 1
            return n
        finally:
            capture.release()


class BoxVideoWriter:
    """Draws each tracked frame into an mp4v video, written atomically.

    Parameters
    ----------
    path : destination (.mp4, .m4v, .mov, .avi or .mkv).
    sequence : nrmlc.data.Sequence whose frames are drawn.
    fps : frame rate of the video.

    Raises
    ------
    ParameterError
        Unknown extension, or OpenCV cannot open a writer (message names ``path``).
    """

    def __init__(self, path: str | os.PathLike, sequence, fps: float = 25.0) -> None:
        check_video_path(path)
        self.path = Path(path)
        self.sequence = sequence
        height, width = sequence.frame_size
        self.tmp_path = io.temporary_for(path)
        try:
            with _quiet_stderr():
                self.writer = cv2.VideoWriter(str(self.tmp_path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height))
        except BaseException:
            io.discard(self.tmp_path)
            raise
        if not self.writer.isOpened():
            io.discard(self.tmp_path)
            raise ParameterError(f"--video {path}: cannot open a video writer (mp4v)")
        self.frames_written = 0

    def on_frame(self, index: int, tracker, frame) -> None:
        """Draw frame ``index`` with NRMLC's box (:func:`nrmlc.tracker.loop.track_sequence`'s hook)."""
        self.draw(index, tracker.initial_box if index == 0 else tracker.last.box)

    def draw(self, index: int, box) -> None:
        """Write frame ``index`` with ``box`` (1-based ``x, y, w, h``) and the ground truth drawn."""
        image = self.sequence.color_frame(index).copy()
        boxes = self.sequence.groundtruth
        truth = boxes[index] if boxes is not None and index < len(boxes) else None
        has_truth = truth is not None and bool(np.all(np.isfinite(truth)))
        if has_truth:
            _draw(image, truth, TRUTH_COLOUR)
        _draw(image, box, TRACKER_COLOUR)
        _legend(image, index, has_truth)
        with native_messages():
            self.writer.write(image)
        self.frames_written += 1

    def finish(self) -> Path | None:
        """Finish the video in its temporary file and return that file (None: no frame was drawn).

        The caller renames it over ``path`` (:func:`nrmlc.io.commit`, or
        :meth:`nrmlc.io.Together.file` with the run's other outputs).
        """
        with native_messages():
            self.writer.release()
        if not self.frames_written:
            io.discard(self.tmp_path)
            return None
        # OpenCV reports no write error (a full disk, a lost file system): a video is kept only
        # when every frame drawn decodes back from the file, before it replaces anything.
        if os.path.getsize(self.tmp_path) == 0:
            io.discard(self.tmp_path)
            raise OutputError(f"--video {self.path}: the video writer wrote nothing (disk full?); no video written")
        decoded = count_decodable_frames(self.tmp_path)
        if decoded != self.frames_written:
            io.discard(self.tmp_path)
            raise OutputError(f"--video {self.path}: only {decoded} of the {self.frames_written} frames written "
                              f"decode back (disk full?); no video written, the earlier file is kept")
        return self.tmp_path

    def close(self) -> None:
        """Finish the video and rename it over ``path`` (call only after a successful run)."""
        if self.finish() is not None:
            io.commit(self.tmp_path, self.path)

    def abort(self) -> None:
        """Drop the partial video; an earlier file at ``path`` stays as it was."""
        with native_messages():
            self.writer.release()
        io.discard(self.tmp_path)


#: Box colours (BGR): the tracker's estimate and the ground truth.
TRACKER_COLOUR = (0, 0, 255)
TRUTH_COLOUR = (0, 200, 0)


def _legend(image: np.ndarray, index: int, has_truth: bool) -> None:
    """Frame number and a key of the box colours, top left, on a dark band so it reads on
    any background."""
    entries = [(f"#{index + 1}", (0, 255, 255)), ("NRMLC", TRACKER_COLOUR)]
    if has_truth:
        entries.append(("ground truth", TRUTH_COLOUR))
    x = 4
    cv2.rectangle(image, (0, 0), (min(image.shape[1] - 1, 250), 22), (0, 0, 0), -1)
    for text, colour in entries:
        cv2.putText(image, text, (x, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv2.LINE_AA)
        x += cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)[0][0] + 10


def _draw(image: np.ndarray, box, colour) -> None:
    x, y, w, h = (float(v) for v in box)
    if not all(np.isfinite(v) and abs(v) < 1e7 for v in (x, y, w, h)):
        return  # nothing sensible to draw (and cv2 wants ints)
    top_left = (int(round(x - 1)), int(round(y - 1)))
    bottom_right = (int(round(x - 1 + w)), int(round(y - 1 + h)))
    cv2.rectangle(image, top_left, bottom_right, colour, 2)
