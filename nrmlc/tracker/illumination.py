"""The frame with its local brightness removed (``illumination_window``; *ours*, 0 = off, the paper).

Patches are unit-norm (:mod:`nrmlc.kernels.warp`), so a change of gain over the patch already
cancels; a change of brightness (an offset) does not, and it is what a light switched on or a
stage light sweeping across a face adds. Subtracting the frame's local mean, taken over a
window ``illumination_window`` times the target's size, cancels such an offset while keeping
the target's contrast against its surroundings, which a patch centred on its own mean loses
(``patch_normalization = 'centred'`` lost 0.09 on the 36 development targets, round 17).
Measured on the development set: docs/findings/round-19-illumination-lost-scale.md.
"""
from __future__ import annotations

import cv2
import numpy as np


def remove_local_mean(frame: np.ndarray, window: float, target_size: float) -> np.ndarray:
    """``frame`` minus its mean over a square box of side ``window * target_size`` pixels.

    Parameters
    ----------
    frame : (H, W) float32
    window : float
        The box's side in multiples of ``target_size`` (> 0).
    target_size : float
        The target's size in pixels (the geometric mean of its width and height).

    Returns
    -------
    (H, W) float32
    """
    side = max(3, int(round(window * target_size)) | 1)  # odd, so the box is centred on its pixel
    # BORDER_REFLECT: a replicated border would weigh the edge pixels' brightness too heavily.
    local_mean = cv2.blur(frame, (side, side), borderType=cv2.BORDER_REFLECT)
    return np.ascontiguousarray(frame - local_mean)
