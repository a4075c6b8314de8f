"""The jobs a run cache computes, and how each is keyed.

A *job* is anything with

- ``key(version) -> str`` and ``description(version) -> dict``: what identifies
  it (``version`` is :func:`nrmlc.workbench.version.code_version`; a job whose result does not
  depend on our sources may ignore it);
- ``frames() -> int``: how many frames it tracks (for progress and estimates);
- ``execute() -> dict`` of numpy arrays: the work, run in a worker process;
- ``result(arrays)``: the object callers get back from the stored arrays;
- optionally ``problem(arrays) -> str | None``: why stored arrays are not a
  finished result of this job (missing arrays, fewer boxes than frames), or
  None; such a file is recomputed with a warning naming it;
- ``folder``: a sub-folder of the cache ("" for tracking runs);
- ``label``: free text for progress lines.

:class:`Job` states this contract as a :class:`typing.Protocol`; :class:`CachedJob` is the base
class the jobs share (the key from the description, the frame count from the sequence and the
job's frame cap); :class:`TrackerJob` adds the fields of a job that runs our tracker (sequence,
parameters, seed) and its label from a template.

:class:`RunSpec` (one tracking run) is the main one; the experiments add live OpenCV peer runs
and recorded tracker internals. A job's key is a hash of its description
(:func:`description_key`), so changing one parameter changes the key of exactly the runs that
use it, and a sequence is keyed by the content of its frames and ground truth
(:attr:`nrmlc.data.Sequence.identity`), not by its path or name.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from nrmlc.errors import ParameterError
from nrmlc.tracker.loop import TrackResult, track_sequence
from nrmlc.tracker.params import TrackerParams


def sequence_identity(sequence) -> str:
    """A string naming the sequence's content: :attr:`nrmlc.data.Sequence.identity`
    (a digest of its frames' bytes and its ground truth, or its synthetic spec, plus an
    overridden initial box)."""
    return sequence.identity


def _count(what: str, value, low: int) -> int:
    """``value`` as a Python int >= ``low``; a float, bool or anything else is refused, never truncated."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ParameterError(f"{what} must be an integer >= {low}, got {value!r}")
    return int(value)


def _real(array) -> bool:
    """Whether ``array`` holds real numbers (integers or floats, not text, objects or booleans)."""
    return np.asarray(array).dtype.kind in "iuf"


def tracking_problem(arrays: dict, n: int, columns: dict[str, int]) -> str | None:
    """Why stored ``arrays`` are not a finished tracking run of ``n`` frames (None: they are): each
    array of ``columns`` (name -> columns) real and of shape ``(n, columns)``, finite boxes, and
    both times a number of seconds."""
    for name, width in columns.items():
        if name not in arrays:
            return f"no {name!r} array"
        shape = np.shape(arrays[name])
        if shape != (n, width):
            return f"{name!r} has shape {shape}, expected ({n}, {width}) for {n} frames"
        if not _real(arrays[name]):
            return f"{name!r} holds {np.asarray(arrays[name]).dtype} values, not numbers"
    if not np.isfinite(arrays["boxes"]).all():
        return "non-finite boxes"
    for name in ("seconds_tracking", "seconds_total"):
        if name not in arrays or np.shape(arrays[name]) != ():
            return f"no {name!r} value"
        # A run's times are what its fps is computed from: a number of seconds, >= 0.
        if not _real(arrays[name]) or not np.isfinite(arrays[name]) or arrays[name] < 0:
            return f"{name!r} is {np.asarray(arrays[name]).tolist()!r}, not a number of seconds"
    return None


def frames_tracked(sequence, n_frames: int | None) -> int:
    """Frames a run over ``sequence`` tracks: all of them, or the first ``n_frames`` (at least 1).

    The one rule for every kind of job (tracking runs, peer runs, recorded internals).
    """
    n = len(sequence)
    return n if n_frames is None else max(1, min(n, int(n_frames)))


#: Part of every run's key: bumped when what a key holds changes meaning without a change of the
#: code (the code version keys that).
CACHE_EPOCH = 1


def params_for_key(params: TrackerParams) -> dict:
    """The parameters as a run's key holds them: every field by name."""
    return params.as_dict()


def description_key(description: dict) -> str:
    """The cache key of a job: a hash of its JSON description (keys sorted)."""
    text = json.dumps(description, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


@runtime_checkable
class Job(Protocol):
    """What :class:`nrmlc.workbench.run_cache.RunCache` needs of a job (module docstring)."""

    folder: ClassVar[str]
    uses_kernels: ClassVar[bool]

    @property
    def label(self) -> str: ...

    def description(self, version: str) -> dict: ...

    def key(self, version: str) -> str: ...

    def frames(self) -> int: ...

    def execute(self) -> dict: ...

    def result(self, arrays: dict): ...


class CachedJob:
    """The part every job over one sequence shares: its key is the hash of its description, it
    tracks the first :meth:`frame_cap` frames of ``self.sequence``, and its result is the arrays."""

    folder: ClassVar[str] = ""
    #: Runs the numba kernels (so workers load them before timing anything).
    uses_kernels: ClassVar[bool] = True

    def frame_cap(self) -> int | None:
        """Frames to track at most (None: all); ``self.n_frames`` unless a job says otherwise."""
        return self.n_frames

    def frames(self) -> int:
        return frames_tracked(self.sequence, self.frame_cap())

    def key(self, version: str) -> str:
        return description_key(self.description(version))

    def result(self, arrays: dict):
        return dict(arrays)


@dataclass(frozen=True)
class TrackerJob(CachedJob):
    """A :class:`CachedJob` that runs our tracker over one sequence: its first fields are the
    sequence, the parameters and the seed (a job adds its own after them), and its progress
    line, :attr:`label`, is :attr:`label_template` filled in with the job."""

    sequence: object
    params: TrackerParams
    seed: int

    #: ``str.format``-ed with ``job=self``, e.g. ``"internals of {job.sequence.name}"``.
    label_template: ClassVar[str] = "{job.sequence.name}"

    @property
    def label(self) -> str:
        return self.label_template.format(job=self)

    def tracker_description(self, version: str, **own) -> dict:
        """What keys a run of the tracker: the sequence's content, the parameters as a key holds
        them (:func:`params_for_key`), the seed and the code version, with the job's ``own``
        entries (a job's :meth:`description` returns this)."""
        return {"sequence": sequence_identity(self.sequence), "params": params_for_key(self.params),
                "seed": int(self.seed), **own, "code_version": version, "epoch": CACHE_EPOCH}


@dataclass(frozen=True)
class RunSpec(CachedJob):
    """One tracking run: what to track and how.

    Attributes
    ----------
    sequence : nrmlc.data.Sequence
    params : TrackerParams
    seed : int
    n_frames : int or None
        Track only the first frames (None: all).
    label : str
        Free text for progress lines and reports (not part of the key).
    """

    sequence: object
    params: TrackerParams = field(default_factory=TrackerParams)
    seed: int = 0
    n_frames: int | None = None
    label: str = ""

    #: Tracking runs live at the top of the cache.
    folder: ClassVar[str] = ""

    def description(self, version: str) -> dict:
        # It decides the key of every cached run (tests/test_runner.py pins one).
        return {"sequence": sequence_identity(self.sequence), "sequence_name": self.sequence.name,
                "params": params_for_key(self.params), "seed": self.seed, "n_frames": self.n_frames,
                "code_version": version, "epoch": CACHE_EPOCH}

    def __post_init__(self) -> None:
        if not isinstance(self.params, TrackerParams):
            raise ParameterError(f"RunSpec: params must be a TrackerParams, got {type(self.params).__name__} "
                                 f"(TrackerParams(**values) makes one from a dict)")
        object.__setattr__(self, "seed", _count("RunSpec: seed", self.seed, 0))
        if self.n_frames is not None:
            object.__setattr__(self, "n_frames", _count("RunSpec: n_frames", self.n_frames, 1))

    def problem(self, arrays: dict) -> str | None:
        """Why ``arrays`` are not a finished run of this spec (None: they are)."""
        return tracking_problem(arrays, self.frames(), {"boxes": 4, "states": 6})

    def execute(self) -> dict:
        return track_sequence(self.sequence, self.params, seed=self.seed, n_frames=self.n_frames).to_arrays()

    def result(self, arrays: dict) -> TrackResult:
        return TrackResult.from_arrays(arrays)
