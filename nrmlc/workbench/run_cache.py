"""One cache for every expensive job: cached, resumable grids on any Executor.

Each job's result (:mod:`nrmlc.workbench.jobs`) is stored under ``<cache>/<folder>/<key>.npz``
with a ``<key>.json`` beside it recording what was run, the numba target and the library
settings (:mod:`nrmlc.workbench.version`). So:

- a rerun skips every job whose file is there (an interrupted grid resumes);
- changing one parameter recomputes exactly the runs that use it;
- changing tracker or kernel code recomputes everything it could affect (a comment or a docstring
  cannot affect a run, so editing one recomputes nothing:
  :func:`nrmlc.workbench.version.code_version`);
- files are written atomically (:mod:`nrmlc.io`), so a killed run leaves no
  corrupt result, only missing ones; a file damaged some other way (a full
  disk, a copy cut short), or one that does not hold the whole result the
  job describes (:meth:`nrmlc.workbench.jobs.RunSpec.problem`), counts as missing, with a
  warning naming it.

Missing jobs go to any :class:`concurrent.futures.Executor`, by default a pool of
single-threaded worker processes (:mod:`nrmlc.workbench.pool`).
"""
from __future__ import annotations

import concurrent.futures as futures
import json
import os
import warnings
import zipfile
from pathlib import Path

import numpy as np

from nrmlc import io
from nrmlc.errors import DataError
from nrmlc.workbench import pool, version
from nrmlc.workbench.progress import Progress

DEFAULT_CACHE = Path(".cache") / "runs"

#: What reading a damaged ``.npz`` raises.
_DAMAGED = (zipfile.BadZipFile, OSError, ValueError, EOFError, KeyError, MemoryError)
#: An entry that inflates beyond this is damage, not a run (the largest run here: 5 MB): read whole,
#: it could take the memory the runs need. A header claiming more than it holds is a MemoryError,
#: damage too.
MAX_ENTRY_BYTES = 1 << 30


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


class RunCache:
    """Results of jobs on disk, ``<folder>/<job.folder>/<job key>.npz``."""

    def __init__(self, folder: str | os.PathLike | None = None) -> None:
        #: Whether the folder is :data:`DEFAULT_CACHE`, chosen by no one (messages say so).
        self.default = folder is None
        self.folder = Path(DEFAULT_CACHE if folder is None else folder)
        self.version = version.code_version()

    @property
    def label(self) -> str:
        """The cache as messages name it: ``--cache F``, or, for the default the user did not
        choose, ``the run cache F (default; choose one with --cache)``."""
        if self.default:
            return f"the run cache {self.folder} (default; choose one with --cache)"
        return f"--cache {self.folder}"

    def check_folder(self, option: str = "--cache") -> None:
        """Refuse, before any work, a cache folder that cannot be created or written to
        (:func:`nrmlc.io.check_folder`; the message names it as ``option``, or as the default
        cache when no folder was given)."""
        io.check_folder(self.folder, option, self.label if self.default else None)

    def path(self, job) -> Path:
        return self.folder / job.folder / f"{job.key(self.version)}.npz"

    def has(self, job) -> bool:
        """Whether the job's file is there and looks whole (a cheap check; :meth:`run` reads it)."""
        path = self.path(job)
        return path.is_file() and zipfile.is_zipfile(path)

    def _read(self, path: Path) -> dict:
        with zipfile.ZipFile(path) as archive:
            inflated = sum(member.file_size for member in archive.infolist())
        if inflated > MAX_ENTRY_BYTES:
            raise ValueError(f"inflates to {inflated / 2**20:.0f} MB, more than a run's "
                             f"{MAX_ENTRY_BYTES / 2**20:.0f} MB")
        with np.load(path) as arrays:
            return {name: arrays[name] for name in arrays.files}

    def load(self, job):
        """The job's stored result.

        Raises
        ------
        DataError
            If its file is missing, damaged or not a finished result (a warning names it).
        """
        arrays = self._readable(self.path(job), job)
        if arrays is None:
            raise DataError(f"{self.path(job)}: no finished result of this job in the cache")
        return job.result(arrays)

    def store(self, job, arrays: dict) -> None:
        # The result first, then its description: a present .npz is always complete.
        io.write_npz(self.path(job), **arrays)
        io.write_json(self.path(job).with_suffix(".json"),
                      dict(job.description(self.version), computed_for=version.numba_target(),
                           library_settings=version.library_settings()))

    def other_targets(self, paths) -> dict:
        """{numba target: count} of the stored runs at ``paths`` computed for a target other than
        this process's (runs stored before the target was recorded are not counted)."""
        here, others = version.numba_target(), {}
        for path in paths:
            description = path.with_suffix(".json")
            if not description.is_file():  # a FIFO there would block the read
                continue
            try:
                target = json.loads(description.read_text()).get("computed_for")
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
        if problem is None and job is not None:
            # A job without a problem() of its own: what its result() cannot read is damage too.
            try:
                job.result(arrays)
            except (KeyError, ValueError, TypeError, IndexError) as exc:
                problem = f"unreadable: {type(exc).__name__}: {_one_line(exc)}"
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
            progress: bool = True, on_result=None) -> list:
        """Make sure every job of ``specs`` is cached, then load them all.

        A run that cannot be stored (a full disk, a cache entry that is a FIFO or a folder) is
        still returned, with one warning naming the cache: finished work is never thrown away
        because the cache cannot keep it.

        Parameters
        ----------
        specs : list of jobs (RunSpec or any job, see :mod:`nrmlc.workbench.jobs`)
        executor : concurrent.futures.Executor, optional
            Where to run missing work. Default: a process pool of ``jobs`` workers
            (default: the number of cores), one thread each.
        jobs : int, optional
        progress : bool
            Show progress on stderr.
        on_result : callable(job, result), optional
            Called with each distinct job's ``job.result(...)`` as soon as it is there (read
            from the cache, or computed), so that a caller can keep it before a later run fails.

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
                          f"numba target ({listed}; this process: {version.numba_target()}); a fresh run may give "
                          f"other boxes (docs/RELIABILITY.md#determinism)", stacklevel=2)
        if on_result is not None:
            for path, arrays in stored.items():
                on_result(unique[path], unique[path].result(arrays))
        if missing:
            missing.sort(key=lambda job: -job.frames())  # longest first: no worker left alone at the end

            def computed(job, arrays) -> None:
                stored[self.path(job)] = arrays
                if on_result is not None:
                    on_result(job, job.result(arrays))

            self._compute(missing, executor, jobs, progress, on_done=computed, keep_unstored=True)
        return [job.result(stored[self.path(job)]) for job in specs]

    def _compute(self, missing: list, executor, jobs, progress, on_done=None, keep_unstored: bool = False) -> list:
        """Run ``missing``, storing each result as soon as it exists and then passing it to
        ``on_done(job, arrays)``; returns [(job, arrays)].

        With ``keep_unstored``, a result that cannot be stored (``OSError``) is warned of, once,
        and kept all the same (the caller has it in memory); else that error ends the batch.
        """
        done: list = []
        unstored: list = []
        workers = jobs or os.cpu_count() or 1
        own = executor is None
        if own and any(getattr(job, "uses_kernels", False) for job in missing):
            pool.prepare_kernels()  # here, once, before any worker loads them and before any timing
        bar = Progress(sum(job.frames() for job in missing), len(missing), enabled=progress)

        def finished(job, arrays: dict) -> None:
            try:
                self.store(job, arrays)
            except OSError as exc:
                if not keep_unstored:
                    raise
                if not unstored:
                    where = f"{self.label}: cannot store runs in it" if self.default else \
                        f"{self.folder}: cannot store runs in the run cache"
                    warnings.warn(f"{where} ({_one_line(exc)}); the results are kept but not cached, so a later "
                                  f"run computes them again", stacklevel=4)
                unstored.append(job)
            done.append((job, arrays))
            bar.update(job.frames(), getattr(job, "label", ""))
            if on_done is not None:
                on_done(job, arrays)

        try:
            if own and workers == 1:
                # In-process, one job at a time: each result is stored as soon as it exists.
                for job in missing:
                    finished(job, pool.execute_job(job, 1))
                return done
            if own:
                executor = pool.process_pool(min(workers, len(missing)),
                                             warm=any(getattr(job, "uses_kernels", False) for job in missing))
            try:
                pending = {executor.submit(pool.execute_job, job, None): job for job in missing}
                failure: BaseException | None = None
                for future in futures.as_completed(pending):
                    if future.cancelled():
                        continue
                    error = future.exception()
                    if error is None:
                        # Stored even after another run failed: finished work is never thrown away.
                        try:
                            finished(pending[future], future.result())
                        except Exception as exc:  # the caller's keeping of it failed: as a failed run
                            error = exc
                    if error is not None and failure is None:
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
