"""The checks of the lineage trackers' parameter groups, each a one-line :class:`ParameterError`
naming ``<Group>.<field>`` and the value given."""
from __future__ import annotations

import dataclasses

import numpy as np

from nrmlc.errors import ParameterError
from nrmlc.tracker.parameter_fields import bounded

__all__ = ["LineageParams", "bounded"]


class LineageParams:
    """Base of the lineage's frozen parameter groups: every field declared with
    :func:`~nrmlc.tracker.parameter_fields.bounded` is checked on construction (an ``int`` field
    with :func:`check_integer`, any other with :func:`check_real`), then the group's
    ``check_group`` checks what the bounds cannot (tuples, fields tied to each other)."""

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            meta = field.metadata
            if "low" not in meta:
                continue
            if field.type in ("int", int):
                check_integer(self, field.name, meta["low"], meta["high"])
            else:
                check_real(self, field.name, meta["low"], meta["high"], low_open=meta["low_open"])
        self.check_group()

    def check_group(self) -> None:
        """The checks that bounds on single fields cannot state (none here)."""


def _where(params, name: str) -> str:
    return f"{type(params).__name__}.{name}"


def _is_integer(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _is_real(value) -> bool:
    return isinstance(value, (int, float, np.number)) and not isinstance(value, bool) and bool(np.isfinite(value))


def check_integer(params, name: str, low: int, high: int) -> None:
    """``params.<name>`` is an integer in ``low..high``."""
    value = getattr(params, name)
    if not (_is_integer(value) and low <= value <= high):
        raise ParameterError(f"{_where(params, name)} must be an integer in {low}..{high}, got {value!r}")


def check_real(params, name: str, low: float, high: float, low_open: bool = False) -> None:
    """``params.<name>`` is a finite number in ``[low, high]`` (``(low, high]`` with ``low_open``)."""
    value = getattr(params, name)
    if not (_is_real(value) and (low < value if low_open else low <= value) and value <= high):
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}]"
        raise ParameterError(f"{_where(params, name)} must be in {interval}, got {value!r}")


def check_template_size(params, name: str = "template_size") -> None:
    """``params.<name>`` is 2 integers (rows, columns) in ``2..256``."""
    size = getattr(params, name)
    if not (isinstance(size, (tuple, list)) and len(size) == 2 and all(_is_integer(v) and 2 <= v <= 256 for v in size)):
        raise ParameterError(f"{_where(params, name)} must be 2 integers in 2..256, got {size!r}")


def check_affine_sigma(params, name: str = "affine_sigma") -> None:
    """``params.<name>`` is the 6 deviations of the particles' affine noise, each in ``[0, 1e4)``."""
    sigma = getattr(params, name)
    if not (isinstance(sigma, (tuple, list)) and len(sigma) == 6 and all(_is_real(s) and 0 <= s < 1e4 for s in sigma)):
        raise ParameterError(f"{_where(params, name)} must be 6 numbers in [0, 1e4), got {sigma!r}")


def check_targets_and_signals(targets, signals) -> tuple[int, int]:
    """The solvers' common inputs: ``targets`` (k, N) and ``signals`` (n, N), float64, finite, with
    at least one atom and one pixel. Returns ``(k, N)``."""
    from nrmlc.kernels.checks import check_array, check_finite

    check_array("targets", targets, np.float64, 2)
    check_array("signals", signals, np.float64, 2)
    k, size = targets.shape
    if k == 0 or size == 0:
        raise ParameterError(f"targets must have at least one atom and one pixel, got shape {targets.shape}")
    if signals.shape[1] != size:
        raise ParameterError(f"signals have {signals.shape[1]} pixels, targets have {size}")
    check_finite("targets", targets)
    check_finite("signals", signals)
    return k, size


def check_weight_cap(params, name: str) -> None:
    """``params.<name>``, ``normalizeWeights.m``'s cap on a template's share of the weights, is in
    ``(0, 1]`` and large enough for ``params.n_templates`` shares to sum to 1."""
    check_real(params, name, 0.0, 1.0, low_open=True)
    cap = getattr(params, name)
    if cap * params.n_templates < 1.0:
        raise ParameterError(f"{_where(params, name)} times n_templates must be >= 1 (weights sum to 1), "
                             f"got {cap!r} x {params.n_templates}")


def check_patch_arguments(frame, states, name: str, columns: str, template_size, out) -> np.ndarray:
    """The checks of a patch sampler's arguments (:func:`nrmlc.lineage.affine.warp_patches`,
    :func:`nrmlc.lineage.l1apg.crop_patches`): ``frame`` (H, W) and ``states`` (the argument
    ``name``, (n, 6), its columns named ``columns`` in the message) float64, C-contiguous and
    finite. Returns ``out`` when it is a C-contiguous float64 array of shape (n, h, w) for
    ``template_size`` ``(h, w)``, a new one when it is None."""
    from nrmlc.kernels.checks import check_array

    check_array("frame", frame, np.float64, 2)
    if not np.isfinite(frame).all():
        raise ParameterError("frame must be finite")
    check_array(name, states, np.float64, 2)
    if states.shape[1] != 6:
        raise ParameterError(f"{name} must have 6 columns ({columns}), got {states.shape[1]}")
    if not np.isfinite(states).all():
        raise ParameterError(f"{name} must be finite")
    shape = (states.shape[0], *(int(v) for v in template_size))
    if out is None:
        return np.empty(shape, dtype=np.float64)
    if out.shape != shape or out.dtype != np.float64 or not out.flags.c_contiguous:
        raise ParameterError(f"out must be a C-contiguous float64 array of shape {shape}")
    return out
