"""Re-detection (*ours*; ``redetect_count`` = 0 is the paper): a wider search on a frame where
the target looks like nothing the positives hold, or holds it only weakly.

On a frame whose best candidate's eps_pos* is at least ``redetect_trigger`` (0.15: weakly
recognised, or not at all), ``redetect_count`` more candidates are drawn around the previous
estimate with ``redetect_factor`` times the translation noise and coded on the same templates;
one counts only if its eps_pos < ``redetect_accept`` (a wide search would otherwise jump to
whatever the negatives rank well, such as another player). On a weakly recognised frame
(eps_pos* below :data:`REDETECT_TRIGGER`) it must also lie within ``redetect_weak_radius``
target sizes of the estimate and be recognised under ``redetect_weak_accept`` (the update
gate): there the target is likely near, and a slide onto the background is the risk. The
counted candidates join the particles the next frame resamples. Chosen on the development set:
docs/findings/round-09-redetection-and-colour.md (the search),
docs/findings/round-51-weak-search-takes-only-recognised-finds.md (the weak trigger).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from nrmlc.geometry import state_to_box

#: eps_pos* at or above which the best candidate's code puts no weight on a positive template
#: (1 up to rounding): the search's only trigger before round 51 (the ``paper`` preset's
#: ``redetect_trigger``); below it a searched frame is weakly recognised.
REDETECT_TRIGGER = 0.99


def needs_search(params, best_error_positive: float) -> bool:
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
    coding : nrmlc.tracker.algorithm.Coding
        What :meth:`NRMLCTracker.encode` gave for the particles' patches.

    Returns
    -------
    states (n + r, 6) and their Coding (n + r candidates), with r = ``redetect_count``. A search
    candidate whose eps_pos is not below ``redetect_accept`` (on a weakly recognised frame, also
    one farther than ``redetect_weak_radius`` or not below ``redetect_weak_accept``) gets
    log h = -inf: it can be neither the estimate nor resampled.
    """
    p = tracker.params
    extra = tracker.diffuse(np.tile(tracker.state, (p.redetect_count, 1)), p.redetect_factor)
    extra_coding = tracker.encode(tracker.patches(frame, extra))
    accepted = extra_coding.error_positive < p.redetect_accept
    best = int(np.argmax(coding.log_confidence))
    if coding.error_positive[best] < REDETECT_TRIGGER:
        # A weakly recognised frame: the target is likely near, a look-alike farther (round 47),
        # and the finds that held a target were recognised under the update gate (round 51).
        box = state_to_box(tracker.state, p.patch_size)
        reach = p.redetect_weak_radius * np.sqrt(box[2] * box[3])
        accepted &= np.hypot(*(extra[:, :2] - tracker.state[:2]).T) <= reach
        accepted &= extra_coding.error_positive < p.redetect_weak_accept
    unrecognised = tracker.frames_unrecognised
    if tracker.peer is not None:  # a held target one expert still recognises is not lost
        unrecognised = min(unrecognised, tracker.peer.frames_unrecognised)
    if p.redetect_global > 0 and unrecognised >= p.redetect_global_after:
        # Lost for a while: the target may be anywhere, so candidates over the whole frame, and
        # only a find recognised under their own gate counts (round 73).
        whole = whole_frame_states(tracker, p.redetect_global)
        whole_coding = tracker.encode(tracker.patches(frame, whole))
        extra = np.vstack([extra, whole])
        extra_coding = extra_coding.joined(whole_coding)
        accepted = np.concatenate([accepted, whole_coding.error_positive < p.redetect_global_accept])
    extra_coding = dataclasses.replace(extra_coding, log_confidence=np.where(
        accepted, extra_coding.log_confidence, -np.inf))
    return np.vstack([states, extra]), coding.joined(extra_coding)


def whole_frame_states(tracker, n: int) -> np.ndarray:
    """(n, 6) states centred uniformly over the frame at the last recognised estimate's shape
    (``recognised_state``), diffused by the motion model (``redetect_global``), drawn from the
    search's own generator."""
    height, width = tracker.frame_shape
    states = np.tile(tracker.recognised_state, (n, 1))
    states[:, 0] = tracker.search_rng.uniform(0.0, width - 1.0, n)
    states[:, 1] = tracker.search_rng.uniform(0.0, height - 1.0, n)
    return tracker.diffuse(states, rng=tracker.search_rng)
