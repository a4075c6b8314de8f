"""The motion floor (*ours*; ``translation_floor = 0`` is the paper): under relative translation
noise, the per-frame translation std is at least ``translation_floor`` image pixels.

Relative noise (L1APG's ``draw_sample``) scales the translation with the target: a small
target's 2 template px are fewer pixels than a fast step. The floor is the lineage's fixed noise
(IVT's and SCM's ``affsig`` [4, 4, ...]); a large target's noise stays its own. It plugs into the
motion model (:meth:`nrmlc.tracker.algorithm.NRMLCTracker.diffuse`). Evidence: docs/DEVIATIONS.md.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nrmlc.tracker.parameter_fields import CheckedParams, bounded

#: The largest per-frame translation std, in image or template pixels.
MAX_TRANSLATION_SIGMA = 1000.0


@dataclass(frozen=True)
class MotionFloorParams(CheckedParams):
    """The motion floor's parameter.

    Attributes
    ----------
    translation_floor : float
        Under ``translation_noise = 'relative'``, the translation std's least value in image
        pixels on an axis whose ``motion_sigmas`` entry is not 0 (0: no floor, the paper).
    """

    translation_floor: float = bounded(4.0, 0, MAX_TRANSLATION_SIGMA)


def translation_sigmas(params, sizes: np.ndarray) -> np.ndarray:
    """The per-frame translation noise's std in image pixels, (n, 2) for the x and y axes, of
    targets whose template pixel is ``sizes`` (n,) image pixels.

    Parameters
    ----------
    params : nrmlc.tracker.params.TrackerParams
        Its ``motion_sigmas``, ``translation_noise`` and ``translation_floor``.
    sizes : (n,) float64
    """
    sigmas = np.asarray(params.motion_sigmas[0:2], dtype=np.float64)
    sizes = np.asarray(sizes, dtype=np.float64)
    if params.translation_noise != "relative":
        return np.broadcast_to(sigmas, (len(sizes), 2)).copy()
    scaled = sigmas * sizes[:, None]
    if params.translation_floor > 0:
        # An axis without translation noise keeps none: the floor lifts noise, it adds none.
        scaled = np.where(sigmas > 0, np.maximum(scaled, params.translation_floor), 0.0)
    return scaled
