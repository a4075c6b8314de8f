"""What the tracker computes: the coding of a frame's candidates (Algorithm 1 on each, and their
confidence) and the per-frame result with its diagnostics."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: eps_pos* at or above which the best candidate's code puts no weight on a positive template
#: (1 up to rounding): the target looks like nothing the positives hold.
NO_POSITIVE_ERROR = 0.99


@dataclass(frozen=True)
class Coding:
    """Algorithm 1 on n candidates, and their confidence (what :meth:`NRMLCTracker.encode` gives).

    Attributes
    ----------
    patches : (n, patch_size**2) float32
        The candidates' unit-norm patch vectors y.
    dots : (n, n_templates) float64
        y . t for every template t of [T_pos, T_neg].
    neighbours : (n, k_max) int64
        Each candidate's k_max nearest templates (indices into [T_pos, T_neg]), nearest first;
        the first k_j of them are the local dictionary B^j.
    coefficients : (n, m, k_max) float64
        The code c^j on each of the m dictionaries (zero beyond k_j).
    weights : (n, m) float64
        The dictionary weights w.
    codes : (n, k_max) float64
        The output code d = sum_j w_j c^j on ``neighbours``.
    error_positive, error_negative : (n,) float64
        eps_pos and eps_neg: the squared error of y against the positive / negative part of d.
    log_confidence : (n,) float64
        log h (with the generative term when it is on; -inf where a re-detection candidate
        is refused).
    similarity : (n,) float64 or None
        The generative term's similarity (None when the term is off).
    """

    patches: np.ndarray
    dots: np.ndarray
    neighbours: np.ndarray
    coefficients: np.ndarray
    weights: np.ndarray
    codes: np.ndarray
    error_positive: np.ndarray
    error_negative: np.ndarray
    log_confidence: np.ndarray
    similarity: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.log_confidence)

    def joined(self, other: "Coding") -> "Coding":
        """This coding with ``other``'s candidates appended."""
        def join(a, b):
            return None if a is None or b is None else np.concatenate([a, b])
        return Coding(**{f: join(getattr(self, f), getattr(other, f)) for f in self.__dataclass_fields__})



@dataclass
class FrameResult:
    """What the tracker computed on one frame (the per-frame diagnostics).

    Attributes
    ----------
    state : (6,) float64, box : (4,) float64
        Estimate (state) and its 1-based OTB box.
    confidence : float
        h of the best candidate (``exp(log_confidence)``; may be inf for a huge alpha).
    log_confidence : float
        log h of the best candidate.
    error_positive, error_negative : float
        eps_pos*, eps_neg* of the best candidate (squared errors of unit vectors).
    template_indices : (k_max,) int64
        The best candidate's nearest templates (indices into [T_pos, T_neg]).
    codes : (k_max,) float64
        Its output code d on those templates (zero elsewhere).
    coefficients : (m, k_max) float64, weights : (m,) float64
        Its per-dictionary codes c^j and dictionary weights w.
    n_positive_templates, n_templates : int
        Template counts at this frame (indices < n_positive_templates are positive).
    n_negative_used : int
        LEN(neg*): negative templates with a non-zero code.
    occluded : bool
        LEN(neg*) > occlusion_max_negative.
    code_sum_positive, code_sum_negative : float
        Sums of the best candidate's codes on positive / negative templates.
    updated_positive : bool
        Whether this frame's result was added to the positive templates.
    redetect_searched, redetected : bool
        Whether this frame ran the re-detection search (``redetect_count``), and whether
        its estimate came from it.
    expert : int
        Which expert's estimate this is: 0 alone or the first of a pair, 1 the second
        (:class:`nrmlc.tracker.experts.ExpertPair`; every field above is then that expert's).
    """

    state: np.ndarray
    box: np.ndarray
    confidence: float
    log_confidence: float
    error_positive: float
    error_negative: float
    template_indices: np.ndarray
    codes: np.ndarray
    coefficients: np.ndarray
    weights: np.ndarray
    n_positive_templates: int
    n_templates: int
    n_negative_used: int
    occluded: bool
    code_sum_positive: float
    code_sum_negative: float
    updated_positive: bool = False
    redetect_searched: bool = False
    redetected: bool = False
    expert: int = 0
