"""Tracker internals for the Sec. 3.3 analysis scripts (Theorem 1, Figs. 1, 2, statistics, occlusion).

Two things live here:

* :class:`Collection` (a job of the run cache) and :func:`collect_many`: run the
  tracker (the 'paper' preset, one seed) over the first frames of a sequence and, at sampled frames, record
  what the coding step saw: for a subset of the candidates the Gram
  ``G = A'A`` of ``A = B - y 1'`` over the candidate's ``N_NEAREST`` nearest
  templates (the tracker's ``k_max`` neighbours first, in the tracker's order,
  so the leading ``k x k`` block of ``G`` is exactly the ``B^j`` of size ``k``),
  element statistics of ``A``, the tracker's own codes, and the mean value of
  every template and candidate. Results are cached on disk (atomic ``.npz``),
  keyed by the sequence, the parameters, the seed, the sampling budget, the
  collector version and :func:`nrmlc.workbench.version.code_version`.
* numpy solvers of the paper's closed forms (:func:`ridge_inverse`,
  :func:`sum_to_one_codes`, :func:`dictionary_weights`, :func:`strictly_dd`),
  used to re-solve the *same* candidates for every lambda.

Sampling budget: :class:`Budget`, one default per script for synthetic and for
real data; ``context.analysis_budget`` overrides it (what the tests do).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from nrmlc.workbench.jobs import TrackerJob
from nrmlc.tracker.params import TrackerParams

#: Bump when the recorded content changes (invalidates the collection cache).
COLLECTOR_VERSION = 3

#: Nearest templates recorded per candidate (k_max = 10 of the tracker, plus
#: more for the randomised counterexample search of theorem1_checks).
N_NEAREST = 16

#: lambda values of the paper's Fig. 4 / Sec. 4.2 sweep.
LAMBDAS = (0.0, 0.01, 0.1, 0.5, 0.8, 1.0, 5.0, 10.0)

#: Paper's estimates (Sec. 3.3): a_ij in (-0.001, 0.003); (A'A)_ij <= 0.01.
PAPER_A_RANGE = (-0.001, 0.003)
PAPER_GRAM_BOUND = 0.01


@dataclass(frozen=True)
class Budget:
    """How much of each sequence the analysis scripts look at.

    Attributes
    ----------
    max_frames : int or None
        Track only the first this many frames of each sequence (None: all).
    every : int
        Record tracker internals every this many frames (frames every, 2 every, ...).
    n_candidates : int
        Candidates recorded per sampled frame (random ones plus the best).
    max_sequences : int or None
        Use at most this many sequences (None: all given).
    seeds : tuple of int or None
        Seeds of tracking runs (None: the script's choice from the context).
    n_particles : int or None
        Override the tracker's particle count (None: its parameters').
    """

    max_frames: int | None = 100
    every: int = 5
    n_candidates: int = 100
    max_sequences: int | None = None
    seeds: tuple | None = None
    n_particles: int | None = None

    def describe(self) -> str:
        frames = "all frames" if self.max_frames is None else f"the first {self.max_frames} frames"
        return (f"{frames} of each sequence tracked, internals recorded every {self.every}th frame, "
                f"{self.n_candidates} random candidates (plus the best) per recorded frame")


def budget_for(context, synthetic: Budget, real: Budget) -> Budget:
    """The budget to use: ``context.analysis_budget`` if set (the tests), else the script's
    default for synthetic or real data; the context's frame cap (``--max-frames``) applies."""
    chosen = getattr(context, "analysis_budget", None)
    if chosen is None:
        chosen = synthetic if context.is_synthetic else real
    cap = getattr(context, "max_frames", None)
    if cap is not None:
        chosen = replace(chosen, max_frames=int(cap) if chosen.max_frames is None else min(int(cap), chosen.max_frames))
    return chosen


def tracker_params(budget: Budget, context=None, **changes) -> TrackerParams:
    """The 'paper' preset (these scripts test the paper's own claims; ``--param`` changes
    apply), with the budget's particle count and ``changes``."""
    params = context.paper_params() if context is not None else TrackerParams.paper()
    if budget.n_particles is not None:
        changes.setdefault("n_particles", int(budget.n_particles))
    return params.replace(**changes) if changes else params


def limit(sequences: list, budget: Budget) -> list:
    return list(sequences) if budget.max_sequences is None else list(sequences)[: budget.max_sequences]


# --------------------------------------------------------------------------- collection
def sampled_frames(n_frames: int, every: int, update_interval: int) -> list[int]:
    """Frames ``every, 2 every, ...`` below ``n_frames``, each moved forward by one if
    the tracker updates its templates right after it (so the recorded templates
    are the ones the candidates were coded on)."""
    chosen = []
    for index in range(every, n_frames, every):
        if (index + 1) % update_interval == 0:
            index += 1
        if index < n_frames and (not chosen or index > chosen[-1]):
            chosen.append(index)
    return chosen


def _record(tracker, frame_index: int, rng: np.random.Generator, n_record: int) -> dict | None:
    """Internals of the current frame's coding step (None if templates already changed)."""
    cand = tracker.last_coding
    # In a pair the templates are the first expert's: a frame the second expert won is then
    # skipped by the check below, as its coding was made on other templates.
    owner = tracker.experts[0] if hasattr(tracker, "experts") else tracker
    templates = owner.templates
    patches = cand.patches
    n_all = len(patches)
    best = int(np.argmax(cand.log_confidence))  # the estimate (step's arg max)
    pick = rng.choice(n_all, size=min(n_record, n_all), replace=False)
    pick = np.unique(np.concatenate([pick, [best]]))
    y = patches[pick].astype(np.float64)
    T = templates.astype(np.float64)
    dots = y @ T.T
    # The tracker's dots must be these: otherwise the templates were replaced after coding.
    if not np.allclose(dots, cand.dots[pick], rtol=0, atol=1e-5):
        return None
    n_pos = len(owner.positive_templates)
    k_max = cand.neighbours.shape[1]
    n_near = min(N_NEAREST, len(T))
    sq = np.einsum("ij,ij->i", T, T)
    distance = sq[None, :] - 2.0 * dots  # |y|^2 is constant per row
    tracker_nb = cand.neighbours[pick].astype(np.int64)
    rows = np.arange(len(pick))[:, None]
    distance[rows, tracker_nb] = -np.inf  # the tracker's neighbours come first, in its order
    order = np.argsort(distance, axis=1, kind="stable")[:, :n_near]
    neighbours = np.concatenate([tracker_nb, order[:, k_max:n_near]], axis=1)
    A = T[neighbours] - y[:, None, :]  # (r, n_near, 1024): columns of A as rows
    gram = np.einsum("rad,rbd->rab", A, A)
    A10 = A[:, :k_max, :].reshape(len(pick), -1)
    sample = np.take_along_axis(A10, rng.integers(0, A10.shape[1], size=(len(pick), 32)), axis=1)
    template_means = templates.mean(axis=1)
    return dict(
        frame=np.int64(frame_index), n_pos=np.int64(n_pos), n_templates=np.int64(len(T)),
        gram=gram, neighbours=neighbours.astype(np.int16), positive=(neighbours < n_pos),
        is_best=(pick == best), a_min=A10.min(axis=1), a_max=A10.max(axis=1),
        a_sample=sample.astype(np.float32),
        coefficients=cand.coefficients[pick].astype(np.float64), weights=cand.weights[pick].astype(np.float64),
        candidate_means=patches.mean(axis=1).astype(np.float32),
        best_mean=np.float32(patches[best].mean()),
        template_means=template_means.astype(np.float32),
        template_positive=np.arange(len(T)) < n_pos,
    )


def _stack_records(records: list[dict]) -> dict:
    out = {}
    per_candidate = ("gram", "neighbours", "positive", "is_best", "a_min", "a_max", "a_sample",
                     "coefficients", "weights")
    counts = [len(r["is_best"]) for r in records]
    for name in per_candidate:
        out[name] = np.concatenate([r[name] for r in records])
    out["candidate_frame"] = np.repeat([r["frame"] for r in records], counts)
    out["frames"] = np.array([r["frame"] for r in records], dtype=np.int64)
    out["n_pos"] = np.array([r["n_pos"] for r in records], dtype=np.int64)
    out["candidate_means"] = np.stack([r["candidate_means"] for r in records])
    out["best_mean"] = np.array([r["best_mean"] for r in records])
    out["template_means"] = np.concatenate([r["template_means"] for r in records])
    out["template_positive"] = np.concatenate([r["template_positive"] for r in records])
    out["template_index"] = np.concatenate([np.arange(len(r["template_means"])) for r in records])
    out["template_frame"] = np.repeat(out["frames"], [len(r["template_means"]) for r in records])
    return out


@dataclass(frozen=True)
class Collection(TrackerJob):
    """Track a sequence and record the coding step's internals at sampled frames.

    A job of :class:`nrmlc.workbench.run_cache.RunCache` (stored under ``<cache>/analysis/``),
    keyed by the sequence, the parameters, the seed, the sampling budget, the
    collector version and the code version.
    """

    budget: Budget

    folder: ClassVar[str] = "analysis"
    label_template: ClassVar[str] = "internals of {job.sequence.name}"

    def frame_cap(self) -> int | None:
        return self.budget.max_frames

    def description(self, version: str) -> dict:
        return self.tracker_description(version, max_frames=self.budget.max_frames, every=self.budget.every,
                                        n_candidates=self.budget.n_candidates, collector=COLLECTOR_VERSION,
                                        n_nearest=N_NEAREST)

    def execute(self) -> dict:
        from experiments.instrumented import track_instrumented

        sequence, params, seed, budget = self.sequence, self.params, self.seed, self.budget
        n_frames = self.frames()
        wanted = set(sampled_frames(n_frames, budget.every, params.update_interval))
        rng = np.random.default_rng([int(seed), 7919])
        records = []

        def record(index, tracker, frame):
            if index in wanted:
                found = _record(tracker, index, rng, budget.n_candidates)
                if found is not None:
                    records.append(found)

        run = track_instrumented(sequence, params, seed=seed, n_frames=n_frames, on_frame=record)
        if not records:
            raise RuntimeError(f"{sequence.name}: no frame recorded (n_frames={n_frames}, every={budget.every})")
        arrays = _stack_records(records)
        arrays["boxes"] = run.boxes
        arrays["seconds"] = np.float64(run.seconds_total)
        arrays["n_tracked"] = np.int64(n_frames)
        return arrays

    def result(self, arrays: dict) -> dict:
        return dict(arrays, name=self.sequence.name)


def collections_for(context, sequences: list, budget: Budget, seed: int = 0,
                    params: TrackerParams | None = None) -> list[Collection]:
    """The collection jobs of :func:`collect_many` (for ``runs(context)``)."""
    params = params if params is not None else tracker_params(budget, context)
    return [Collection(s, params, int(seed), budget) for s in sequences]


def collect_many(context, sequences: list, budget: Budget, seed: int = 0,
                 params: TrackerParams | None = None) -> list[dict]:
    """Recorded internals of each sequence (cached in the run cache; missing ones computed
    in the context's pool)."""
    jobs = collections_for(context, sequences, budget, seed, params)
    return context.cache.run(jobs, executor=context.executor, jobs=context.jobs)


def pooled(collections: list[dict], name: str) -> np.ndarray:
    return np.concatenate([c[name] for c in collections])


# --------------------------------------------------------------------------- solvers
def ridge_inverse(gram, lam: float) -> np.ndarray:
    """``(G + lam I)^{-1}`` for a batch of symmetric PSD ``G`` (..., k, k).

    Through the eigen-decomposition, so ``lam = 0`` with a singular ``G`` gives the
    pseudo-inverse (the ``lam -> 0+`` limit of the sum-to-one solution) instead of noise.
    ``gram`` may also be a precomputed ``np.linalg.eigh(G)`` pair (reused across lambdas).
    """
    values, vectors = gram if isinstance(gram, tuple) else np.linalg.eigh(gram)
    values = np.clip(values, 0.0, None) + lam
    scale = np.max(np.abs(values), axis=-1, keepdims=True)
    inv = np.where(values > 1e-13 * scale, 1.0 / np.where(values > 0, values, 1.0), 0.0)
    return (vectors * inv[..., None, :]) @ np.swapaxes(vectors, -1, -2)


def sum_to_one_codes(gram: np.ndarray, lam: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solutions of eq. (allcr) for a batch of Grams.

    Returns
    -------
    inverse : (..., k, k) ``F^{-1}``
    raw : (..., k) ``F^{-1} 1`` (the paper's printed solution)
    codes : (..., k) ``F^{-1} 1 / 1'F^{-1} 1`` (the sum-to-one solution; same signs)
    """
    inverse = ridge_inverse(gram, lam)
    raw = inverse.sum(axis=-1)
    codes = raw / raw.sum(axis=-1, keepdims=True)
    return inverse, raw, codes


def strictly_dd(matrix: np.ndarray) -> np.ndarray:
    """True where every row has |m_ii| > sum_{j != i} |m_ij| (batch over leading axes)."""
    absolute = np.abs(matrix)
    diagonal = np.diagonal(absolute, axis1=-2, axis2=-1)
    off = absolute.sum(axis=-1) - diagonal
    return np.all(diagonal > off, axis=-1)


def max_offdiag_row_sum(matrix: np.ndarray) -> np.ndarray:
    """max_i sum_{j != i} |m_ij|: the right-hand side of eq. (lambda) (without epsilon)."""
    absolute = np.abs(matrix)
    off = absolute.sum(axis=-1) - np.diagonal(absolute, axis1=-2, axis2=-1)
    return off.max(axis=-1)


def dictionary_weights(gram: np.ndarray, codes_by_size: list[np.ndarray], beta: float) -> np.ndarray:
    """w of eq. (allcw): ``(H + beta I)^{-1} 1`` normalised, with ``H = C' G C`` the Gram
    of ``D - y 1'`` (``D_j = B^j c^j``; the c^j live on the leading k_j neighbours).

    Parameters
    ----------
    gram : (n, k_max, k_max) ``A'A`` over the k_max nearest templates.
    codes_by_size : m arrays (n, k_j) of sum-to-one codes.
    beta : ridge on w.

    Returns
    -------
    w : (n, m)
    """
    n, k_max = gram.shape[0], gram.shape[-1]
    C = np.zeros((n, k_max, len(codes_by_size)))
    for j, codes in enumerate(codes_by_size):
        C[:, : codes.shape[1], j] = codes
    H = np.swapaxes(C, 1, 2) @ (gram @ C)
    return sum_to_one_codes(H, beta)[2]


__all__ = ["Budget", "Collection", "budget_for", "collect_many", "collections_for", "sum_to_one_codes", "strictly_dd",
           "dictionary_weights", "ridge_inverse", "max_offdiag_row_sum", "LAMBDAS", "N_NEAREST"]
