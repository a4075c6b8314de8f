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


#: SCM's push-out zones (fractions of the negative std) at initialisation
#: (``affineTrainG.m``: ``back = round(sigma/4)``) and at updates (``updateDic.m``: ``/5``).
SCM_PUSH_INIT = 0.25
SCM_PUSH_UPDATE = 0.2


def target_size(state: np.ndarray, patch_size: int) -> tuple[float, float]:
    """Width and height (image pixels) of the target's template grid, ignoring rotation,
    as SCM measures them (``sz * est(3)`` and ``sz * est(3) * p0``)."""
    return float(patch_size * state[2]), float(patch_size * state[2] * state[4])


def scm_positive_states(rng: np.random.Generator, state: np.ndarray, n: int, sigma: float) -> np.ndarray:
    """``n`` states whose centres are drawn from N(state centre, sigma^2 I) (image pixels),
    as SCM's ``affineTrainG.m`` draws its positive templates (sigma = 1 px there).

    Returns
    -------
    states : (n, 6) float64
    """
    states = np.tile(state, (n, 1))
    states[:, :2] += sigma * rng.standard_normal((n, 2))
    return states


def scm_negative_states(rng: np.random.Generator, state: np.ndarray, n: int, patch_size: int,
                        push: float, clearance=(0.0, 0.0)) -> np.ndarray:
    """``n`` negative template states as SCM draws them (``affineTrainG.m``, ``updateDic.m``).

    Centres are drawn from N(centre, diag(w^2, h^2)) in image pixels; a coordinate that
    falls within ``push * w`` (``push * h``) of the target's is moved out to the edge of
    that zone, on its own side, so no negative is centred on the target. ``clearance``
    (x, y) px widens the zone on each axis (round 44: the target's recent displacement).

    Returns
    -------
    states : (n, 6) float64
    """
    width, height = target_size(state, patch_size)
    states = np.tile(state, (n, 1))
    for axis, sigma in ((0, width), (1, height)):
        offset = sigma * rng.standard_normal(n)
        zone = push * sigma + clearance[axis]
        inside = np.abs(offset) <= zone
        # SCM maps [0, zone] to +zone and [-zone, 0) to -zone.
        offset[inside] = np.where(offset[inside] >= 0, zone, -zone)
        states[:, axis] += offset
    return states
