"""Re-detection (*ours*; ``redetect_count`` = 0 is the paper): a wider search on a frame where
the target looks like nothing the positives hold.

On a frame whose best candidate's code puts no weight on a positive template (eps_pos* = 1),
``redetect_count`` more candidates are drawn around the previous estimate with
``redetect_factor`` times the translation noise and coded on the same templates; one counts only
if its eps_pos < ``redetect_accept`` (a wide search would otherwise jump to whatever the
negatives rank well, such as another player). They join the particles the next frame resamples.
Chosen on the development set: docs/findings/round-09-redetection-and-colour.md.
"""
from __future__ import annotations

import dataclasses

import numpy as np

#: eps_pos* at or above which a frame runs the search: 1 up to rounding, i.e. the best
#: candidate's code puts no weight on a positive template.
REDETECT_TRIGGER = 0.99


def needs_search(params, best_error_positive: float, best_error_negative: float,
                 previous_error_positive: float = 0.0) -> bool:
    """Whether this frame runs the search: it is on, and the best candidate uses no positive
    (or, under ``redetect_trigger = 'negative'``, looks more like the negatives; under
    'negative_after_recognised', that after a frame whose eps_pos* was under the update threshold,
    ``previous_error_positive``)."""
    if params.redetect_count == 0:
        return False
    if best_error_positive > best_error_negative and (
            params.redetect_trigger == "negative"
            or (params.redetect_trigger.startswith("negative_after_recognised")
                and previous_error_positive < params.update_error_threshold)):
        return True
    return best_error_positive >= REDETECT_TRIGGER


def quiet_search(params, best_error_positive: float) -> bool:
    """Whether this frame's search (:func:`needs_search` said it runs) is one only the quiet
    trigger runs: it then draws from its own generator and is undone unless it finds the estimate
    (under '..._quiet_strict', a find whose eps_pos is under ``update_error_threshold``)."""
    return (params.redetect_trigger.startswith("negative_after_recognised_quiet")
            and best_error_positive < REDETECT_TRIGGER)


def quiet_find_kept(params, found_error_positive: float) -> bool:
    """Whether a quiet search's find (a search candidate that would be the estimate) is kept:
    always under '..._quiet'; under '..._quiet_strict' only if it is recognised as well as a
    result that joins the positives (eps_pos < ``update_error_threshold``)."""
    if params.redetect_trigger == "negative_after_recognised_quiet_strict":
        return found_error_positive < params.update_error_threshold
    return True


def search(tracker, frame: np.ndarray, states: np.ndarray, coding, rng=None) -> tuple:
    """This frame's particles and their coding with the search's candidates appended.

    Parameters
    ----------
    tracker : nrmlc.tracker.algorithm.NRMLCTracker
        Its estimate, motion model, patches and coder are used.
    frame : (height, width) float32
    states : (n, 6) float64
    coding : nrmlc.tracker.algorithm.Coding
        What :meth:`NRMLCTracker.encode` gave for the particles' patches.
    rng : numpy.random.Generator, optional
        The generator of the search's draws (default: the tracker's).

    Returns
    -------
    states (n + r, 6) and their Coding (n + r candidates), with r = ``redetect_count``. A search
    candidate whose eps_pos is not below ``redetect_accept`` gets log h = -inf: it can be
    neither the estimate nor resampled.
    """
    p = tracker.params
    extra = tracker.diffuse(np.tile(tracker.state, (p.redetect_count, 1)), p.redetect_factor, rng)
    accept = np.full(len(extra), p.redetect_accept)
    if p.redetect_global > 0 and tracker.frames_unrecognised >= p.redetect_global_after:
        extra = np.vstack([extra, global_states(tracker, p.redetect_global, rng)])
        accept = np.concatenate([accept, np.full(p.redetect_global, p.redetect_global_accept)])
    extra_coding = tracker.encode(tracker.patches(frame, extra))
    extra_coding = dataclasses.replace(extra_coding, log_confidence=np.where(
        extra_coding.error_positive < accept, extra_coding.log_confidence, -np.inf))
    return np.vstack([states, extra]), coding.joined(extra_coding)


def global_states(tracker, n: int, rng=None) -> np.ndarray:
    """(n, 6) states centred uniformly over the frame at the last recognised estimate's shape,
    diffused by the motion model (``redetect_global``); ``rng`` as in :func:`search`."""
    rng = tracker.rng if rng is None else rng
    height, width = tracker.frame_shape
    states = np.tile(tracker.recognised_state, (n, 1))
    states[:, 0] = rng.uniform(0.0, width - 1.0, n)
    states[:, 1] = rng.uniform(0.0, height - 1.0, n)
    return tracker.diffuse(states, rng=rng)
