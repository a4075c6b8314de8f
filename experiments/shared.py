"""What several experiment scripts share, beyond the grid (:mod:`experiments.grid`) and the
formatting (:mod:`experiments.tables`): no script imports another script.

- :func:`plain_params`: lambda = beta = 0 (Fig. 4's red line, the ablations' plain row);
- :data:`TRIAL_VALUES`: the trial value of each numeric extension (the ablations' rows, the
  bench's generative-term row);
- :func:`blocks`, :data:`ON_TARGET_IOU`, :func:`lock_lost_at` (:func:`first_run_below`): the sequence blocks and the
  loss-of-lock and on-target rules of the failure measures (the failure mechanisms, the
  oracle gate, the scale likelihood, the development evaluation);
- :data:`STATS_SYNTHETIC_BUDGET`, :data:`STATS_REAL_BUDGET`, :func:`stats_runs`: the recorded
  internals of the non-negativity statistics, which Fig. 2 reads too.

Library modules of the experiments, used by several scripts on purpose:
:mod:`experiments.internals` (recorded tracker internals and the closed-form solvers) and
:mod:`experiments.peers` (the live OpenCV trackers and the shipped peer results).
"""
from __future__ import annotations

import numpy as np

from experiments.internals import Budget, budget_for, collections_for, limit


def plain_params(base):
    """lambda = beta = 0 as the 'plain' coder (shared by Fig. 4 and the ablations, so it runs once)."""
    return base.replace(coding="plain", lam=0.0, beta=0.0)


#: Numeric extensions beyond the paper, and lineage values, with a trial value each: a row each
#: when the default has the paper's (off) value. Their screening on the development sequences,
#: which chose the defaults, is in docs/FINDINGS.md.
TRIAL_VALUES = {"negative_push": 0.5, "generative_weight": 10.0}


#: Loss of lock: IoU below this ...
LOST_IOU = 0.1
#: ... on this many consecutive annotated frames.
LOST_RUN = 10
#: The gate shut on the target: frames with at least this IoU count as holding the target.
ON_TARGET_IOU = 0.5


def blocks(context) -> list[tuple[str, list]]:
    """(block label, sequences): the paper's given sequences, then the development ones (the
    given sequences when neither set is among them)."""
    out = [("paper's sequences" if not context.is_synthetic else "synthetic suite", context.paper_sequences())]
    if context.development_sequences():
        out.append(("development sequences", context.development_sequences()))
    out = [(label, list(seqs)) for label, seqs in out if seqs]
    # Neither set given (``--sequences`` named others): the given ones, rather than nothing.
    return out or [("other sequences", context.sequences())]


def lock_lost_at(overlaps, frames, iou: float = LOST_IOU, run: int = LOST_RUN) -> int | None:
    """The first frame that starts ``run`` consecutive evaluated frames with IoU < ``iou``.

    Parameters
    ----------
    overlaps : (n,) float
        IoU of the evaluated (annotated) frames, in order.
    frames : (n,) int
        Their 0-based frame indices.

    Returns
    -------
    int or None
        That frame's index, or None when no such run exists.
    """
    return first_run_below(overlaps, frames, iou, run)


def first_run_below(values, frames, below: float, run: int = LOST_RUN) -> int | None:
    """The first of ``frames`` (n,) that starts ``run`` consecutive ``values`` (n,) below ``below``,
    or None (:func:`lock_lost_at` on IoU; the development evaluation on the tracked scale)."""
    low = np.asarray(values, dtype=np.float64) < below
    if low.size < run:
        return None
    # Windows of `run` consecutive entries that are all low: a moving sum equal to `run`.
    counts = np.convolve(low.astype(np.int64), np.ones(run, dtype=np.int64), mode="valid")
    hits = np.flatnonzero(counts == run)
    return int(np.asarray(frames)[hits[0]]) if hits.size else None


#: Sampling budgets of the non-negativity statistics' recorded internals (synthetic, real data).
STATS_SYNTHETIC_BUDGET = Budget(max_frames=None, every=5, n_candidates=100)
STATS_REAL_BUDGET = Budget(max_frames=100, every=5, n_candidates=100)


def stats_runs(context) -> list:
    """The recorded internals of the non-negativity statistics (one collection per given sequence)."""
    budget = budget_for(context, STATS_SYNTHETIC_BUDGET, STATS_REAL_BUDGET)
    return collections_for(context, limit(context.sequences(), budget), budget)
