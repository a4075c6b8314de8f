"""Re-detection (*ours*; ``redetect_count = 0`` is the paper): a wider search on a frame where
the target looks like nothing the positives hold, or holds it only weakly.

It plugs into :meth:`nrmlc.tracker.algorithm.NRMLCTracker.step` as a second source of candidates.
On a frame whose best candidate's eps_pos* is at least ``redetect_trigger``, ``redetect_count``
more candidates are drawn around the previous estimate with ``redetect_factor`` times the
translation noise and coded on the same templates. One counts only if its eps_pos <
``redetect_accept``: a wide search would otherwise jump to whatever the negatives rank well,
such as another player. On a weakly recognised frame (the code still uses a positive) it must
also lie within ``redetect_weak_radius`` target sizes of the estimate and be recognised under
``redetect_weak_accept`` (the update gate): there the target is likely near, and a slide onto the
background is the risk. The counted candidates join the particles the next frame resamples.
Evidence: docs/DEVIATIONS.md.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from nrmlc.geometry import state_to_box
from nrmlc.tracker.parameter_fields import CheckedParams, bounded
from nrmlc.tracker.records import NO_POSITIVE_ERROR

#: Most candidates a frame can code (100,000 are 400 MB of patches).
MAX_CANDIDATES = 100_000


@dataclass(frozen=True)
class RedetectionParams(CheckedParams):
    """The re-detection's parameters (:mod:`nrmlc.tracker.redetect`).

    Attributes
    ----------
    redetect_count : int
        Search candidates per searched frame (0: no search, the paper).
    redetect_factor : float
        Their translation noise, in multiples of the motion model's.
    redetect_accept : float
        A search candidate counts only where its eps_pos is below this.
    redetect_trigger : float
        The search runs on a frame whose best candidate's eps_pos* is at least this: 0.99 only
        where the code uses no positive; 0.15 also where it uses them weakly.
    redetect_weak_radius : float
        On a weakly recognised frame, a search candidate counts only within this many target
        sizes (sqrt(w h) of the estimate) of the estimate (100: no limit).
    redetect_weak_accept : float
        On a weakly recognised frame, a search candidate counts only if its eps_pos is also below
        this (1: only ``redetect_accept``).
    """

    redetect_count: int = bounded(300, 0, MAX_CANDIDATES)
    redetect_factor: float = bounded(4.0, 1, 100)
    redetect_accept: float = bounded(0.3, 0, 1, low_open=True)
    redetect_trigger: float = bounded(0.15, 0, 1, low_open=True)
    redetect_weak_radius: float = bounded(1.0, 0, 100, low_open=True)
    redetect_weak_accept: float = bounded(0.1, 0, 1, low_open=True)


def needs_search(params: RedetectionParams, best_error_positive: float) -> bool:
    """Whether this frame runs the search (it is on, and the best candidate's eps_pos* reaches
    ``redetect_trigger``)."""
    return params.redetect_count > 0 and best_error_positive >= params.redetect_trigger


def search(tracker, frame: np.ndarray, states: np.ndarray, coding) -> tuple:
    """This frame's particles and their coding with the search's candidates appended.

    Parameters
    ----------
    tracker : nrmlc.tracker.algorithm.NRMLCTracker
        Its estimate, motion model, patches and coder are used.
    frame : (height, width) float32
    states : (n, 6) float64
    coding : nrmlc.tracker.records.Coding
        What :meth:`NRMLCTracker.encode` gave for the particles' patches.

    Returns
    -------
    states (n + r, 6) and their Coding (n + r candidates), with r = ``redetect_count``. A search
    candidate that does not count gets log h = -inf: it can be neither the estimate nor resampled.
    """
    p = tracker.params
    extra = tracker.diffuse(np.tile(tracker.state, (p.redetect_count, 1)), p.redetect_factor)
    extra_coding = tracker.encode(tracker.patches(frame, extra))
    accepted = extra_coding.error_positive < p.redetect_accept
    best = int(np.argmax(coding.log_confidence))
    if coding.error_positive[best] < NO_POSITIVE_ERROR:
        box = state_to_box(tracker.state, p.patch_size)
        reach = p.redetect_weak_radius * np.sqrt(box[2] * box[3])
        accepted &= np.hypot(*(extra[:, :2] - tracker.state[:2]).T) <= reach
        accepted &= extra_coding.error_positive < p.redetect_weak_accept
    extra_coding = dataclasses.replace(extra_coding, log_confidence=np.where(
        accepted, extra_coding.log_confidence, -np.inf))
    return np.vstack([states, extra]), coding.joined(extra_coding)
