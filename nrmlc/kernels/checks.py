"""Input checks shared by the kernels' public wrappers.

Compiled kernels trust their inputs (wrong dtype or layout means a silent
recompile, a copy, or garbage), so every public wrapper checks them first and
raises a one-line :class:`~nrmlc.errors.ParameterError` naming the argument.
"""
from __future__ import annotations

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
