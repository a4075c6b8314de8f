"""Writing a tracking video: the frames with the tracked (and true) box drawn."""
from __future__ import annotations

import os

import cv2
import numpy as np

from nrmlc.errors import ParameterError


class BoxVideoWriter:
    """Collects frames during tracking and writes an mp4 (mp4v codec).

    The file is written to a temporary name and renamed when closed, so an
    interrupted run leaves no half-written video under the final name.
    """

    def __init__(self, path: str, sequence, fps: float = 25.0) -> None:
        self.path = path
        self.sequence = sequence
        height, width = sequence.frame_size
        directory = os.path.dirname(os.path.abspath(path))
        os.makedirs(directory, exist_ok=True)
        self.tmp_path = os.path.join(directory, f".tmp-{os.path.basename(path)}")
        self.writer = cv2.VideoWriter(self.tmp_path, cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height))
        if not self.writer.isOpened():
            raise ParameterError(f"--video {path}: cannot open a video writer (mp4v)")
        self.frames_written = 0

    def on_frame(self, index: int, tracker, frame) -> None:
        image = self.sequence.color_frame(index).copy()
        truth = self.sequence.groundtruth[index]
        if np.all(np.isfinite(truth)):
            _draw(image, truth, (0, 200, 0))
        box = tracker.initial_box if index == 0 else tracker.last.box
        _draw(image, box, (0, 0, 255))
        cv2.putText(image, f"#{index + 1}", (5, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 255, 255), 1)
        self.writer.write(image)
        self.frames_written += 1

    def close(self) -> None:
        self.writer.release()
        if self.frames_written:
            os.replace(self.tmp_path, self.path)
        elif os.path.exists(self.tmp_path):
            os.unlink(self.tmp_path)


def _draw(image: np.ndarray, box, colour) -> None:
    x, y, w, h = (float(v) for v in box)
    top_left = (int(round(x - 1)), int(round(y - 1)))
    bottom_right = (int(round(x - 1 + w)), int(round(y - 1 + h)))
    cv2.rectangle(image, top_left, bottom_right, colour, 2)
