"""Brightness levelling (*ours*; ``brightness = 'raw'`` is the paper): every frame is shifted by
one constant so that its mean gray is the first frame's.

A camera's exposure moves every pixel's level together; the unit-norm patch cancels a gain but
not an offset, and an offset turns the target away from its positives. It plugs into
:meth:`nrmlc.tracker.algorithm.NRMLCTracker.update` where a frame comes in. Evidence:
docs/DEVIATIONS.md.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from nrmlc.tracker.parameter_fields import CheckedParams


@dataclass(frozen=True)
class BrightnessParams(CheckedParams):
    """Brightness levelling's parameter.

    Attributes
    ----------
    brightness : {'first_frame', 'raw'}
        'first_frame': each frame's mean gray moved to the first frame's; 'raw' (the paper): the
        gray frame as it comes.
    """

    brightness: Literal["first_frame", "raw"] = "first_frame"


def levelled(frame: np.ndarray, first_frame_mean: float, params: BrightnessParams) -> np.ndarray:
    """``frame`` (height, width) float32 with its mean gray moved to ``first_frame_mean`` under
    ``brightness = 'first_frame'``; as it is otherwise."""
    if params.brightness == "raw":
        return frame
    return frame + np.float32(first_frame_mean - frame.mean(dtype=np.float64))
