"""Project-wide settings: numba compilation flags, thread counts, data root.

Every ``@njit`` in :mod:`nrmlc.kernels` takes its flags from here, so that a
change of policy (say, turning ``fastmath`` off to compare against a
reference bit for bit) is made in one place.
"""
from __future__ import annotations

import os

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

    OpenMP (numba's pool) and OpenBLAS both busy-wait between calls by default,
    and the tracker alternates between them many times a frame, so waiting
    threads took the cores the other pool needed (measured: 35 fps before,
    ~106 after, same machine). So OpenBLAS runs one thread, numba's OpenMP
    workers wait passively (``OMP_WAIT_POLICY=PASSIVE``, set in
    :mod:`nrmlc.kernels`), and the one large product per frame is split by rows
    over numba's thread count (:func:`nrmlc.kernels.distance.candidate_template_dots`).
    Each particle is computed by one thread and each product row by the same
    single-threaded kernel, so results are bit-identical for any thread count.
    The experiment runner gives each worker process one thread.

    Returns the thread count applied.
    """
    import cv2
    import numba
    from threadpoolctl import threadpool_limits

    n_cores = os.cpu_count() or 1
    n = n_cores if n_threads is None else int(n_threads)
    if n < 1:
        from nrmlc.errors import ParameterError

        raise ParameterError(f"threads must be >= 1, got {n_threads}")
    n = min(n, numba.config.NUMBA_NUM_THREADS)
    numba.set_num_threads(n)
    # OpenBLAS workers busy-wait ~0.1 s after every call and OPENBLAS_THREAD_TIMEOUT is
    # read only at load, so with a BLAS call every frame they never sleep.
    threadpool_limits(limits=1, user_api="blas")
    cv2.setNumThreads(n)
    return n
