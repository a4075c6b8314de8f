"""Checked, frozen parameter groups: each field declares its kind by its annotation (``int``,
``float``, ``bool``, ``tuple`` or a ``Literal`` of its choices) and its range beside its default
(:func:`bounded`); one generic loop coerces and checks every field of every group.

The paper's group lives in :mod:`nrmlc.tracker.params`; each addition's group lives in the
addition's own module, and :class:`nrmlc.tracker.params.TrackerParams` joins them.
"""
from __future__ import annotations

import dataclasses
import math
import sys
import typing
from typing import Literal

import numpy as np

from nrmlc.errors import ParameterError


def bounded(default, low=None, high=None, *, low_open: bool = False, high_open: bool = False):
    """A field with ``default`` whose value must lie between ``low`` and ``high`` (None: no bound;
    ``*_open``: the bound itself is excluded)."""
    return dataclasses.field(default=default, metadata=dict(low=low, high=high, low_open=low_open,
                                                            high_open=high_open))


def fail(name: str, message: str) -> None:
    """Refuse parameter ``name`` with a one-line :class:`ParameterError`."""
    raise ParameterError(f"parameter {name}: {message}")


class CheckedParams:
    """Base of every parameter group: on construction each field is coerced to its kind and
    range-checked, then each group's ``check_group`` (the checks that tie its fields together)
    runs."""

    def __post_init__(self) -> None:
        kinds = field_kinds(type(self))
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _coerce(f, kinds[f.name], getattr(self, f.name)))
        for group in reversed(type(self).__mro__):
            check = group.__dict__.get("check_group")
            if check is not None:
                check(self)


def field_kinds(cls) -> dict:
    """Each field's annotation of ``cls``, resolved (``int``, ``float``, ``bool``, ``tuple[...]``,
    ``Literal[...]``); the groups' annotations live in their own modules."""
    kinds = {}
    for base in reversed(cls.__mro__):
        if dataclasses.is_dataclass(base):
            namespace = vars(sys.modules[base.__module__])
            kinds.update(typing.get_type_hints(base, globalns=namespace))
    return kinds


def range_text(field: dataclasses.Field, kind) -> str:
    """The values ``field`` accepts, for messages and ``nrmlc params``: '1..100000', '(0, 1]',
    '>= 0', 'regularized | constrained | plain', 'True | False', '6 numbers', or '' (any)."""
    if typing.get_origin(kind) is Literal:
        return " | ".join(typing.get_args(kind))
    if kind is bool:
        return "True | False"
    if typing.get_origin(kind) is tuple:
        return "integers" if typing.get_args(kind)[0] is int else "numbers"
    meta = field.metadata
    low, high = meta.get("low"), meta.get("high")
    if low is not None and high is not None:
        if kind is int:
            return f"{low}..{high}"
        return f"{'(' if meta['low_open'] else '['}{low:g}, {high:g}{')' if meta['high_open'] else ']'}"
    if low is not None:
        return f"{'>' if meta['low_open'] else '>='} {low:g}"
    if high is not None:
        return f"{'<' if meta['high_open'] else '<='} {high:g}"
    return ""


def _coerce(field: dataclasses.Field, kind, value):
    """``value`` as the plain Python value of ``field``'s kind, range-checked from its metadata.

    numpy scalars become the Python numbers they equal (so that they give the same cache keys),
    sequences become tuples (hashable), and a float where an integer is needed is refused, never
    truncated.
    """
    name = field.name
    if typing.get_origin(kind) is Literal:
        choices = typing.get_args(kind)
        if not isinstance(value, str) or value not in choices:
            noun = {"coding": "mode", "confidence": "form"}.get(name, "value")
            fail(name, f"unknown {noun} {value!r}; choose one of {', '.join(choices)}")
        return value
    if kind is bool:
        if isinstance(value, np.bool_):
            value = bool(value)
        if not isinstance(value, bool):
            fail(name, f"must be True or False, got {value!r}")
        return value
    if typing.get_origin(kind) is tuple:
        integral = typing.get_args(kind)[0] is int
        if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__iter__"):
            fail(name, f"must be a sequence of numbers, got {value!r}")
        values = tuple(value)
        numbers = (int, np.integer) if integral else (int, float, np.integer, np.floating)
        if any(isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers) for v in values):
            fail(name, f"must be a sequence of {'integers' if integral else 'numbers'}, got {values!r}")
        return tuple(int(v) if integral else float(v) for v in values)
    if kind is int:
        if isinstance(value, np.integer):
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            fail(name, f"must be an integer, got {value!r}")
    else:
        if isinstance(value, (np.integer, np.floating)) and not isinstance(value, np.bool_):
            value = value.item()
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            fail(name, f"must be a finite number, got {value!r}")
    _check_range(field, kind, value)
    return value


def _check_range(field: dataclasses.Field, kind, value) -> None:
    meta = field.metadata
    low, high = meta.get("low"), meta.get("high")
    below = low is not None and (value <= low if meta["low_open"] else value < low)
    above = high is not None and (value >= high if meta["high_open"] else value > high)
    if below or above:
        both = low is not None and high is not None
        fail(field.name, f"must be {'in ' if both else ''}{range_text(field, kind)}, got {value}")
