"""Input checks shared by the kernels' public wrappers.

Compiled kernels trust their inputs (wrong dtype or layout means a silent
recompile, a copy, or garbage), so every public wrapper checks them first and
raises a one-line :class:`~nrmlc.errors.ParameterError` naming the argument.
"""
from __future__ import annotations

import numbers

import numpy as np

from nrmlc.errors import ParameterError


def check_array(name: str, array, dtypes, ndim: int) -> None:
    """Raise ParameterError unless ``array`` is a C-contiguous ndarray of an allowed dtype and ndim.

    Parameters
    ----------
    name : str
        Argument name used in the message.
    array : object
    dtypes : dtype or tuple of dtypes
    ndim : int
    """
    allowed = tuple(np.dtype(d) for d in (dtypes if isinstance(dtypes, (tuple, list)) else (dtypes,)))
    if not isinstance(array, np.ndarray):
        raise ParameterError(f"{name} must be a numpy array, got {type(array).__name__}")
    if array.dtype not in allowed:
        names = " or ".join(str(d) for d in allowed)
        raise ParameterError(f"{name} must have dtype {names}, got {array.dtype}")
    if array.ndim != ndim:
        raise ParameterError(f"{name} must be {ndim}-D, got shape {array.shape}")
    if not array.flags.c_contiguous:
        raise ParameterError(f"{name} must be C-contiguous")


def check_length(name: str, array: np.ndarray, expected: int, reference: str) -> None:
    """Raise ParameterError unless ``array`` has ``expected`` rows (entries, if 1-D).

    Parameters
    ----------
    name : str
        Argument name used in the message.
    array : ndarray
    expected : int
    reference : str
        What fixes ``expected``, e.g. ``"dots has 600 rows"``.
    """
    if array.shape[0] != expected:
        unit = "entries" if array.ndim == 1 else "rows"
        raise ParameterError(f"{name} has {array.shape[0]} {unit}, {reference}")


def check_int(name: str, value, minimum: int, maximum: int | None = None) -> int:
    """Return ``value`` as an int, or raise ParameterError unless it is an integer in ``[minimum, maximum]``.

    Parameters
    ----------
    name : str
        Argument name used in the message.
    value : object
    minimum : int
    maximum : int, optional
        No upper bound when None.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise ParameterError(f"{name} must be an integer, got {value!r}")
    value = int(value)
    if value < minimum or (maximum is not None and value > maximum):
        upper = "" if maximum is None else f", <= {maximum}"
        raise ParameterError(f"{name} must be >= {minimum}{upper}, got {value}")
    return value


def check_nonnegative_real(name: str, value) -> float:
    """Return ``value`` as a float, or raise ParameterError unless it is a finite real number >= 0."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    if not (np.isfinite(value) and value >= 0.0):
        raise ParameterError(f"{name} must be finite and >= 0, got {value}")
    return value


def check_flag(name: str, value) -> bool:
    """Return ``value`` as a bool, or raise ParameterError unless it is a (numpy) bool."""
    if not isinstance(value, (bool, np.bool_)):
        raise ParameterError(f"{name} must be a bool, got {value!r}")
    return bool(value)


def check_finite(name: str, array: np.ndarray) -> None:
    """Raise ParameterError if ``array`` holds NaN or infinite values."""
    if not np.all(np.isfinite(array)):
        raise ParameterError(f"{name} contains NaN or infinite values")


def check_indices(name: str, indices: np.ndarray, upper: int) -> None:
    """Raise ParameterError unless every entry of ``indices`` lies in ``[0, upper)``.

    Compiled kernels index with them unchecked, so an entry out of range would read
    outside the indexed array.
    """
    if indices.size and (indices.min() < 0 or indices.max() >= upper):
        raise ParameterError(f"{name} must lie in [0, {upper})")
