"""The checks of the lineage trackers' parameter groups, each a one-line :class:`ParameterError`
naming ``<Group>.<field>`` and the value given."""
from __future__ import annotations

import numpy as np

from nrmlc.errors import ParameterError


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
