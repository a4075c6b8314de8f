"""Turning an image array into the float32 gray frame every part of nrmlc works on."""
from __future__ import annotations

import cv2
import numpy as np

_INTEGER_SCALE = {np.dtype(np.uint8): 1.0 / 255.0, np.dtype(np.uint16): 1.0 / 65535.0}


def to_gray_float32(image: np.ndarray) -> np.ndarray:
    """A gray, gray+alpha, BGR or BGRA image as a C-contiguous float32 gray frame.

    uint8 is divided by 255 and uint16 by 65535 (so the frame is in [0, 1]);
    other numeric types keep their values. Colour is converted with OpenCV's
    luma weights in float, after the scaling, so no precision is lost to
    integer rounding; integer inputs are clipped to [0, 1] afterwards because
    float rounding of the weights can overshoot 1 slightly. A float32 gray
    image is returned without a copy when it is already C-contiguous.

    Parameters
    ----------
    image : (H, W), (H, W, 1), (H, W, 2), (H, W, 3) or (H, W, 4) numeric array
        The caller checks the dtype and shape (see ``Sequence.raw_frame`` and
        ``nrmlc.tracker.nrmlc_tracker.as_gray_frame``).

    Returns
    -------
    frame : (H, W) float32
    """
    if image.ndim == 3 and image.shape[2] in (1, 2):  # gray, or gray + alpha (the alpha is of no use)
        image = image[:, :, 0]
    scale = _INTEGER_SCALE.get(image.dtype)
    gray = image.astype(np.float32, copy=False)
    if scale is not None:
        gray = gray * np.float32(scale)
    if gray.ndim == 3:
        code = cv2.COLOR_BGR2GRAY if gray.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        gray = cv2.cvtColor(np.ascontiguousarray(gray), code)
        if scale is not None:
            np.clip(gray, 0.0, 1.0, out=gray)
    return np.ascontiguousarray(gray)
