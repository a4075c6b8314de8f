"""Candidate-template inner products and k-nearest-template selection.

The coding stage (:mod:`nrmlc.kernels.coding`) never touches the
``dim``-length vectors again: every squared distance and every local Gram
matrix it needs is an expansion of three small tables,

* ``dots[i, t] = y_i . t_t``            (:func:`candidate_template_dots`),
* ``template_gram[s, t] = t_s . t_t``   (:func:`template_gram`),
* ``|y_i|^2`` and ``|t_t|^2``           (row sums of squares, or the Gram diagonal).

so the only ``O(dim)`` work per frame is one matrix product.

Implementation choice (measured on the 2-core Xeon build machine, numba
threads = BLAS threads = 2, ``n_candidates=600, n_templates=250, dim=1024``,
median of 20 calls): OpenBLAS ``sgemm`` + cast to float64 took 1.76 ms, a
numba ``prange`` kernel with float32 accumulation 7.98 ms (float64
accumulation 16.8 ms), ``dgemm`` on float64 copies 4.0 ms including the
casts. BLAS wins, so :func:`candidate_template_dots` is a checked wrapper
around the matrix product and needs no ``njit``. Under the thread policy of
:func:`nrmlc.config.set_threads` numpy's BLAS runs one thread, so the product
is split into fixed blocks of rows shared by ``numba.get_num_threads()`` Python
threads (:func:`_row_blocked_product`).

Precision note: ``sgemm`` accumulates in float32, so each dot carries an
absolute error of up to ~1e-6 for unit-norm rows (7e-7 measured). That is
harmless for the regularised coder (``ridge`` near 1) but it is the
dominant error of the unregularised ("plain") coder, whose local Gram
entries are differences of such dots. Pass float64 arrays to get ``dgemm``
(about 2.3x slower) when that matters.
"""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from numba import njit, prange

from nrmlc.config import NUMBA_FLAGS, PARALLEL_FLAGS
from nrmlc.errors import ParameterError
from nrmlc.kernels.checks import check_array, check_int, check_length

__all__ = ["candidate_template_dots", "squared_norms", "template_gram", "nearest_templates"]

_FLOAT_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))


#: Rows of the candidate-template product per ``sgemm`` call. Fixed, never derived from the
#: thread count: OpenBLAS's Haswell kernels (its choice on an x86-64 CPU without AVX-512)
#: give a row other bits in a call of another size or at another offset (on an AMD EPYC, 2026-12-02,
#: 121 of 450 rows differed between one call and two halves), so blocks that followed the thread
#: count made the boxes follow it too; with fixed blocks each row is computed by the same call
#: whatever the thread count. The threads share the blocks.
_ROWS_PER_BLOCK = 128

_pool_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None
_pool_size = 0


def _thread_pool(n_threads: int) -> ThreadPoolExecutor:
    """A process-wide pool of ``n_threads`` workers (re-created when the count changes)."""
    global _pool, _pool_size
    with _pool_lock:
        if _pool is None or _pool_size != n_threads:
            if _pool is not None:
                _pool.shutdown(wait=True)
            _pool = ThreadPoolExecutor(max_workers=n_threads, thread_name_prefix="nrmlc-gemm")
            _pool_size = n_threads
        return _pool


_controller = None


def _one_blas_thread():
    """Context in which numpy's BLAS runs one thread (~13 us to enter and leave).

    BLAS rounding can depend on its thread count (OpenBLAS dgemm/dsyrk split
    the sums differently), so every product here runs single-threaded and the
    parallelism comes from splitting rows ourselves: the results are then the
    same whatever the caller's BLAS or numba thread settings.
    """
    global _controller
    if _controller is None:
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
    return _controller.limit(limits=1, user_api="blas")


def _run_in_threads(tasks: list) -> None:
    """Run zero-argument ``tasks`` in up to ``numba.get_num_threads()`` threads, BLAS held to one.

    The calling thread takes the first task. Which thread runs a task never changes
    what it computes, so results do not depend on the thread count as long as the
    tasks themselves do not (callers fix them).
    """
    n_threads = max(1, min(numba.get_num_threads(), len(tasks)))
    with _one_blas_thread():
        if n_threads == 1:
            for task in tasks:
                task()
            return
        pool = _thread_pool(n_threads - 1)
        pending = [(pool.submit(task), task) for task in tasks[1:]]
        tasks[0]()
        for future, task in pending:
            # A task no worker has started yet (its thread has not had a core: the machine
            # is busy) is run here rather than waited for; same task, same result.
            if future.cancel():
                task()
            else:
                future.result()


def _row_blocked_product(candidates: np.ndarray, templates: np.ndarray) -> np.ndarray:
    """``candidates @ templates.T`` in float64, its fixed row blocks (:data:`_ROWS_PER_BLOCK`)
    multiplied in up to ``numba.get_num_threads()`` threads.

    BLAS itself is held to one thread (:func:`_one_blas_thread`; why: the
    thread policy in :func:`nrmlc.config.set_threads`); numpy releases the GIL,
    so the blocks run in parallel and idle workers sleep. Each thread also casts
    its block of a float32 product to float64 (exact), so no serial pass over
    the product remains. The blocks do not depend on the thread count, so neither
    does the result (why that matters: :data:`_ROWS_PER_BLOCK`).
    """
    n_rows = candidates.shape[0]
    out = np.empty((n_rows, templates.shape[0]), dtype=np.float64)
    single = candidates.dtype == np.float32
    products = np.empty(out.shape, dtype=np.float32) if single else out
    bounds = list(range(0, n_rows, _ROWS_PER_BLOCK)) + [n_rows]

    def block(start: int, stop: int):
        def task() -> None:
            np.matmul(candidates[start:stop], templates.T, out=products[start:stop])
            if single:
                out[start:stop] = products[start:stop]
        return task

    _run_in_threads([block(start, stop) for start, stop in zip(bounds[:-1], bounds[1:])])
    return out


def candidate_template_dots(candidates: np.ndarray, templates: np.ndarray) -> np.ndarray:
    """Inner products between every candidate and every template.

    Parameters
    ----------
    candidates : ndarray, shape (n_candidates, dim), float32 or float64
        Candidate patches as (unit-norm) rows, C-contiguous.
    templates : ndarray, shape (n_templates, dim), same dtype as ``candidates``
        Template patches as rows, C-contiguous.

    Returns
    -------
    dots : ndarray, shape (n_candidates, n_templates), float64
        ``dots[i, t] = candidates[i] . templates[t]``. Float32 inputs are
        multiplied by ``sgemm`` (float32 accumulation) and then cast, which
        was 2.3x faster than ``dgemm`` and 4.5x faster than a numba kernel
        here (see the module docstring for timings and the precision cost).
    """
    check_array("candidates", candidates, _FLOAT_DTYPES, 2)
    check_array("templates", templates, _FLOAT_DTYPES, 2)
    if templates.dtype != candidates.dtype:
        raise ParameterError(
            f"templates dtype {templates.dtype} differs from candidates dtype {candidates.dtype}"
        )
    if templates.shape[1] != candidates.shape[1]:
        raise ParameterError(
            f"templates have dim {templates.shape[1]}, candidates have dim {candidates.shape[1]}"
        )
    return _row_blocked_product(candidates, templates)


@njit(**NUMBA_FLAGS)
def _squared_norm(vector):
    """Squared norm of one row, accumulated in float64 (one candidate; see :func:`squared_norms`)."""
    total = 0.0
    for d in range(vector.shape[0]):
        value = np.float64(vector[d])
        total += value * value
    return total


@njit(**NUMBA_FLAGS)
def _squared_norms(vectors, out):
    # On the calling thread: ~0.1 ms for 600 x 1024, while a parallel region that
    # waits for a thread which lost its core (a busy machine) measured 0.6 ms.
    for i in range(vectors.shape[0]):
        out[i] = _squared_norm(vectors[i])


def squared_norms(vectors: np.ndarray) -> np.ndarray:
    """Squared Euclidean norm of every row, accumulated in float64.

    Replaces ``np.einsum("ij,ij->i", v, v, dtype=np.float64)``, which casts
    through a buffered iterator (0.9 ms for 600 x 1024 float32 on one core,
    against ~0.1 ms here). Products of float32 values are exact in float64;
    only the summation order differs from einsum's (a few ulps of 1e-16).

    Parameters
    ----------
    vectors : ndarray, shape (n_vectors, dim), float32 or float64, C-contiguous

    Returns
    -------
    sq_norms : ndarray, shape (n_vectors,), float64
    """
    check_array("vectors", vectors, _FLOAT_DTYPES, 2)
    out = np.empty(vectors.shape[0], dtype=np.float64)
    _squared_norms(vectors, out)
    return out


@njit(**NUMBA_FLAGS)
def _assemble_gram(gram, previous, kept, fresh, stayed, among_new, against_stayed):
    """Fill ``gram`` (n, n) from the carried block of ``previous`` and the new rows' products.

    ``among_new`` (n_fresh, n_fresh) holds ``new @ new.T``, ``against_stayed`` (n_fresh,
    n_stayed) ``new @ stayed.T``. Only the upper triangle of ``among_new`` is read and both
    triangles of ``gram`` get the same value, so ``gram`` is exactly symmetric whatever
    BLAS routine computed the product.
    """
    for a in range(stayed.shape[0]):
        for b in range(stayed.shape[0]):
            gram[stayed[a], stayed[b]] = previous[kept[stayed[a]], kept[stayed[b]]]
    for a in range(fresh.shape[0]):
        for b in range(fresh.shape[0]):
            gram[fresh[a], fresh[b]] = among_new[min(a, b), max(a, b)]
        for b in range(stayed.shape[0]):
            value = np.float64(against_stayed[a, b])
            gram[fresh[a], stayed[b]] = value
            gram[stayed[b], fresh[a]] = value


def template_gram(templates: np.ndarray, previous: np.ndarray | None = None,
                  kept: np.ndarray | None = None) -> np.ndarray:
    """Gram matrix of the template set, in the templates' precision, recomputing only new rows.

    A template update replaces every negative and at most one positive, so the
    block of the templates that stayed is carried over from the previous Gram and
    only the new rows are multiplied: ``new @ new.T`` (a ``syrk``, half the work of
    a product) and ``new @ stayed.T``, in two threads. Float32 templates are
    multiplied in float32 (``ssyrk``/``sgemm``, then cast), as the candidate dots
    are (:func:`candidate_template_dots`): every local Gram entry combines the two,
    so a float64 Gram beside float32 dots would not make it more accurate, and it
    cost twice the time. Pass float64 templates for a float64 Gram.

    Parameters
    ----------
    templates : ndarray, shape (n_templates, dim), float32 or float64
        Template patches as rows, C-contiguous.
    previous : ndarray, shape (n_previous, n_previous), float64, optional
        The Gram of the previous template set (this function's output for it).
    kept : ndarray, shape (n_templates,), int64, optional
        With ``previous``: ``kept[t]`` is the row of ``previous`` that holds template
        ``t`` unchanged, or -1 for a new template.

    Returns
    -------
    gram : ndarray, shape (n_templates, n_templates), float64
        ``gram[s, t] = templates[s] . templates[t]``, exactly symmetric. Entries
        carried over equal those of ``previous``; an entry can differ from the
        same entry of a whole new product by the rounding of the product
        (~1e-7 in float32, ~1e-14 in float64, for unit-norm rows).
    """
    check_array("templates", templates, _FLOAT_DTYPES, 2)
    n_templates = templates.shape[0]
    if (previous is None) != (kept is None):
        raise ParameterError("template_gram: pass previous and kept together, or neither")
    if previous is None:
        kept = np.full(n_templates, -1, dtype=np.int64)
    else:
        check_array("previous", previous, (np.dtype(np.float64),), 2)
        if previous.shape[0] != previous.shape[1]:
            raise ParameterError(f"previous must be a square Gram, got shape {previous.shape}")
        check_array("kept", kept, (np.dtype(np.int64),), 1)
        check_length("kept", kept, n_templates, f"templates has {n_templates} rows")
        if kept.size and (kept.min() < -1 or kept.max() >= previous.shape[0]):
            raise ParameterError(f"kept must hold rows of previous (0..{previous.shape[0] - 1}) or -1")
    fresh = np.flatnonzero(kept < 0)
    stayed = np.flatnonzero(kept >= 0)
    new = np.ascontiguousarray(templates[fresh])
    old = np.ascontiguousarray(templates[stayed])
    products = {"new": np.empty((0, 0), dtype=templates.dtype),
                "stayed": np.empty((fresh.size, 0), dtype=templates.dtype)}

    def among_new() -> None:
        # numpy runs ``a @ a.T`` as a syrk (half the work of a product).
        products["new"] = new @ new.T

    def against_stayed() -> None:
        products["stayed"] = new @ old.T

    if fresh.size:
        _run_in_threads([among_new, against_stayed] if stayed.size else [among_new])
    gram = np.empty((n_templates, n_templates), dtype=np.float64)
    _assemble_gram(gram, previous if previous is not None else np.empty((0, 0)), kept, fresh, stayed,
                   products["new"], products["stayed"])
    return gram


@njit(**NUMBA_FLAGS)
def _nearest_row(dots_row, sq_norm, template_sq_norms, best_index, best_distance):
    """The ``k = len(best_index)`` nearest templates of one candidate, sorted, into the two rows.

    The output rows double as the candidate's sorted k-buffer (insertion), so no
    work buffer is needed.
    """
    k = best_index.shape[0]
    n_filled = 0
    for t in range(dots_row.shape[0]):
        distance = sq_norm + template_sq_norms[t] - 2.0 * dots_row[t]
        # Cancellation can make a true zero slightly negative; clamp so the
        # ranking and the reported value agree.
        if distance < 0.0:
            distance = 0.0
        # NaN sorts last (as +inf) so every slot is still filled.
        if not (distance <= np.inf):
            distance = np.inf
        if n_filled < k:
            position = n_filled
            n_filled += 1
        elif distance < best_distance[k - 1]:
            position = k - 1
        else:
            continue
        # Strict '>' keeps earlier (lower-index) templates ahead on ties.
        while position > 0 and best_distance[position - 1] > distance:
            best_distance[position] = best_distance[position - 1]
            best_index[position] = best_index[position - 1]
            position -= 1
        best_distance[position] = distance
        best_index[position] = t


@njit(**PARALLEL_FLAGS)
def _nearest_templates(dots, candidate_sq_norms, template_sq_norms, indices, sq_distances):
    for i in prange(dots.shape[0]):
        _nearest_row(dots[i], candidate_sq_norms[i], template_sq_norms, indices[i], sq_distances[i])


def nearest_templates(
    dots: np.ndarray,
    candidate_sq_norms: np.ndarray,
    template_sq_norms: np.ndarray,
    k: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest templates of every candidate in squared Euclidean distance.

    The distance is expanded as ``|y|^2 + |t|^2 - 2 y.t`` (clamped at 0), so
    only the precomputed inner products are read. Each candidate keeps a
    sorted buffer of its ``k`` best templates (insertion, ``O(n_templates k)``
    worst case) instead of sorting all distances.

    Parameters
    ----------
    dots : ndarray, shape (n_candidates, n_templates), float64
        Candidate-template inner products (:func:`candidate_template_dots`).
    candidate_sq_norms : ndarray, shape (n_candidates,), float64
        Squared norms of the candidates.
    template_sq_norms : ndarray, shape (n_templates,), float64
        Squared norms of the templates (e.g. the diagonal of :func:`template_gram`).
    k : int
        Number of neighbours, ``1 <= k <= n_templates``.

    Returns
    -------
    indices : ndarray, shape (n_candidates, k), int64
        Template indices sorted by ascending distance; ties are broken by the
        lower template index, so the result is deterministic (it equals a
        stable argsort of the distances, truncated to ``k``). NaN distances
        rank last.
    sq_distances : ndarray, shape (n_candidates, k), float64
        The matching squared distances, ascending.
    """
    check_array("dots", dots, (np.dtype(np.float64),), 2)
    check_array("candidate_sq_norms", candidate_sq_norms, (np.dtype(np.float64),), 1)
    check_array("template_sq_norms", template_sq_norms, (np.dtype(np.float64),), 1)
    n_candidates, n_templates = dots.shape
    check_length("candidate_sq_norms", candidate_sq_norms, n_candidates, f"dots has {n_candidates} rows")
    check_length("template_sq_norms", template_sq_norms, n_templates, f"dots has {n_templates} columns")
    k = check_int("k", k, 1, n_templates)
    indices = np.empty((n_candidates, k), dtype=np.int64)
    sq_distances = np.empty((n_candidates, k), dtype=np.float64)
    _nearest_templates(dots, candidate_sq_norms, template_sq_norms, indices, sq_distances)
    return indices, sq_distances
