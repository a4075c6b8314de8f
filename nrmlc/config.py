"""Project-wide settings: numba compilation flags, thread policy, data root.

Every ``@njit`` in :mod:`nrmlc` takes its flags from here
(``tests/test_config.py`` checks it), so that a change of policy (say, turning
``fastmath`` off to compare against a reference bit for bit) is made in one
place. The thread policy is explained once, in :func:`set_threads`.

Importing this module (which ``import nrmlc`` does) sets
``OMP_WAIT_POLICY=PASSIVE`` unless the user set it: libgomp reads it once, when
numba's OpenMP pool starts, so it must be in the environment before anything
can start that pool (see :func:`set_threads`).
"""
from __future__ import annotations

import os
import sys
import warnings

#: Environment of the thread policy, applied at import unless the user set it (see :func:`set_threads`).
THREAD_ENV = {"OMP_WAIT_POLICY": "PASSIVE"}


def _numba_pool_started() -> bool:
    """Whether numba's thread pool is already running (it reads the environment only once)."""
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    return bool(parallel is not None and getattr(parallel, "_is_initialized", False))


#: True when numba's pool was started, without a user-set wait policy, before nrmlc was imported:
#: the passive policy then cannot take effect in this process (set_threads warns).
_POLICY_TOO_LATE = _numba_pool_started() and any(name not in os.environ for name in THREAD_ENV)
for _name, _value in THREAD_ENV.items():
    os.environ.setdefault(_name, _value)

#: Flags shared by every compiled kernel. ``cache=True`` keeps the warm start
#: short (compiled code lives next to the sources in ``__pycache__``).
#: fastmath is limited to flags that cannot turn finite input into NaN or hide
#: NaN: re-association lets the per-pixel loops vectorise, but we keep
#: ``nnan``/``ninf`` off so that NaN checks in the kernels stay meaningful.
#: Results stay bit-identical across thread counts because each particle is
#: computed start to finish by one thread with a fixed instruction sequence.
NUMBA_FLAGS = dict(cache=True, fastmath={"nsz", "arcp", "contract", "reassoc"}, nogil=True)

#: Flags for kernels that loop over particles with ``prange``.
PARALLEL_FLAGS = dict(NUMBA_FLAGS, parallel=True)

#: Side of the square template grid (the paper normalises patches to 32x32).
PATCH_SIZE = 32

#: Environment variable naming the data root (same as ``make figures DATA=...``).
DATA_ENV = "NRMLC_DATA"


def data_root_from_env() -> str | None:
    """Return the data root given by ``$NRMLC_DATA``, or None when unset/empty."""
    root = os.environ.get(DATA_ENV, "").strip()
    return root or None


def set_threads(n_threads: int | None) -> int:
    """Give numba and OpenCV ``n_threads`` threads (None: all cores), OpenBLAS one.

    The thread policy (the one place it is explained; other modules link here):

    * **Why.** A tracked frame alternates many times between numba's parallel
      kernels (an OpenMP pool), one large BLAS product and a little numpy.
      OpenMP and OpenBLAS workers both busy-wait after each call by default
      (libgomp about 3 ms, ``GOMP_SPINCOUNT=300000``; OpenBLAS about 0.1 s,
      ``OPENBLAS_THREAD_TIMEOUT``), so a waiting pool kept a core spinning
      while the other pool needed it. On a quiet 2-core machine that only
      costs CPU time; with other processes running it divided the frame
      rate by 3 to 7 (Car4, 600 particles). ``make bench`` measures the
      set-ups side by side (its "Thread set-ups" table).
    * **numba (OpenMP)** workers wait passively: ``OMP_WAIT_POLICY=PASSIVE``
      is set when :mod:`nrmlc.config` is imported, which ``import nrmlc`` (and
      so any ``nrmlc`` import) does first, unless the variable is already set
      (a user's value wins). libgomp reads it only once, when numba starts its
      pool, so the policy holds whatever is imported or called first. Only a
      pool started before ``nrmlc`` was imported cannot get it (a warning
      says so). ``tests/test_config.py`` checks it in fresh processes.
    * **OpenBLAS** runs one thread (threadpoolctl, at run time; its
      environment variables only work before numpy is imported). The one large
      product per frame is split by rows over numba's thread count in Python
      threads instead (:func:`nrmlc.kernels.distance.candidate_template_dots`),
      which is as fast as OpenBLAS's threads without their spinning.
    * **OpenCV** gets ``n_threads`` threads.
    * **Determinism.** Each particle is computed start to finish by one thread
      and each product row by the same single-threaded BLAS kernel, so the same
      seed gives the same boxes, bit for bit, for any thread count
      (``tests/test_determinism.py``).
    * The experiment runner gives each worker process one thread, one process
      per core.

    Parameters
    ----------
    n_threads : int or None
        Threads for numba and OpenCV; None means all logical cores (capped at
        ``numba.config.NUMBA_NUM_THREADS``).

    Returns
    -------
    n : int
        The thread count applied.
    """
    import cv2
    import numba
    from threadpoolctl import threadpool_limits

    n_cores = os.cpu_count() or 1
    n = n_cores if n_threads is None else int(n_threads)
    if n < 1:
        from nrmlc.errors import ParameterError

        raise ParameterError(f"threads must be >= 1, got {n_threads}")
    if _POLICY_TOO_LATE:
        warnings.warn("numba's thread pool started before nrmlc was imported, so its workers spin-wait; "
                      "import nrmlc first or set OMP_WAIT_POLICY=PASSIVE (see nrmlc.config.set_threads)",
                      RuntimeWarning, stacklevel=2)
    n = min(n, numba.config.NUMBA_NUM_THREADS)
    numba.set_num_threads(n)
    threadpool_limits(limits=1, user_api="blas")
    cv2.setNumThreads(n)
    return n
