"""What an expert sees (*ours*; ``eyes = 'gray'`` is the paper): the vector each candidate is coded
as.

- 'gray': the paper's unit-norm gray patch (:func:`nrmlc.kernels.warp.warp_patches`);
- 'gradient': the gradient-orientation cells of that patch (:mod:`nrmlc.kernels.gradient_cells`),
  which keep the target's edges and drop its level and most of its shading;
- 'colour': the gray patch beside the two opponent-colour planes ``(R - G) / sqrt 2`` and
  ``(R + G - 2B) / sqrt 6`` at half the side (colour varies slowly), each plane unit-norm and the
  whole scaled by ``1 / sqrt 3``; on a gray video the colour planes are flat and the expert sees
  the gray patch.

An expert codes its candidates on its own templates, sampled in its own eyes, exactly as the
paper codes gray patches. Its reconstruction errors live in its own space; each eye's errors are
divided by :data:`ERROR_SCALE` so that every threshold on eps_pos* (the update gate, re-detection,
the pair's choice) reads in the gray patch's units. The generative term models gray local
patches, so only a gray expert has one.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from nrmlc.geometry import state_to_affine
from nrmlc.kernels.gradient_cells import gradient_cells
from nrmlc.kernels.warp import warp_patches
from nrmlc.tracker.parameter_fields import CheckedParams, fail

#: How much larger each eye's eps_pos* is than the gray patch's on the same frames: the ratio of
#: their medians for the true box on development half A's colour videos, coded on the first
#: frame's templates over the first 20 frames, where the gray patch's median (0.088) is nearest
#: the update gate (0.1) (``python -m experiments.development.eye_scales``,
#: ``figures/development/eye_scales.json``). The ratio is not one constant: it is larger where the
#: errors are smaller, so it is read where the thresholds act.
ERROR_SCALE = {"gray": 1.0, "gradient": 4.6, "colour": 2.6}


@dataclass(frozen=True)
class EyesParams(CheckedParams):
    """What one expert sees.

    Attributes
    ----------
    eyes : {'gray', 'gradient', 'colour'}
        The vector each candidate and template is: 'gray', the unit-norm gray patch (the paper);
        'gradient', its gradient-orientation cells; 'colour', the gray patch and two
        opponent-colour planes (:mod:`nrmlc.tracker.eyes`).
    """

    eyes: Literal["gray", "gradient", "colour"] = "gray"

    def check_group(self) -> None:
        from nrmlc.kernels.gradient_cells import CELL_SIZE

        if self.eyes == "gradient" and self.patch_size % CELL_SIZE:
            fail("patch_size", f"must be a multiple of {CELL_SIZE} (the gradient cells) when eyes='gradient', "
                               f"got {self.patch_size}")
        if self.eyes == "colour" and self.patch_size < 4:
            fail("patch_size", f"must be at least 4 (the colour planes' half side) when eyes='colour', "
                               f"got {self.patch_size}")


def opponent_planes(image) -> np.ndarray | None:
    """The two opponent-colour planes of a colour ``image`` (BGR or BGRA numpy, or a PIL image,
    which is RGB): (2, height, width) float32, in the units of the gray frame
    (:func:`nrmlc.data.image.to_gray_float32`); None for a gray image."""
    if type(image).__module__.startswith("PIL."):
        if image.mode in ("L", "LA", "I;16", "I", "F"):
            return None
        image = np.asarray(image.convert("RGB"))[:, :, ::-1]
    if image.ndim != 3 or image.shape[2] < 3:
        return None
    scale = {np.dtype(np.uint8): 1.0 / 255.0, np.dtype(np.uint16): 1.0 / 65535.0}.get(image.dtype, 1.0)
    blue, green, red = (image[:, :, c].astype(np.float32) * np.float32(scale) for c in range(3))
    return np.stack([(red - green) * np.float32(1 / np.sqrt(2.0)),
                     (red + green - 2 * blue) * np.float32(1 / np.sqrt(6.0))])


def seen(frame: np.ndarray, states: np.ndarray, patch_size: int, eyes: str,
         colour: np.ndarray | None = None) -> np.ndarray:
    """The vectors an expert with ``eyes`` codes for ``states`` (n, 6) in ``frame``.

    Parameters
    ----------
    frame : (height, width) float32
        The gray frame.
    states : (n, 6) float64
    patch_size : int
    eyes : {'gray', 'gradient', 'colour'}
    colour : (2, height, width) float32, optional
        :func:`opponent_planes` of the frame ('colour'; None: a gray video).

    Returns
    -------
    vectors : (n, d) float32
        Unit rows: d = ``patch_size**2`` ('gray'), ``(patch_size // 4)**2 * 9`` ('gradient'),
        ``patch_size**2 + 2 * (patch_size // 2)**2`` ('colour').
    """
    affines = np.ascontiguousarray(state_to_affine(states))
    patches = warp_patches(frame, affines, patch_size)
    if eyes == "gradient":
        return gradient_cells(patches, patch_size)
    if eyes == "colour":
        side = patch_size // 2
        if colour is None:
            chroma = np.full((len(states), 2 * side * side), 1.0 / side, dtype=np.float32)
        else:
            # The same box on a grid of half the side: the grid's steps twice as long.
            coarse = affines.copy()
            coarse[:, :, :2] *= (patch_size - 1) / (side - 1)
            chroma = np.hstack([warp_patches(np.ascontiguousarray(plane), coarse, side) for plane in colour])
        return np.hstack([patches, chroma]) * np.float32(1 / np.sqrt(3.0))
    return patches
