"""What an expert sees (*ours*; ``eyes = 'gray'`` is the paper): the vector each candidate is coded
as.

- 'gray': the paper's unit-norm gray patch (:func:`nrmlc.kernels.warp.warp_patches`);
- 'gradient': the gradient-orientation cells of that patch (:mod:`nrmlc.kernels.gradient_cells`),
  which keep the target's edges and drop its level and most of its shading.

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
from nrmlc.kernels.gradient_cells import CELL_SIZE, gradient_cells
from nrmlc.kernels.warp import warp_patches
from nrmlc.tracker.parameter_fields import CheckedParams, fail

#: How much larger each eye's eps_pos* is than the gray patch's on the same frames: the ratio of
#: their medians for the true box on development half A's videos stored in colour, coded on the
#: first frame's templates over the first 20 frames, where the gray patch's median (0.088) is nearest
#: the update gate (0.1) (``python -m experiments.development.eye_scales``,
#: ``figures/development/eye_scales.json``). The ratio is not one constant: it is larger where the
#: errors are smaller, so it is read where the thresholds act.
ERROR_SCALE = {"gray": 1.0, "gradient": 4.6}


@dataclass(frozen=True)
class EyesParams(CheckedParams):
    """What one expert sees.

    Attributes
    ----------
    eyes : {'gray', 'gradient'}
        The vector each candidate and template is: 'gray', the unit-norm gray patch (the paper);
        'gradient', its gradient-orientation cells (:mod:`nrmlc.tracker.eyes`).
    """

    eyes: Literal["gray", "gradient"] = "gray"

    def check_group(self) -> None:
        if self.eyes == "gradient" and self.patch_size % CELL_SIZE:
            fail("patch_size", f"must be a multiple of {CELL_SIZE} (the gradient cells) when eyes='gradient', "
                               f"got {self.patch_size}")


def seen(frame: np.ndarray, states: np.ndarray, patch_size: int, eyes: str) -> np.ndarray:
    """The vectors an expert with ``eyes`` codes for ``states`` (n, 6) in ``frame`` (height, width)
    float32: (n, d) float32 unit rows, d = ``patch_size**2`` ('gray') or ``(patch_size // 4)**2 * 9``
    ('gradient')."""
    return seen_by_each(frame, [states], patch_size, [eyes])[0]


def seen_by_each(frame: np.ndarray, states: list, patch_size: int, eyes: list) -> list:
    """:func:`seen` for several experts' particles in one frame, with one warp over all of them
    and one gradient pass over those of every gradient expert: each particle's vector is the
    same as alone (every kernel treats each particle on its own), and the kernels' threads meet
    once per stage instead of once per expert.

    Parameters
    ----------
    frame : (height, width) float32
    states : list of (n_i, 6) float64
        Each expert's particles.
    patch_size : int
    eyes : list of str
        Each expert's eyes.

    Returns
    -------
    list of (n_i, d_i) float32
        What each expert codes.
    """
    bounds = np.cumsum([0] + [len(part) for part in states])
    patches = warp_patches(frame, np.ascontiguousarray(state_to_affine(np.vstack(states))), patch_size)
    seen_parts = [patches[bounds[i]:bounds[i + 1]] for i in range(len(states))]
    gradient = [i for i, name in enumerate(eyes) if name == "gradient"]
    if gradient:
        cells = gradient_cells(np.vstack([seen_parts[i] for i in gradient]), patch_size)
        cell_bounds = np.cumsum([0] + [len(seen_parts[i]) for i in gradient])
        for j, i in enumerate(gradient):
            seen_parts[i] = cells[cell_bounds[j]:cell_bounds[j + 1]]
    return seen_parts
