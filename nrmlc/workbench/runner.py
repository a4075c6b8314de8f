"""One cache for every expensive job: cached, resumable grids on any Executor.

A *job* is anything with

- ``key(version) -> str`` and ``description(version) -> dict``: what identifies
  it (``version`` is :func:`code_version`; a job whose result does not depend on
  our sources may ignore it);
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

:class:`RunSpec` (one tracking run) is the main one; the experiments add live
OpenCV peer runs and recorded tracker internals. Each result is stored under
``<cache>/<folder>/<key>.npz`` with a ``<key>.json`` beside it recording what
was run. So:

- a rerun skips every job whose file is there (an interrupted grid resumes);
- changing one parameter recomputes exactly the runs that use it;
- changing tracker or kernel code recomputes everything it could affect (a comment or a docstring
  cannot affect a run, so editing one recomputes nothing: :func:`code_version`);
- files are written atomically (:mod:`nrmlc.io`), so a killed run leaves no
  corrupt result, only missing ones; a file damaged some other way (a full
  disk, a copy cut short), or one that does not hold the whole result the
  job describes (:meth:`RunSpec.problem`), counts as missing, with a warning
  naming it;
- a sequence folder is keyed by the content of its frames and ground truth
  (:attr:`nrmlc.data.Sequence.identity`), not by its path or name.

Jobs go to any :class:`concurrent.futures.Executor`. By default a process
pool whose workers each use one thread for numba, OpenBLAS and OpenCV (on 2
cores, 2 single-threaded workers beat 1 two-threaded worker and never
oversubscribe). Its processes start from a fresh interpreter (``forkserver``,
or ``spawn`` where that does not exist), never by forking this one: a process
that has used GNU OpenMP (numba's threads) cannot fork safely. A Dask
``distributed`` client's ``get_executor()`` works too.
"""
from __future__ import annotations

import ast
import concurrent.futures as futures
import functools
import hashlib
import io as text_io
import json
import multiprocessing
import os
import signal
import subprocess
import sys
import time
import tokenize
import warnings
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from nrmlc import io
from nrmlc.errors import ParameterError
from nrmlc.tracker.params import TrackerParams
from nrmlc.tracker.loop import TrackResult, track_sequence

#: Sources whose change can change a run's boxes. ``data`` is included because it
#: decodes and converts the frames (and renders the synthetic ones) and reads the
#: initial box: a change there changes what the tracker sees.
_RESULT_SOURCES = ("geometry.py", "config.py", "data", "kernels", "tracker")

DEFAULT_CACHE = Path(".cache") / "runs"

#: Seconds between plain progress lines when stderr is not a terminal.
PROGRESS_INTERVAL = 30.0

#: What reading a damaged ``.npz`` raises.
_DAMAGED = (zipfile.BadZipFile, OSError, ValueError, EOFError, KeyError)


def code_version() -> str:
    """Hash of every source file that can change a tracking result, as :func:`executable_text`
    gives it: a comment or docstring edited leaves the version, and the run cache, as they were."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for name in _RESULT_SOURCES:
        path = root / name
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for file in files:
            digest.update(str(file.relative_to(root)).encode())
            digest.update(executable_text(file.read_bytes().decode("utf-8")).encode())
    return digest.hexdigest()[:16]


@functools.lru_cache(maxsize=256)
def executable_text(source: str) -> str:
    """``source`` (a Python module) without its comments, its string statements (docstrings) and
    its blank lines, and each line without trailing blanks: what of a file can change a run.

    Where the spans cut come from the parser and the tokenizer, which agree on them across Python
    versions (the text kept is the source's own, never a dump of the tree). Memoised on the text:
    :func:`code_version` reads the files every time (an edit is seen) but parses each text once,
    where a process makes several run caches (a grid, the tests)."""
    lines = source.splitlines()

    def position(line: int, offset: int) -> tuple[int, int]:
        """(line, column in characters) of the parser's (line, offset in UTF-8 bytes)."""
        return line, len(lines[line - 1].encode("utf-8")[:offset].decode("utf-8"))

    spans = [(position(node.lineno, node.col_offset), position(node.end_lineno, node.end_col_offset))
             for node in ast.walk(ast.parse(source))
             if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
             and isinstance(node.value.value, str)]
    spans += [(token.start, token.end) for token in tokenize.generate_tokens(text_io.StringIO(source).readline)
              if token.type == tokenize.COMMENT]
    for (first, start), (last, end) in sorted(spans, reverse=True):  # from the end: earlier spans stay put
        lines[first - 1:last] = [lines[first - 1][:start] + lines[last - 1][end:]]
    return "\n".join(line.rstrip() for line in lines if line.strip())


@functools.cache
def numba_target() -> str:
    """The CPU numba compiles the kernels for in this process: ``NUMBA_CPU_NAME`` or the host's,
    and which features (``NUMBA_CPU_FEATURES``, or the host's). Runs can differ between targets
    (docs/RELIABILITY.md#determinism), and the cache key does not hold it: it is stored beside
    each run and checked when runs are read (:meth:`RunCache.run`). Fixed for the process (numba
    reads the variables once), so it is worked out once."""
    import numba
    from llvmlite import binding

    name = numba.config.CPU_NAME or binding.get_host_cpu_name()
    features = numba.config.CPU_FEATURES
    return f"{name} ({'host features' if features is None else 'features: ' + (features or 'none')})"


# The variables that move OpenBLAS's, numpy's and OpenCV's IPP kernels off the host's best SIMD
# level (`make figures PORTABLE=1`); they can change the boxes as the numba target can (IPP only
# the peers' and the synthetic suite's drawing, whose integer pixels the tests pin).
LIBRARY_VARIABLES = ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES", "OPENCV_IPP")


def library_settings() -> dict:
    """{variable: value} of :data:`LIBRARY_VARIABLES` set in this process, recorded beside each
    stored run (``library_settings``) for the record only: reading runs does not compare them."""
    return {name: os.environ[name] for name in LIBRARY_VARIABLES if name in os.environ}


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


def frames_tracked(sequence, n_frames: int | None) -> int:
    """Frames a run over ``sequence`` tracks: all of them, or the first ``n_frames`` (at least 1).

    The one rule for every kind of job (tracking runs, peer runs, recorded internals).
    """
    n = len(sequence)
    return n if n_frames is None else max(1, min(n, int(n_frames)))


#: Tracker switches added after runs were cached, with their off value. A run's key leaves such a
#: switch out while it is off, so the runs cached before it existed keep their keys and
#: ``experiments.development.screen --baseline-version`` can pair a new switch with them (round 19 used it
#: for its five switches, then removed them; round 20 for ``translation_floor``, whose 0 is the
#: ``paper`` preset's and the default's before round 20; round 51 for the weak-trigger search's
#: three fields, whose off values are the ``paper`` preset's and the default's before round 51; rounds
#: 63-64 for ``second_expert``, whose 'off' is the ``paper`` preset's and the default's before round 64;
#: round 77 for ``unrecognised_size_share``, whose 0 is the ``paper`` preset's and the default's before
#: round 77; its gate ``unrecognised_gate`` is not a switch and stays in every key).
SWITCHES_ADDED_LATER: dict[str, object] = {"translation_floor": 0.0, "brightness": "raw", "redetect_trigger": 0.99,
                                           "redetect_weak_radius": 100.0, "redetect_weak_accept": 1.0,
                                           "second_expert": "off", "expert_blend_iou": 1.0,
                                           "unrecognised_size_share": 0.0}


def params_for_key(params: TrackerParams) -> dict:
    """The parameters as a run's key holds them: ``params.as_dict()`` without the switches of
    :data:`SWITCHES_ADDED_LATER` that are off."""
    return {name: value for name, value in params.as_dict().items()
            if not (name in SWITCHES_ADDED_LATER and value == SWITCHES_ADDED_LATER[name])}


def description_key(description: dict) -> str:
    """The cache key of a job: a hash of its JSON description (keys sorted)."""
    text = json.dumps(description, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


@runtime_checkable
class Job(Protocol):
    """What :class:`RunCache` needs of a job (module docstring)."""

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
                "seed": int(self.seed), **own, "code_version": version}


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
    recentre_every : int
        Diagnostics: 0 (an ordinary run) or move the estimate to the ground
        truth after every this many frames (see :func:`track_sequence`).
    negative_shares : bool
        Also record the per-frame negative shares of c and w (``track_sequence``'s option; only
        the reports that show them ask for it).
    """

    sequence: object
    params: TrackerParams = field(default_factory=TrackerParams)
    seed: int = 0
    n_frames: int | None = None
    label: str = ""
    recentre_every: int = 0
    negative_shares: bool = False

    #: Tracking runs live at the top of the cache.
    folder: ClassVar[str] = ""

    def description(self, version: str) -> dict:
        # Do not change: it decides the key of every cached run (tests/test_runner.py pins one).
        description = {"sequence": sequence_identity(self.sequence), "sequence_name": self.sequence.name,
                       "params": params_for_key(self.params), "seed": self.seed, "n_frames": self.n_frames,
                       "code_version": version}
        if self.recentre_every:  # only then, so that ordinary runs keep their keys
            description["recentre_every"] = int(self.recentre_every)
        if self.negative_shares:  # likewise
            description["negative_shares"] = True
        return description

    def __post_init__(self) -> None:
        if not isinstance(self.params, TrackerParams):
            raise ParameterError(f"RunSpec: params must be a TrackerParams, got {type(self.params).__name__} "
                                 f"(TrackerParams(**values) makes one from a dict)")
        object.__setattr__(self, "seed", _count("RunSpec: seed", self.seed, 0))
        if self.n_frames is not None:
            object.__setattr__(self, "n_frames", _count("RunSpec: n_frames", self.n_frames, 1))

    def problem(self, arrays: dict) -> str | None:
        """Why ``arrays`` are not a finished run of this spec (None: they are)."""
        n = self.frames()
        for name, columns in (("boxes", 4), ("states", 6)):
            if name not in arrays:
                return f"no {name!r} array"
            shape = np.shape(arrays[name])
            if shape != (n, columns):
                return f"{name!r} has shape {shape}, expected ({n}, {columns}) for {n} frames"
        if not np.isfinite(arrays["boxes"]).all():
            return "non-finite boxes"
        for name in ("seconds_tracking", "seconds_total"):
            if name not in arrays or np.shape(arrays[name]) != ():
                return f"no {name!r} value"
        return None

    def execute(self) -> dict:
        truth = self.sequence.groundtruth if self.recentre_every else None
        result = track_sequence(self.sequence, self.params, seed=self.seed, n_frames=self.n_frames,
                                recentre_boxes=truth, recentre_every=self.recentre_every,
                                negative_shares=self.negative_shares)
        return result.to_arrays()

    def result(self, arrays: dict) -> TrackResult:
        return TrackResult.from_arrays(arrays)


def _execute(job, threads: int | None) -> dict:
    """Run one job (in a worker process, or in this one with ``threads``)."""
    if threads is not None:
        from nrmlc.config import set_threads

        set_threads(threads)
    return job.execute()


# ------------------------------------------------------------------ processes
def warm_up() -> None:
    """Load (or compile) the tracker's numba kernels before any timed run.

    A process's first tracking run would otherwise pay for loading the
    compiled kernels inside its timed ``init``/``update``. 7 frames: past the
    first template update under any schedule up to the paper's 5 frames, so its
    kernels load too.
    """
    from nrmlc.data import SyntheticSequence, SyntheticSpec

    sequence = SyntheticSequence(SyntheticSpec(name="warm-up", seed=0, n_frames=7))
    for coding in ("regularized", "constrained"):
        track_sequence(sequence, TrackerParams(n_particles=20, coding=coding), n_frames=7)


def kernels_cached() -> bool:
    """Whether numba's on-disk cache holds compiled code, newer than its source, for every
    module with an ``@njit`` kernel.

    A heuristic (numba decides for itself), good enough to tell the user that a
    run will start by compiling.
    """
    import re

    decorated = re.compile(r"^\s*@(numba\.)?njit", re.MULTILINE)
    root = Path(__file__).resolve().parents[1]
    for source in root.rglob("*.py"):
        if not decorated.search(source.read_text(errors="replace")):
            continue
        indexes = list((source.parent / "__pycache__").glob(f"{source.stem}.*.nbi"))
        if not indexes or max(p.stat().st_mtime for p in indexes) < source.stat().st_mtime:
            return False
    return True


_kernels_ready = False
_target_problem: str | None = None


def check_numba_target() -> None:
    """Refuse, in one line, a numba target this CPU cannot run.

    ``NUMBA_CPU_NAME`` (make's ``NUMBA_TARGET``) names the CPU the kernels are compiled for;
    code for a CPU with more instructions than this one (``znver4``'s AVX-512 on a CPU without
    it) kills the process with an illegal instruction and no word of why. So when the variable
    names another CPU than the host's, or ``NUMBA_CPU_FEATURES`` adds features, :func:`warm_up`
    runs first in a child process (compiling into the same numba cache, so the time is not
    lost); if the child dies, :class:`~nrmlc.errors.ParameterError` says so. Checked once per
    process.

    Raises
    ------
    ParameterError
        The child process died (its signal or last error line is named).
    """
    global _target_problem
    import numba
    from llvmlite import binding

    name, features, host = numba.config.CPU_NAME, numba.config.CPU_FEATURES, binding.get_host_cpu_name()
    if (not name or name == host) and not features:
        return
    if _target_problem is None:
        # the child imports this very package, whatever the current folder or installed copy
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [str(Path(__file__).resolve().parents[2])] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
        child = subprocess.run([sys.executable, "-c", "from nrmlc.workbench.runner import warm_up; warm_up()"], env=env,
                               capture_output=True, text=True)
        if child.returncode < 0:
            _target_problem = f"died with {signal.Signals(-child.returncode).name}"
        elif child.returncode > 0:
            lines = child.stderr.strip().splitlines()
            _target_problem = f"failed ({lines[-1] if lines else f'exit status {child.returncode}'})"
        else:
            _target_problem = ""
    if _target_problem:
        raise ParameterError(f"NUMBA_CPU_NAME={name or host}, NUMBA_CPU_FEATURES={features!r} (make's NUMBA_TARGET): "
                             f"this CPU ({host}) cannot run the kernels compiled for it: the warm-up {_target_problem}; "
                             f"leave NUMBA_TARGET unset to compile for this CPU (docs/RELIABILITY.md#determinism)")


def prepare_kernels(stream=None) -> float:
    """Compile or load the kernels in this process, once; say so when it compiles.

    Returns the seconds it took (0 when already done). Called before workers
    start, so they load compiled code from the cache instead of compiling it
    two at a time, and so no compile time is counted as tracking time.
    """
    global _kernels_ready
    if _kernels_ready:
        return 0.0
    stream = sys.stderr if stream is None else stream
    compiling = not kernels_cached()
    if compiling:
        print("[nrmlc] compiling the numba kernels (once, after an install or a code change; about 20-60 s; "
              "not counted as tracking time) ...", file=stream, flush=True)
    start = time.perf_counter()
    check_numba_target()
    warm_up()
    seconds = time.perf_counter() - start
    if compiling:
        print(f"[nrmlc] kernels compiled in {seconds:.0f} s", file=stream, flush=True)
    _kernels_ready = True
    return seconds


def _exit_with(parent: int, every: float = 2.0) -> None:
    """End this worker when process ``parent`` is gone: a pool's workers outlive a killed
    parent (SIGKILL runs no clean-up) and would hold their cores and memory otherwise."""
    while True:
        time.sleep(every)
        try:
            os.kill(parent, 0)
        except ProcessLookupError:
            os._exit(1)
        except PermissionError:  # alive, someone else's (cannot happen for our parent)
            pass


def _worker_init(parent: int | None = None) -> None:
    import threading

    from nrmlc.config import set_threads

    if parent is not None:
        threading.Thread(target=_exit_with, args=(parent,), name="exit-with-parent", daemon=True).start()
    set_threads(1)
    warm_up()


def process_pool(workers: int) -> futures.ProcessPoolExecutor:
    """A pool of ``workers`` single-threaded, warmed-up processes started from a fresh
    interpreter (forkserver, else spawn): safe after this process used OpenMP. They end
    themselves within seconds if this process is killed."""
    methods = multiprocessing.get_all_start_methods()
    context = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
    return futures.ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_worker_init,
                                       initargs=(os.getpid(),))


# ------------------------------------------------------------------- progress
class Progress:
    """Frames done of a batch of jobs: a tqdm bar on a terminal, else a plain line
    every :data:`PROGRESS_INTERVAL` seconds (runs done/total, frames, fps, ETA)."""

    def __init__(self, total_frames: int, n_jobs: int, enabled: bool = True, stream=None,
                 interval: float = PROGRESS_INTERVAL) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.total, self.n_jobs, self.interval = int(total_frames), int(n_jobs), float(interval)
        self.frames = self.jobs = 0
        self.start = self.last = time.monotonic()
        self.enabled = enabled
        self.bar = None
        if enabled and getattr(self.stream, "isatty", lambda: False)():
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, unit="frame", desc=f"{n_jobs} runs", file=self.stream)
        elif enabled:
            self._line("started")

    def _line(self, what: str) -> None:
        elapsed = time.monotonic() - self.start
        rate = self.frames / elapsed if elapsed > 0 else 0.0
        eta = f", ETA {(self.total - self.frames) / rate / 60:.1f} min" if rate > 0 and self.frames < self.total else ""
        print(f"[runs] {what}: {self.jobs}/{self.n_jobs} runs, {self.frames}/{self.total} frames, "
              f"{rate:.0f} frames/s, {elapsed / 60:.1f} min{eta}", file=self.stream, flush=True)

    def update(self, frames: int, title: str = "") -> None:
        self.frames += int(frames)
        self.jobs += 1
        if self.bar is not None:
            self.bar.update(int(frames))
            self.bar.set_postfix_str(title, refresh=False)
        elif self.enabled and time.monotonic() - self.last >= self.interval:
            self.last = time.monotonic()
            self._line("progress")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        elif self.enabled:
            self._line("done" if self.jobs == self.n_jobs else "stopped")


# ---------------------------------------------------------------------- cache
class RunCache:
    """Results of jobs on disk, ``<folder>/<job.folder>/<job key>.npz``."""

    def __init__(self, folder: str | os.PathLike = DEFAULT_CACHE) -> None:
        self.folder = Path(folder)
        self.version = code_version()

    def path(self, job) -> Path:
        return self.folder / job.folder / f"{job.key(self.version)}.npz"

    def has(self, job) -> bool:
        """Whether the job's file is there and looks whole (a cheap check; :meth:`run` reads it)."""
        path = self.path(job)
        return path.is_file() and zipfile.is_zipfile(path)

    def _read(self, path: Path) -> dict:
        with np.load(path) as arrays:
            return {name: arrays[name] for name in arrays.files}

    def load(self, job):
        """The job's stored result.

        Raises
        ------
        DataError
            If its file is missing, damaged or not a finished result (a warning names it).
        """
        from nrmlc.errors import DataError

        arrays = self._readable(self.path(job), job)
        if arrays is None:
            raise DataError(f"{self.path(job)}: no finished result of this job in the cache")
        return job.result(arrays)

    def store(self, job, arrays: dict) -> None:
        # The result first, then its description: a present .npz is always complete.
        io.write_npz(self.path(job), **arrays)
        io.write_json(self.path(job).with_suffix(".json"),
                      dict(job.description(self.version), computed_for=numba_target(),
                           library_settings=library_settings()))

    def other_targets(self, paths) -> dict:
        """{numba target: count} of the stored runs at ``paths`` computed for a target other than
        this process's (runs stored before the target was recorded are not counted)."""
        here, others = numba_target(), {}
        for path in paths:
            try:
                target = json.loads(path.with_suffix(".json").read_text()).get("computed_for")
            except (OSError, ValueError, AttributeError):
                continue
            if target is not None and target != here:
                others[target] = others.get(target, 0) + 1
        return others

    def _readable(self, path: Path, job=None):
        """The stored arrays, or None (with a warning naming the file) if it is damaged or, for
        a job with a ``problem`` method, not a finished result of ``job``."""
        if not path.is_file():
            return None
        try:
            arrays = self._read(path)
        except _DAMAGED as exc:
            warnings.warn(f"{path}: damaged cache file ({type(exc).__name__}: {exc}); computing it again",
                          stacklevel=3)
            return None
        check = getattr(job, "problem", None)
        problem = check(arrays) if check is not None else None
        if problem is not None:
            warnings.warn(f"{path}: incomplete cache entry ({problem}); computing it again", stacklevel=3)
            return None
        return arrays

    def missing(self, jobs: list) -> list:
        """The distinct jobs of ``jobs`` whose file is absent or cut short (a cheap check:
        damage inside a file is found when :meth:`run` reads it)."""
        unique = {}
        for job in jobs:
            unique.setdefault(self.path(job), job)
        missing = []
        for path, job in unique.items():
            if not path.is_file():
                missing.append(job)
            elif not zipfile.is_zipfile(path):
                warnings.warn(f"{path}: damaged cache file (not a whole .npz); computing it again", stacklevel=2)
                missing.append(job)
        return missing

    def ensure(self, specs: list, executor: futures.Executor | None = None, jobs: int | None = None,
               progress: bool = True) -> list:
        """Compute every missing job of ``specs`` (longest first) without loading the others;
        returns the jobs computed."""
        missing = sorted(self.missing(specs), key=lambda job: -job.frames())
        if missing:
            self._compute(missing, executor, jobs, progress)
        return missing

    def run(self, specs: list, executor: futures.Executor | None = None, jobs: int | None = None,
            progress: bool = True) -> list:
        """Make sure every job of ``specs`` is cached, then load them all.

        Parameters
        ----------
        specs : list of jobs (RunSpec or any job, see the module docstring)
        executor : concurrent.futures.Executor, optional
            Where to run missing work. Default: a process pool of ``jobs`` workers
            (default: the number of cores), one thread each.
        jobs : int, optional
        progress : bool
            Show progress on stderr.

        Returns
        -------
        results : list, ``job.result(...)`` in the order of ``specs``.
        """
        stored, unique = {}, {}
        for job in specs:
            unique.setdefault(self.path(job), job)
        missing = []
        for path, job in unique.items():
            arrays = self._readable(path, job)
            if arrays is None:
                missing.append(job)
            else:
                stored[path] = arrays
        others = self.other_targets([path for path, job in unique.items()
                                     if path in stored and getattr(job, "uses_kernels", False)])
        if others:
            listed = ", ".join(f"{count} for {target}" for target, count in others.items())
            warnings.warn(f"{self.folder}: {sum(others.values())} of the cached runs read were computed for another "
                          f"numba target ({listed}; this process: {numba_target()}); a fresh run may give other boxes "
                          f"(docs/RELIABILITY.md#determinism)", stacklevel=2)
        if missing:
            missing.sort(key=lambda job: -job.frames())  # longest first: no worker left alone at the end
            for job, arrays in self._compute(missing, executor, jobs, progress):
                stored[self.path(job)] = arrays
        return [job.result(stored[self.path(job)]) for job in specs]

    def _compute(self, missing: list, executor, jobs, progress) -> list:
        """Run ``missing``, storing each result as soon as it exists; returns [(job, arrays)]."""
        done: list = []
        workers = jobs or os.cpu_count() or 1
        own = executor is None
        if own and any(getattr(job, "uses_kernels", False) for job in missing):
            prepare_kernels()  # here, once, before any worker loads them and before any timing
        bar = Progress(sum(job.frames() for job in missing), len(missing), enabled=progress)

        def finished(job, arrays: dict) -> None:
            self.store(job, arrays)
            done.append((job, arrays))
            bar.update(job.frames(), getattr(job, "label", ""))

        try:
            if own and workers == 1:
                # In-process, one job at a time: each result is stored as soon as it exists.
                for job in missing:
                    finished(job, _execute(job, 1))
                return done
            if own:
                executor = process_pool(min(workers, len(missing)))
            try:
                pending = {executor.submit(_execute, job, None): job for job in missing}
                failure: BaseException | None = None
                for future in futures.as_completed(pending):
                    if future.cancelled():
                        continue
                    error = future.exception()
                    if error is None:
                        # Stored even after another run failed: finished work is never thrown away.
                        finished(pending[future], future.result())
                    elif failure is None:
                        failure = error
                        for other in pending:  # runs not started yet; those running still finish
                            other.cancel()
                if failure is not None:
                    raise failure
            finally:
                if own:
                    executor.shutdown(wait=True, cancel_futures=True)
        finally:
            bar.close()
        return done
