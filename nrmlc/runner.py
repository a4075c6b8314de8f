"""Cached, resumable grids of tracking runs.

A *run* is one (sequence, parameter set, seed, frame count). Its result is
stored under ``<cache>/<key>.npz`` with a ``<key>.json`` beside it recording
what was run; the key hashes the sequence's identity, the parameters, the
seed, the frame count and the *code version* (a hash of the sources that
decide the boxes). So:

- a rerun skips every run whose file is there (an interrupted grid resumes);
- changing one parameter recomputes exactly the runs that use it;
- changing tracker or kernel code recomputes everything it could affect;
- files are written atomically (:mod:`nrmlc.io`), so a killed run leaves no
  corrupt result, only missing ones.

Runs go to any :class:`concurrent.futures.Executor`. By default a process
pool whose workers each use one thread for numba, OpenBLAS and OpenCV (on 2
cores, 2 single-threaded workers beat 1 two-threaded worker and never
oversubscribe). A Dask ``distributed`` client's ``get_executor()`` works too.
"""
from __future__ import annotations

import concurrent.futures as futures
import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nrmlc import io
from nrmlc.tracker.params import TrackerParams
from nrmlc.tracker.run import TrackResult, track_sequence

#: Sources whose change can change a run's boxes. ``data`` is included because it
#: decodes and converts the frames (and renders the synthetic ones) and reads the
#: initial box: a change there changes what the tracker sees.
_RESULT_SOURCES = ("geometry.py", "config.py", "data", "kernels", "tracker")

DEFAULT_CACHE = Path(".cache") / "runs"


def code_version() -> str:
    """Hash of every source file that can change a tracking result."""
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for name in _RESULT_SOURCES:
        path = root / name
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for file in files:
            digest.update(str(file.relative_to(root)).encode())
            digest.update(file.read_bytes())
    return digest.hexdigest()[:16]


def sequence_identity(sequence) -> str:
    """A string naming the sequence's content: :attr:`nrmlc.data.Sequence.identity`
    (its folder or its synthetic spec, plus an overridden initial box)."""
    return sequence.identity


@dataclass(frozen=True)
class RunSpec:
    """One tracking run: what to track and how.

    Attributes
    ----------
    sequence : nrmlc.data.Sequence
    params : TrackerParams
    seed : int
    n_frames : int or None
        Track only the first frames (None: all).
    label : str
        Free text for progress bars and reports (not part of the key).
    recentre_every : int
        Diagnostics: 0 (an ordinary run) or move the estimate to the ground
        truth after every this many frames (see :func:`track_sequence`).
    """

    sequence: object
    params: TrackerParams = field(default_factory=TrackerParams)
    seed: int = 0
    n_frames: int | None = None
    label: str = ""
    recentre_every: int = 0

    def description(self, version: str) -> dict:
        description = {"sequence": sequence_identity(self.sequence), "sequence_name": self.sequence.name,
                       "params": self.params.as_dict(), "seed": self.seed, "n_frames": self.n_frames,
                       "code_version": version}
        if self.recentre_every:  # only then, so that ordinary runs keep their keys
            description["recentre_every"] = int(self.recentre_every)
        return description

    def key(self, version: str) -> str:
        text = json.dumps(self.description(version), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:24]


def _execute(spec: RunSpec, threads: int | None) -> dict:
    if threads is not None:
        from nrmlc.config import set_threads

        set_threads(threads)
    truth = spec.sequence.groundtruth if spec.recentre_every else None
    result = track_sequence(spec.sequence, spec.params, seed=spec.seed, n_frames=spec.n_frames,
                            recentre_boxes=truth, recentre_every=spec.recentre_every)
    return result.to_arrays()


def _worker_init() -> None:
    from nrmlc.config import set_threads

    set_threads(1)


class RunCache:
    """Results of runs on disk, keyed by :meth:`RunSpec.key`."""

    def __init__(self, folder: str | os.PathLike = DEFAULT_CACHE) -> None:
        self.folder = Path(folder)
        self.version = code_version()

    def path(self, spec: RunSpec) -> Path:
        return self.folder / f"{spec.key(self.version)}.npz"

    def has(self, spec: RunSpec) -> bool:
        return self.path(spec).is_file()

    def load(self, spec: RunSpec) -> TrackResult:
        with np.load(self.path(spec)) as arrays:
            return TrackResult.from_arrays(dict(arrays))

    def store(self, spec: RunSpec, arrays: dict) -> None:
        # The result first, then its description: a present .npz is always complete.
        io.write_npz(self.path(spec), **arrays)
        io.write_json(self.path(spec).with_suffix(".json"), spec.description(self.version))

    def run(self, specs: list[RunSpec], executor: futures.Executor | None = None, jobs: int | None = None,
            progress: bool = True) -> list[TrackResult]:
        """Make sure every run of ``specs`` is cached, then load them all.

        Parameters
        ----------
        specs : list of RunSpec
        executor : concurrent.futures.Executor, optional
            Where to run missing work. Default: a process pool of ``jobs`` workers
            (default: the number of cores), one thread each.
        jobs : int, optional
        progress : bool
            Show a progress bar on stderr.

        Returns
        -------
        results : list of TrackResult, in the order of ``specs``.
        """
        unique = {}
        for spec in specs:
            unique.setdefault(spec.key(self.version), spec)
        missing = [spec for key, spec in unique.items() if not self.has(spec)]
        if missing:
            self._compute(missing, executor, jobs, progress)
        return [self.load(spec) for spec in specs]

    def _compute(self, missing, executor, jobs, progress) -> None:
        from tqdm import tqdm

        def n_frames(spec: RunSpec) -> int:
            return len(spec.sequence) if spec.n_frames is None else min(spec.n_frames, len(spec.sequence))

        bar = tqdm(total=sum(n_frames(s) for s in missing), unit="frame", desc=f"{len(missing)} runs",
                   disable=not progress or None)

        def finished(spec: RunSpec, arrays: dict) -> None:
            self.store(spec, arrays)
            bar.update(n_frames(spec))
            bar.set_postfix_str(f"{spec.label or spec.sequence.name} seed {spec.seed}", refresh=False)

        jobs = jobs or os.cpu_count() or 1
        try:
            if executor is None and jobs == 1:
                # In-process, one run at a time: each result is stored as soon as it exists.
                for spec in missing:
                    finished(spec, _execute(spec, 1))
                return
            own = executor is None
            if own:
                executor = futures.ProcessPoolExecutor(max_workers=jobs, initializer=_worker_init)
            try:
                pending = {executor.submit(_execute, spec, None): spec for spec in missing}
                failure: BaseException | None = None
                for done in futures.as_completed(pending):
                    if done.cancelled():
                        continue
                    error = done.exception()
                    if error is None:
                        # Stored even after another run failed: finished work is never thrown away.
                        finished(pending[done], done.result())
                    elif failure is None:
                        failure = error
                        for future in pending:  # runs not started yet; those running still finish
                            future.cancel()
                if failure is not None:
                    raise failure
            finally:
                if own:
                    executor.shutdown(wait=True, cancel_futures=True)
        finally:
            bar.close()
