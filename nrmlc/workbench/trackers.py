"""The trackers ``nrmlc benchmark`` runs, known only by ``init(frame, box)`` / ``update(frame) -> box``.

The benchmark (:func:`nrmlc.workbench.benchmark.run_benchmark`) needs three things of a tracker,
an *entry*:

- ``name``: free text for messages;
- ``settings() -> dict``: JSON that identifies the tracker; it is stored in the results folder's
  ``benchmark.json``, and a folder made with other settings is refused;
- ``job(sequence, seed, n_frames)``: a run-cache job (:class:`nrmlc.workbench.jobs.Job`) that
  tracks ``sequence`` from its first frame, whose ``result(...)`` has ``boxes`` (one 1-based
  ``x, y, w, h`` row per tracked frame) and ``fps_tracking``.

Two entries:

- :class:`NRMLCEntry`: our tracker with given parameters. Its settings are ``{"params": ...}`` and
  its job is :class:`nrmlc.workbench.jobs.RunSpec`, as before entries existed, so result folders
  and run-cache entries made then are still used.
- :class:`ImportedTracker`: ``"package.module:factory"``, any callable returning an object with
  ``init(frame, box)`` and ``update(frame) -> (x, y, w, h)``, as got10k-toolkit's trackers have
  (``nrmlc benchmark DATA --out R --tracker package.module:factory``). It is called as
  ``factory(seed=seed)`` when it has a ``seed`` parameter, else as ``factory()``, once per run.
  Frames are the sequence's colour frames, ``(H, W, 3)`` uint8 in OpenCV's BGR order (gray
  sequences are converted), as OpenCV's and pysot's trackers take them; the box given to ``init``
  and every box ``update`` returns are 1-based OTB boxes. Its runs are :class:`InitUpdateJob`\\ s,
  stored in the run cache's ``imported/`` folder and keyed by the sequence's content, the factory's
  name, the bytes of the file(s) defining it, the seed and the frame cap: editing that file
  recomputes its runs; editing another module it imports does not (use another ``--cache``),
  except for the lineage's trackers, whose keys cover every ``nrmlc`` module they import.
"""
from __future__ import annotations

import hashlib
import importlib
import inspect
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from nrmlc.errors import NrmlcError, ParameterError
from nrmlc.tracker.loop import TrackResult
from nrmlc.tracker.params import TrackerParams
from nrmlc.workbench.jobs import CACHE_EPOCH, CachedJob, RunSpec, _count, sequence_identity, tracking_problem

#: Part of an imported tracker's run key: bumped when :meth:`InitUpdateJob.execute` changes what it
#: gives the tracker or how it times it (our code version is not in these keys: the user's tracker
#: does not depend on it).
RUNNER_VERSION = 2
#: The option :class:`ImportedTracker`'s messages name.
OPTION = "--tracker"
#: What the factory must return, for help texts and messages.
CONTRACT = ("an object with init(frame, box) and update(frame) -> (x, y, w, h); frames are (H, W, 3) "
            "uint8 BGR images, boxes 1-based x, y, w, h")


class TrackerFailed(NrmlcError):
    """An imported tracker raised, or returned something that is not a box (one line naming it and the frame)."""


@runtime_checkable
class TrackerEntry(Protocol):
    """What the benchmark needs of a tracker (module docstring)."""

    name: str

    def settings(self) -> dict: ...

    def job(self, sequence, seed: int, n_frames: int | None): ...


@dataclass(frozen=True)
class NRMLCEntry:
    """NRMLC with ``params``: settings ``{"params": params.as_dict()}``, jobs :class:`RunSpec`."""

    params: TrackerParams = field(default_factory=TrackerParams)
    name: str = "NRMLC"

    def __post_init__(self) -> None:
        if not isinstance(self.params, TrackerParams):
            raise ParameterError(f"run_benchmark: params must be a TrackerParams, got {type(self.params).__name__}")

    def settings(self) -> dict:
        # Exactly what benchmark.json held before entries: such folders still resume.
        return {"params": self.params.as_dict()}

    def job(self, sequence, seed: int, n_frames: int | None) -> RunSpec:
        # The run cache's key of these runs is RunSpec's (tests/test_runner.py pins it).
        return RunSpec(sequence, self.params, seed, n_frames, label=sequence.name)


def _accepts_seed(factory) -> bool:
    try:
        parameters = inspect.signature(factory).parameters
    except (TypeError, ValueError):  # a builtin without a signature
        return False
    seed = parameters.get("seed")
    return seed is not None and seed.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)


def _resolve(spec: str, search_path=()):
    """``(module, factory)`` named by ``spec`` (``package.module:factory``, or
    ``package.module:Class.method``); one :class:`ParameterError` line naming ``--tracker`` otherwise.
    ``search_path`` entries missing from :data:`sys.path` are appended first (a worker process
    imports what its parent could)."""
    where = f"{OPTION} {spec!r}"
    if not isinstance(spec, str):
        raise ParameterError(f"{OPTION}: expected text 'package.module:factory', got {type(spec).__name__}")
    module_name, colon, attribute = spec.partition(":")
    module_name, attribute = module_name.strip(), attribute.strip()
    if not colon or not module_name or not attribute:
        raise ParameterError(f"{where}: expected package.module:factory (the module to import, a colon, "
                             f"and the callable in it that returns the tracker)")
    for entry in search_path:
        if entry not in sys.path:
            sys.path.append(entry)
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and (module_name == exc.name or module_name.startswith(exc.name + ".")):
            raise ParameterError(f"{where}: no module named {exc.name!r} (is its folder on PYTHONPATH, or the "
                                 f"package installed?)") from exc
        raise ParameterError(f"{where}: importing {module_name} failed ({type(exc).__name__}: {exc})") from exc
    except Exception as exc:  # the user's module: any error in it is theirs to see
        raise ParameterError(f"{where}: importing {module_name} failed ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())})") from exc
    factory = module
    for part in attribute.split("."):
        if not part.isidentifier() or not hasattr(factory, part):
            raise ParameterError(f"{where}: module {module_name} has no attribute {attribute!r}")
        factory = getattr(factory, part)
    if not callable(factory):
        raise ParameterError(f"{where}: {attribute} is a {type(factory).__name__}, not a callable "
                             f"that returns the tracker")
    return module, factory


def _make(spec: str, factory, seed: int):
    """The tracker ``factory`` makes for ``seed``, checked to have ``init`` and ``update``."""
    seeded = _accepts_seed(factory)
    call = f"{spec.partition(':')[2]}({'seed=' + str(seed) if seeded else ''})"
    try:
        tracker = factory(seed=seed) if seeded else factory()
    except Exception as exc:
        raise ParameterError(f"{OPTION} {spec!r}: {call} raised {type(exc).__name__}: "
                             f"{' '.join(str(exc).split())}") from exc
    lacking = [name for name in ("init", "update") if not callable(getattr(tracker, name, None))]
    if lacking:
        raise ParameterError(f"{OPTION} {spec!r}: {call} returned a {type(tracker).__name__}, which has no "
                             f"{' and no '.join(n + '()' for n in lacking)} method; it must return {CONTRACT}")
    return tracker


def _source_digest(spec: str, module, factory) -> str:
    """A hash of the file(s) defining ``factory``: the module named and the one the factory is from;
    for the lineage's trackers (:mod:`nrmlc.lineage`), also every module of ``nrmlc`` they import,
    directly or not (:func:`nrmlc_imports`), so that editing a shared part recomputes their runs and
    adding another tracker does not."""
    files = set()
    for owner in (module, inspect.getmodule(factory)):
        path = getattr(owner, "__file__", None)
        if path:
            files.add(str(Path(path).resolve()))
        name = getattr(owner, "__name__", "")
        if name.startswith(LINEAGE_PACKAGE + ".") and path:
            files.update(nrmlc_imports(name))
    if not files:
        raise ParameterError(f"{OPTION} {spec!r}: the module has no source file to key its runs on")
    digest = hashlib.sha256()
    for path in sorted(files):
        try:
            digest.update(Path(path).read_bytes())
        except OSError as exc:
            raise ParameterError(f"{OPTION} {spec!r}: cannot read {path} to key its runs on ({exc})") from None
    return digest.hexdigest()[:24]


def nrmlc_imports(module_name: str) -> set[str]:
    """The source files of ``module_name`` and of every ``nrmlc`` module it imports, directly or
    through other ``nrmlc`` modules (read from their source, imports inside functions included)."""
    import ast
    import importlib.util

    def origin(name):
        try:
            found = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            return None
        return found.origin if found is not None and found.origin and found.origin.endswith(".py") else None

    files, pending, seen = set(), [module_name], set()
    while pending:
        name = pending.pop()
        path = origin(name) if name not in seen else None
        seen.add(name)
        if path is None:
            continue
        files.add(str(Path(path).resolve()))
        for node in ast.walk(ast.parse(Path(path).read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                pending += [alias.name for alias in node.names if alias.name.split(".")[0] == "nrmlc"]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").split(".")[0] == "nrmlc":
                # ``from package import name``: the package, and ``name`` when it is a module of it
                pending += [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
    return files


#: The package of the built-in lineage trackers (``--tracker ivt``).
LINEAGE_PACKAGE = "nrmlc.lineage"


def lineage_name(spec) -> str | None:
    """The lineage tracker ``spec`` names (``"ivt"``, any case), or None when it names none."""
    from nrmlc.lineage import TRACKERS

    if isinstance(spec, str) and ":" not in spec and spec.strip().lower() in TRACKERS:
        return spec.strip().lower()
    return None


class ImportedTracker:
    """A tracker of the user's, ``"package.module:factory"`` (module docstring), or one of the
    lineage's by its short name (``"ivt"``: :data:`nrmlc.lineage.TRACKERS`).

    Checked at once, in one :class:`ParameterError` line naming ``--tracker``: the module is
    imported, the factory found and called once (with ``seed=0`` when it takes a seed), and what
    it returns must have ``init`` and ``update``.
    """

    def __init__(self, spec: str) -> None:
        short = lineage_name(spec)
        if short is not None:
            from nrmlc.lineage import TRACKERS

            spec = TRACKERS[short]
        module, factory = _resolve(spec)
        _make(spec, factory, 0)
        self.spec = spec.strip()
        self.name = short.upper() if short is not None else self.spec
        self.source = _source_digest(spec, module, factory)
        # Where a worker process looks for the module (it may have been found through a sys.path
        # entry this process added).
        self.search_path = tuple(p for p in sys.path if isinstance(p, str))

    def settings(self) -> dict:
        return {"tracker": self.spec}

    def job(self, sequence, seed: int, n_frames: int | None) -> "InitUpdateJob":
        return InitUpdateJob(sequence, self.spec, self.source, seed, n_frames, search_path=self.search_path)

    def __repr__(self) -> str:
        return f"ImportedTracker({self.spec!r})"


def check_box(box, spec: str, sequence, index: int) -> np.ndarray:
    """``box`` as a (4,) float64 array of finite numbers; else :class:`TrackerFailed` naming the tracker and frame."""
    try:
        array = np.asarray(box)
    except Exception:  # noqa: BLE001 - whatever the tracker returned
        array = None
    if array is None or array.shape != (4,) or array.dtype.kind not in "iuf" or not np.isfinite(array).all():
        shown = " ".join(repr(box).split())
        shown = shown if len(shown) <= 80 else shown[:77] + "..."
        raise TrackerFailed(f"{OPTION} {spec}: update() on frame {index + 1} of {sequence.name} returned {shown}, "
                            f"not a box (4 finite numbers x, y, w, h)")
    return array.astype(np.float64)


def track_init_update(spec: str, sequence, seed: int, n_frames: int, init_box=None, on_box=None,
                      search_path=()) -> tuple[np.ndarray, float]:
    """Track ``sequence``'s first ``n_frames`` frames with the tracker ``spec``'s factory makes.

    Parameters
    ----------
    spec : str
        ``package.module:factory``.
    sequence : nrmlc.data.Sequence
    seed : int
    n_frames : int
    init_box : (4,) array_like, optional
        The first box (default: the sequence's).
    on_box : callable(index, box), optional
        Called with each frame's box as it is known (for drawing).
    search_path : tuple of str
        ``sys.path`` entries to add first (:func:`_resolve`).

    Returns
    -------
    boxes : (n_frames, 4) float64
        1-based ``x, y, w, h``; row 0 is the first box.
    seconds : float
        Time spent in ``init`` and ``update``.
    """
    _, factory = _resolve(spec, search_path)
    tracker = _make(spec, factory, seed)
    boxes = np.empty((n_frames, 4), dtype=np.float64)
    boxes[0] = sequence.init_box if init_box is None else init_box
    tracking = 0.0
    for index in range(n_frames):
        frame = sequence.color_frame(index)
        step = "init()" if index == 0 else "update()"
        tick = time.perf_counter()
        try:
            output = tracker.init(frame, boxes[0].copy()) if index == 0 else tracker.update(frame)
        except Exception as exc:
            raise TrackerFailed(f"{OPTION} {spec}: {step} on frame {index + 1} of {sequence.name} "
                                f"raised {type(exc).__name__}: {' '.join(str(exc).split())}") from exc
        tracking += time.perf_counter() - tick
        if index > 0:
            boxes[index] = check_box(output, spec, sequence, index)
        if on_box is not None:
            on_box(index, boxes[index])
    return boxes, tracking


@dataclass(frozen=True)
class InitUpdateJob(CachedJob):
    """One run of an imported tracker (:class:`ImportedTracker`) over a sequence, through
    ``init`` and ``update`` only.

    ``seconds_tracking`` is the time spent in ``init`` and ``update``, as NRMLC's runs count it
    (:class:`nrmlc.tracker.loop.TrackResult`: fps is frames after the first over it);
    ``seconds_total`` is the whole run, with making the tracker and reading frames.
    Its result is a :class:`nrmlc.tracker.loop.TrackResult` without states.

    Attributes
    ----------
    sequence : nrmlc.data.Sequence
    tracker : str
        ``package.module:factory``.
    source : str
        Hash of the factory's source file(s) (:class:`ImportedTracker` computes it).
    seed : int
    n_frames : int or None
    search_path : tuple of str
        ``sys.path`` entries the worker adds to find the module (not part of the key).
    """

    sequence: object
    tracker: str
    source: str
    seed: int = 0
    n_frames: int | None = None
    search_path: tuple = field(default=(), compare=False, repr=False)

    folder: ClassVar[str] = "imported"
    uses_kernels: ClassVar[bool] = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "seed", _count("InitUpdateJob: seed", self.seed, 0))
        if self.n_frames is not None:
            object.__setattr__(self, "n_frames", _count("InitUpdateJob: n_frames", self.n_frames, 1))

    @property
    def label(self) -> str:
        return self.sequence.name

    def description(self, version: str | None = None) -> dict:
        # Not our code version: the user's tracker does not depend on it (RUNNER_VERSION and the
        # epoch stand for what this class does).
        return {"tracker": self.tracker, "source": self.source, "sequence": sequence_identity(self.sequence),
                "seed": int(self.seed), "n_frames": self.n_frames, "runner": RUNNER_VERSION, "epoch": CACHE_EPOCH}

    def execute(self) -> dict:
        start = time.perf_counter()
        boxes, tracking = track_init_update(self.tracker, self.sequence, self.seed, self.frames(),
                                            search_path=self.search_path)
        return {"boxes": boxes, "seconds_tracking": np.float64(tracking),
                "seconds_total": np.float64(time.perf_counter() - start)}

    def problem(self, arrays: dict) -> str | None:
        """Why ``arrays`` are not a finished run of this job (None: they are)."""
        return tracking_problem(arrays, self.frames(), {"boxes": 4})

    def result(self, arrays: dict) -> TrackResult:
        boxes = np.asarray(arrays["boxes"], dtype=np.float64)
        return TrackResult(boxes, np.zeros((len(boxes), 0)), {}, float(arrays["seconds_tracking"]),
                           float(arrays["seconds_total"]))
