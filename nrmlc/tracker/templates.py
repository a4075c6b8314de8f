"""Sampling template states around a target (Sec. 3 of the paper)."""
from __future__ import annotations

import numpy as np

from nrmlc.geometry import state_to_affine


def offsets_in_annulus(rng: np.random.Generator, n: int, inner: float, outer: float) -> np.ndarray:
    """Points uniformly distributed (by area) in the annulus inner <= d < outer.

    Returns
    -------
    offsets : (n, 2) float64
        ``(du, dv)`` in template pixels.
    """
    radius = np.sqrt(rng.uniform(inner**2, outer**2, size=n))
    angle = rng.uniform(0.0, 2 * np.pi, size=n)
    return np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)


def shifted_states(state: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """States of the target moved by template-grid offsets.

    An offset ``(du, dv)`` is measured on the target's own template grid, so it is
    mapped into the image by the target's 2x2 warp: the shift follows the target's
    size, aspect and rotation.

    Parameters
    ----------
    state : (6,) float64
    offsets : (n, 2) float64

    Returns
    -------
    states : (n, 6) float64
    """
    linear = state_to_affine(state)[:, :2]
    states = np.tile(state, (len(offsets), 1))
    states[:, :2] += offsets @ linear.T
    return states


def positive_states(rng: np.random.Generator, state: np.ndarray, n: int, radius: float) -> np.ndarray:
    """The target itself plus ``n - 1`` states whose centres lie within ``radius``.

    Returns
    -------
    states : (n, 6) float64
    """
    offsets = np.vstack([np.zeros((1, 2)), offsets_in_annulus(rng, n - 1, 0.0, radius)])
    return shifted_states(state, offsets)


def negative_states(rng: np.random.Generator, state: np.ndarray, n: int, inner: float, outer: float) -> np.ndarray:
    """``n`` states whose centres lie in the annulus ``inner < d < outer``.

    Returns
    -------
    states : (n, 6) float64
    """
    return shifted_states(state, offsets_in_annulus(rng, n, inner, outer))
