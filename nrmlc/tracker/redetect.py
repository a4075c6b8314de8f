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

from nrmlc.geometry import state_to_box

#: eps_pos* at or above which a frame runs the search: 1 up to rounding, i.e. the best
#: candidate's code puts no weight on a positive template.
REDETECT_TRIGGER = 0.99


def needs_search(params, best_error_positive: float) -> bool:
    """Whether this frame runs the search (it is on, and the best candidate uses no positive)."""
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
    candidate whose eps_pos is not below ``redetect_accept`` gets log h = -inf: it can be
    neither the estimate nor resampled.
    """
    p = tracker.params
    extra = tracker.diffuse(np.tile(tracker.state, (p.redetect_count, 1)), p.redetect_factor)
    extra_coding = tracker.encode(tracker.patches(frame, extra))
    accepted = extra_coding.error_positive < p.redetect_accept
    best = int(np.argmax(coding.log_confidence))
    if coding.error_positive[best] < REDETECT_TRIGGER:
        # A weakly recognised frame (round 47): the target is likely near, a look-alike farther.
        box = state_to_box(tracker.state, p.patch_size)
        reach = p.redetect_weak_radius * np.sqrt(box[2] * box[3])
        accepted &= np.hypot(*(extra[:, :2] - tracker.state[:2]).T) <= reach
        # Round 51: the finds that helped were recognised under the update gate; Suv's slide was not.
        accepted &= extra_coding.error_positive < p.redetect_weak_accept
    extra_coding = dataclasses.replace(extra_coding, log_confidence=np.where(
        accepted, extra_coding.log_confidence, -np.inf))
    return np.vstack([states, extra]), coding.joined(extra_coding)
