"""Where jobs run: in this process or in a pool of single-threaded worker processes, with the
tracker's numba kernels compiled or loaded first.

By default a process pool whose workers each use one thread for numba, OpenBLAS and OpenCV (on 2
cores, 2 single-threaded workers beat 1 two-threaded worker and never oversubscribe). Its
processes start from a fresh interpreter (``forkserver``, or ``spawn`` where that does not
exist), never by forking this one: a process that has used GNU OpenMP (numba's threads) cannot
fork safely. Any other :class:`concurrent.futures.Executor` works too (a Dask ``distributed``
client's ``get_executor()``).

The kernels are made ready (:func:`prepare_kernels`) before any worker starts and before any
timing, so workers load compiled code instead of compiling it two at a time, and no compile time
is counted as tracking time.
"""
from __future__ import annotations

import concurrent.futures as futures
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from nrmlc.errors import ParameterError
from nrmlc.tracker.loop import track_sequence
from nrmlc.tracker.params import TrackerParams


def execute_job(job, threads: int | None) -> dict:
    """Run one job (in a worker process, or in this one with ``threads``)."""
    if threads is not None:
        from nrmlc.config import set_threads

        set_threads(threads)
    return job.execute()


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
        child = subprocess.run([sys.executable, "-c", "from nrmlc.workbench.pool import warm_up; warm_up()"],
                               env=env, capture_output=True, text=True)
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


def _worker_init(parent: int | None = None, warm: bool = True) -> None:
    import threading

    from nrmlc.config import set_threads

    if parent is not None:
        threading.Thread(target=_exit_with, args=(parent,), name="exit-with-parent", daemon=True).start()
    set_threads(1)
    if warm:
        warm_up()


def process_pool(workers: int, warm: bool = True) -> futures.ProcessPoolExecutor:
    """A pool of ``workers`` single-threaded processes started from a fresh interpreter
    (forkserver, else spawn): safe after this process used OpenMP. With ``warm``, each loads our
    kernels before its first job (jobs that do not run them, e.g. a user's tracker, need not
    wait). They end themselves within seconds if this process is killed."""
    methods = multiprocessing.get_all_start_methods()
    context = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
    return futures.ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_worker_init,
                                       initargs=(os.getpid(), warm))
