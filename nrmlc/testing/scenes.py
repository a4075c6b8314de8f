"""Small hand-made scenes for tests whose outcome is known in advance."""
from __future__ import annotations

import cv2
import numpy as np


def jump_scene(jump: float = 16, n_frames: int = 12, jump_frame: int = 4) -> tuple[list[np.ndarray], np.ndarray]:
    """A 24x24 textured square on a smooth textured 160x120 background that stands still,
    then jumps ``jump`` px to the right at ``jump_frame`` and stays there.

    At 16 px the jump is about 10 sigma of the default motion model's translation noise
    (2 template px of a 24 px target is 1.5 px) and 2.7 sigma of the re-detection search's.

    Returns
    -------
    frames : list of (120, 160) uint8
    boxes : (n_frames, 4) float64
        1-based OTB ground truth.
    """
    rng = np.random.default_rng(7)
    background = cv2.GaussianBlur(rng.random((120, 160)).astype(np.float32), (0, 0), 2.0)
    background = 60 + 100 * (background - background.min()) / np.ptp(background)
    texture = cv2.GaussianBlur(rng.random((24, 24)).astype(np.float32), (0, 0), 1.0)
    texture = 20 + 215 * (texture - texture.min()) / np.ptp(texture)
    frames, boxes = [], []
    for index in range(n_frames):
        x = 50 + (int(jump) if index >= jump_frame else 0)
        frame = background.copy()
        frame[40:64, x:x + 24] = texture
        frames.append(frame.astype(np.uint8))
        boxes.append((x + 1, 41, 24, 24))
    return frames, np.array(boxes, dtype=np.float64)


def write_small_suite(root, n_sequences: int):
    """``n_sequences`` synthetic sequences of 10 frames at 96x72 as OTB folders under ``root`` (a data root)."""
    from nrmlc.data import synthetic_suite, write_otb_sequence

    for sequence in synthetic_suite(n_frames=10, size=(72, 96), n_sequences=n_sequences, seed=0):
        write_otb_sequence(sequence, root / sequence.name)
    return root
