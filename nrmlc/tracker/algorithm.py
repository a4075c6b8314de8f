"""The NRMLC tracker (Algorithms 1 and 2 of the paper).

Per frame:

1. propagate the particles (eq. 1): resample last frame's particles in proportion to
   their confidence and diffuse them with the Gaussian motion model (``propagation=
   'condensation'``, IVT's ``estwarp_condens.m``), or draw them all around the previous
   estimate (``'best'``); keep them inside the frame (:func:`nrmlc.geometry.clamp_states`);
2. warp them into unit-norm 32x32 patch vectors (:mod:`nrmlc.kernels.warp`);
3. find each candidate's ``k_max`` nearest templates among ``[T_pos, T_neg]``
   (:mod:`nrmlc.kernels.distance`), which gives the nested local dictionaries
   B^1..B^m of sizes k_1..k_m;
4. code the candidate on each dictionary (approximated LLC, eq. allcr / allcn / allc)
   and combine the codes with dictionary weights w (Algorithm 1, eq. allcw)
   (:mod:`nrmlc.kernels.coding`);
5. score each candidate with log h = -alpha (eps_pos - eps_neg) (in the log domain, so
   no alpha overflows); the estimate is the most confident candidate. If the best
   candidate's code uses no positive template, first re-detect (*ours*, ``redetect_count``):
   code a wider search around the previous estimate, whose candidates count only where
   eps_pos < ``redetect_accept``. With ``generative_weight`` > 0 (*ours*, the default; 0
   in the paper preset), log h also gains SCM's local-patch similarity
   (:mod:`nrmlc.tracker.generative`);
6. every ``update_interval`` frames, resample the negative templates around the
   estimate and, unless the target is judged occluded (LEN(neg*) too large),
   add the result to the positive templates when eps_pos* < threshold;
7. with a second expert (*ours*, ``second_expert``; off in the paper, on by default since round
   64), a second tracker with an update every frame (or the lineage's motion model) does steps
   1-6 on its own, and the frame's output is the estimate of the one whose running average of
   eps_pos* is lower; where the two experts' boxes agree (IoU >= ``expert_blend_iou``), their
   blend (round 76); on a frame neither expert recognises (eps_pos* >= ``unrecognised_gate``),
   the output's size moves toward the last recognised output's (round 77).
"""
from __future__ import annotations

import contextlib
import dataclasses
import threading
from dataclasses import dataclass

import numpy as np

from nrmlc.data.image import as_gray_frame
from nrmlc.errors import ParameterError
from nrmlc.geometry import (MIN_BOX_SIZE, as_box, box_iou, box_to_state, clamp_states, clip_initial_box,
                            state_to_affine, state_to_box, usable_boxes)
from nrmlc.kernels.coding import code_candidates
from nrmlc.kernels.distance import candidate_template_dots, template_gram
from nrmlc.kernels.warp import warp_patches
from nrmlc.tracker.generative import LocalHistogramModel
from nrmlc.tracker.params import TrackerParams
from nrmlc.tracker.redetect import REDETECT_TRIGGER, needs_search, search
from nrmlc.tracker.templates import (SCM_PUSH_INIT, SCM_PUSH_UPDATE, negative_states, positive_states,
                                     scm_negative_states, scm_positive_states)

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


def negative_shares(coding: Coding, dictionary_sizes) -> tuple[float, float]:
    """(share of negative entries among all candidates' c, within each k_j; share among their w):
    the non-negativity diagnostics of the ablation table and ``stats_nonnegativity``."""
    sizes = np.asarray(dictionary_sizes)
    within = np.arange(coding.coefficients.shape[2])[None, :] < sizes[:, None]  # (m, k_max)
    return float(np.mean(coding.coefficients[:, within] < 0)), float(np.mean(coding.weights < 0))


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
        Whose estimate this is: 0 the tracker's own, 1 its second expert's
        (``second_expert``; every field above is then the second expert's).
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


def choose_expert(average: np.ndarray, errors: np.ndarray, memory: float) -> tuple[np.ndarray, int]:
    """One frame of the second expert's choice (``second_expert``).

    Parameters
    ----------
    average : (2,) float64
        Each expert's running average of eps_pos* (own, second) before this frame; 0 at the first.
    errors : (2,) float64
        This frame's eps_pos* of each expert's estimate.
    memory : float
        The weight of the past (``expert_memory``), in [0, 1).

    Returns
    -------
    average : (2,) float64
        ``memory * average + (1 - memory) * errors``.
    chosen : int
        1 where the second expert's average is strictly lower, else 0 (the own one on a tie).
    """
    average = memory * average + (1.0 - memory) * errors
    return average, int(average[1] < average[0])


def blend_experts(boxes: np.ndarray, errors: np.ndarray, min_iou: float) -> np.ndarray | None:
    """The blend of the two experts' boxes where they agree (``expert_blend_iou``): two estimates
    of one box whose errors are partly independent, so their mean is nearer the truth than either
    (round 76).

    Parameters
    ----------
    boxes : (2, 4) float64
        The own and the second expert's boxes ``x, y, w, h`` (w, h > 0).
    errors : (2,) float64
        This frame's eps_pos* of each (>= 0).
    min_iou : float
        The least IoU of the two boxes that blends them; 1 never blends.

    Returns
    -------
    box : (4,) float64 or None
        None where the boxes overlap less than ``min_iou``; else the centre the weighted mean of
        the two centres and the width and height the weighted geometric means, the second
        expert's weight ``errors[0] / errors.sum()`` (the better recognised one weighs more; one
        half where both are 0).
    """
    if min_iou >= 1 or box_iou(boxes[0], boxes[1]) < min_iou:
        return None
    total = errors[0] + errors[1]
    weight = 0.5 if total <= 0 else errors[0] / total
    weights = np.array([1.0 - weight, weight])
    centres = boxes[:, :2] + boxes[:, 2:] / 2
    return _box_around(weights @ centres, np.exp(weights @ np.log(boxes[:, 2:])))


def held_size(box: np.ndarray, recognised_log_size: np.ndarray, share: float) -> np.ndarray:
    """The output on a frame where neither expert recognises the target
    (``unrecognised_size_share``): a lost tracker's box drifts small, and the size last recognised
    is the best it has (round 77).

    Parameters
    ----------
    box : (4,) float64
        The experts' output ``x, y, w, h`` (w, h > 0).
    recognised_log_size : (2,) float64
        log(w), log(h) of the last output whose frame an expert recognised.
    share : float
        How far the log width and height move toward ``recognised_log_size``, in [0, 1].

    Returns
    -------
    box : (4,) float64
        The same centre; width and height ``exp(log size + share * (recognised - log size))``.
    """
    log_size = np.log(box[2:])
    return _box_around(box[:2] + box[2:] / 2, np.exp(log_size + share * (recognised_log_size - log_size)))


def experts_output(boxes: np.ndarray, errors: np.ndarray, chosen: int, recognised_log_size: np.ndarray,
                   params: TrackerParams) -> tuple[np.ndarray, np.ndarray, bool]:
    """What the pair reports on a frame (``second_expert``): the chosen expert's box, or the two's
    blend where they agree (:func:`blend_experts`); where neither expert's eps_pos* is under
    ``unrecognised_gate``, with its size moved toward the last recognised output's (:func:`held_size`).
    The tracker and its offline rebuild (``experiments/development/expert_choice.py``) both report through it.

    Parameters
    ----------
    boxes : (2, 4) float64
        The own and the second expert's boxes ``x, y, w, h`` (w, h > 0).
    errors : (2,) float64
        This frame's eps_pos* of each.
    chosen : int
        The expert :func:`choose_expert` chose, 0 (own) or 1.
    recognised_log_size : (2,) float64
        log(w), log(h) of the last output whose frame an expert recognised.
    params : TrackerParams
        Its ``expert_blend_iou``, ``unrecognised_gate`` and ``unrecognised_size_share``.

    Returns
    -------
    box : (4,) float64
        The output.
    recognised_log_size : (2,) float64
        The output's log size where an expert recognises the target; else the one given.
    moved : bool
        Whether ``box`` is the blend or a held size rather than ``boxes[chosen]``.
    """
    box = blend_experts(boxes, errors, params.expert_blend_iou)
    moved = box is not None
    if box is None:
        box = boxes[chosen]
    if errors.min() < params.unrecognised_gate:
        return box, np.log(box[2:]), moved
    if params.unrecognised_size_share > 0:
        return held_size(box, recognised_log_size, params.unrecognised_size_share), recognised_log_size, True
    return box, recognised_log_size, moved


def _box_around(centre: np.ndarray, size: np.ndarray) -> np.ndarray:
    """The box ``x, y, w, h`` (4,) of ``centre`` (2,) and ``size`` (2,)."""
    return np.concatenate([centre - size / 2, size])


def _exp_or_inf(value: float) -> float:
    """exp(value) for reporting h, inf instead of an overflow warning."""
    return float("inf") if value > 709.0 else float(np.exp(value))


class NRMLCTracker:
    """NRMLC tracker with the got10k Tracker interface (``init`` / ``update``).

    Parameters
    ----------
    seed : int
        Seed of the tracker's random generator (templates and particles). The
        same seed gives the same boxes, whatever the thread count.
    params : TrackerParams, optional
        Full parameter set; keyword arguments override single fields.
    **overrides
        Any :class:`TrackerParams` field, e.g. ``n_particles=300, coding="constrained"``.

    Examples
    --------
    >>> tracker = NRMLCTracker(seed=0)
    >>> tracker.init(first_frame, (x, y, w, h))
    >>> box = tracker.update(next_frame)
    """

    name = "NRMLC"

    def __init__(self, seed: int = 0, params: TrackerParams | None = None, **overrides) -> None:
        if params is not None and not isinstance(params, TrackerParams):
            raise ParameterError(f"params must be a TrackerParams, got {type(params).__name__} "
                                 f"(TrackerParams(**values), or pass the values as keywords)")
        base = params if params is not None else TrackerParams()
        self.params = base.replace(**overrides) if overrides else base
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ParameterError(f"parameter seed: must be a non-negative integer, got {seed!r}")
        self.seed = int(seed)
        self.rng = np.random.default_rng(self.seed)
        self.frame_index = -1
        self.state: np.ndarray | None = None
        self.last: FrameResult | None = None
        #: The last frame's :class:`Coding` of every candidate (set in ``update`` for observers
        #: such as experiments/internals.py; the algorithm never reads it).
        self.last_coding: Coding | None = None
        self.generative: LocalHistogramModel | None = None
        self.frame_shape: tuple | None = None
        self.initial_box: np.ndarray | None = None
        self.first_frame_mean: float | None = None
        self.particles: np.ndarray | None = None
        self.log_weights: np.ndarray | None = None
        self.positive_templates: np.ndarray | None = None
        self.negative_templates: np.ndarray | None = None
        self.templates: np.ndarray | None = None
        self.template_gram: np.ndarray | None = None
        self.template_sq_norms: np.ndarray | None = None
        #: The second expert (``second_expert``), a tracker of its own, and both experts' running
        #: average of eps_pos* (own, second); None and unused when there is none.
        self.partner = None if self.params.second_expert == "off" else self._new_partner()
        self.expert_errors = np.zeros(2)
        #: log(w), log(h) of the last output whose frame an expert recognised
        #: (``unrecognised_size_share``); the first frame's box at ``init``; None without a second expert.
        self.recognised_log_size: np.ndarray | None = None
        self._busy = threading.Lock()

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state.pop("_busy", None)  # a lock cannot be pickled; a copy gets its own
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._busy = threading.Lock()

    @contextlib.contextmanager
    def _alone(self, what: str):
        """One call at a time: a tracker's state is one particle cloud, advanced frame by frame;
        two threads updating it at once would interleave their frames and break its arrays."""
        if not self._busy.acquire(blocking=False):
            raise ParameterError(f"NRMLCTracker.{what}: called while another thread is inside init or update of "
                                 f"the same tracker; use one tracker per thread (or a lock around it)")
        try:
            yield
        finally:
            self._busy.release()

    # -- templates -------------------------------------------------------
    def patches(self, frame: np.ndarray, states: np.ndarray) -> np.ndarray:
        """The patch vectors the tracker codes for ``states`` (n, 6) in ``frame`` (a frame
        as ``update`` sees it): (n, patch_size**2) float32, unit rows."""
        return warp_patches(frame, np.ascontiguousarray(state_to_affine(states)), self.params.patch_size)

    def _set_templates(self, positives: np.ndarray, negatives: np.ndarray,
                       kept_positives: np.ndarray | None = None) -> None:
        """``kept_positives[i]``: the previous template row that positive ``i`` still is, or -1
        (None: no Gram row is carried over)."""
        self.positive_templates = positives
        self.negative_templates = negatives
        self.templates = np.ascontiguousarray(np.vstack([positives, negatives]))
        if kept_positives is None:
            self.template_gram = template_gram(self.templates)
        else:
            kept = np.concatenate([kept_positives, np.full(len(negatives), -1, dtype=np.int64)])
            self.template_gram = template_gram(self.templates, self.template_gram, kept)
        self.template_sq_norms = np.ascontiguousarray(np.diag(self.template_gram))

    def _sample_positives(self, frame: np.ndarray, state: np.ndarray) -> np.ndarray:
        p = self.params
        if p.template_sampling == "scm":
            states = scm_positive_states(self.rng, state, p.n_positive, p.positive_sigma)
        else:
            states = positive_states(self.rng, state, p.n_positive, p.positive_radius)
        return self.patches(frame, states)

    def _sample_negatives(self, frame: np.ndarray, state: np.ndarray, first: bool = False) -> np.ndarray:
        p = self.params
        if p.template_sampling == "scm":
            # SCM's zones, scaled by negative_push / SCM's 1/4 (the update zone keeps SCM's 4:5 ratio).
            push = p.negative_push * (1.0 if first else SCM_PUSH_UPDATE / SCM_PUSH_INIT)
            states = scm_negative_states(self.rng, state, p.n_negative, p.patch_size, push)
        else:
            states = negative_states(self.rng, state, p.n_negative, p.positive_radius, p.negative_radius)
        return self.patches(frame, states)

    # -- public interface -----------------------------------------------
    def init(self, image, box) -> None:
        """Start tracking the target in ``box`` (1-based x, y, w, h) of ``image``
        (a numpy image or a PIL image)."""
        with self._alone("init"):
            self._init(image, box)

    def _init(self, image, box) -> None:
        frame = as_gray_frame(image)
        box = clip_initial_box(box, frame.shape)
        p = self.params
        self.rng = np.random.default_rng(self.seed)
        self.frame_shape = frame.shape
        self.state = box_to_state(box, p.patch_size)
        self.initial_box = box
        self.first_frame_mean = float(frame.mean(dtype=np.float64))
        self.particles = None
        self.log_weights = None
        positives = self._sample_positives(frame, self.state)
        self._set_templates(positives, self._sample_negatives(frame, self.state, first=True))
        self.generative = None
        if p.generative_weight > 0:
            self.generative = LocalHistogramModel(self.rng, self.patches(frame, self.state[None, :])[0],
                                                  p.patch_size, p.generative_neighbours, p.generative_lam,
                                                  p.generative_step)
        self.frame_index = 0
        self.last = None
        if self.partner is not None:
            self.partner._init(image, box)
        self.expert_errors = np.zeros(2)
        self.recognised_log_size = None if self.partner is None else np.log(np.asarray(box, dtype=np.float64)[2:])

    def update(self, image) -> np.ndarray:
        """Track into the next frame; returns the 1-based ``(x, y, w, h)`` box.

        Raises
        ------
        ParameterError
            Before ``init``, for a frame of another size, or when another thread is
            inside ``init`` or ``update`` of this tracker.
        """
        with self._alone("update"):
            return self._update(image)

    def _update(self, image) -> np.ndarray:
        if self.state is None:
            raise ParameterError("call init(frame, box) before update(frame)")
        frame = as_gray_frame(image)
        if frame.shape != self.frame_shape:
            raise ParameterError(f"frame is {frame.shape[1]}x{frame.shape[0]} but init() saw "
                                 f"{self.frame_shape[1]}x{self.frame_shape[0]}")
        frame = self._levelled(frame)
        self.frame_index += 1
        result, coding, best = self.step(frame)
        best_patch = coding.patches[best][None, :]
        if (self.frame_index + 1) % self.params.update_interval == 0:
            self._update_templates(frame, result, best_patch)
        if self.generative is not None and (self.frame_index + 1) % self.params.generative_interval == 0:
            # Coded again alone: keeping every candidate's local codes cost more than this.
            local = self.generative.similarity(best_patch)
            self.generative.update(local["neighbours"][0], local["codes"][0], float(local["occluded_share"][0]))
        self.last_coding = coding
        if self.partner is not None:
            return self._output_of_the_experts(image, result)
        return result.box

    def _new_partner(self) -> "NRMLCTracker":
        """The second expert (``second_expert``): an :class:`NRMLCTracker` (whatever this tracker's
        class) with the same seed and :meth:`TrackerParams.partner_params`."""
        return NRMLCTracker(self.seed, self.params.partner_params())

    def _output_of_the_experts(self, image, own: FrameResult) -> np.ndarray:
        """Track ``image`` with the second expert too, and make the output (``last``, the returned
        box) the estimate of the expert whose average eps_pos* is lower (the own one on a tie), or
        the two's blend where their boxes overlap at IoU >= ``expert_blend_iou`` (``last`` then the
        chosen expert's result with the blended box and its state); where neither expert's eps_pos*
        is under ``unrecognised_gate``, with its size moved toward the last recognised output's
        (:func:`held_size`). Each expert goes on from its own estimate: the choice, the blend and the
        held size change only what is reported."""
        self.partner._update(image)
        errors = np.array([own.error_positive, self.partner.last.error_positive])
        self.expert_errors, chosen = choose_expert(self.expert_errors, errors, self.params.expert_memory)
        if chosen == 1:
            self.last = dataclasses.replace(self.partner.last, expert=1)
            self.last_coding = self.partner.last_coding
        box, self.recognised_log_size, moved = experts_output(
            np.stack([own.box, self.partner.last.box]), errors, chosen, self.recognised_log_size, self.params)
        if moved:
            self.last = dataclasses.replace(self.last, box=box, state=box_to_state(box, self.params.patch_size))
        return self.last.box

    def move_to(self, box) -> None:
        """Move the estimate to ``box`` (1-based x, y, w, h), keeping the templates.

        For diagnostics such as re-centring on the ground truth: the next
        ``update`` draws its particles around this box, and its size is the last recognised one
        (``unrecognised_size_share``).
        """
        if self.state is None:
            raise ParameterError("call init(frame, box) before move_to(box)")
        box = as_box(box)
        if not usable_boxes(box):
            raise ParameterError(f"box must be 4 finite numbers (x, y, w, h) with w, h > 0, got {box.tolist()}")
        self.state = box_to_state(box, self.params.patch_size)
        self.particles = None
        self.log_weights = None
        if self.partner is not None:
            self.recognised_log_size = np.log(box[2:])
            self.partner.move_to(box)

    def _levelled(self, frame: np.ndarray) -> np.ndarray:
        """``frame`` (height, width) float32 with its mean gray moved to the first frame's under
        ``brightness = 'first_frame'``; as it is otherwise."""
        if self.params.brightness == "raw":
            return frame
        return frame + np.float32(self.first_frame_mean - frame.mean(dtype=np.float64))

    # -- one frame -------------------------------------------------------
    def sample_particles(self) -> np.ndarray:
        """(n_particles, 6) states for this frame: last frame's particles resampled by
        confidence (condensation) or the estimate repeated, then diffused and clamped."""
        p = self.params
        n = p.n_particles
        if p.propagation == "condensation" and self.particles is not None:
            weights = np.exp(self.log_weights - self.log_weights.max())
            cumulative = np.cumsum(weights)
            # Multinomial resampling, as estwarp_condens.m; searchsorted keeps it O(n log n).
            picks = np.searchsorted(cumulative, self.rng.random(n) * cumulative[-1], side="right")
            states = self.particles[np.minimum(picks, len(self.particles) - 1)]
        else:
            states = np.tile(self.state, (n, 1))
        return self.diffuse(states)

    def diffuse(self, states: np.ndarray, translation_factor: float = 1.0) -> np.ndarray:
        """Add the motion model's noise to ``states`` (n, 6) in place, with the translation
        noise ``translation_factor`` times larger (re-detection); clamp them."""
        p = self.params
        standard = self.rng.standard_normal((len(states), 6))
        noise = standard * np.asarray(p.motion_sigmas)
        if p.translation_noise == "relative":
            size = states[:, 2] * np.sqrt(0.5 * (1.0 + states[:, 4] ** 2))
            if p.translation_floor > 0:
                noise[:, 0:2] = standard[:, 0:2] * p.translation_sigmas(size)
            else:  # kept apart so that without the floor the boxes stay those of the paper preset's runs
                noise[:, 0:2] *= size[:, None]
        if translation_factor != 1.0:
            noise[:, 0:2] *= translation_factor
        states[:, 0:2] += noise[:, 0:2]
        states[:, 2] *= np.exp(noise[:, 2])
        states[:, 3] += noise[:, 3]
        states[:, 4] *= np.exp(noise[:, 4])
        states[:, 5] += noise[:, 5]
        return clamp_states(states, self.frame_shape, MIN_BOX_SIZE, p.patch_size)

    def encode(self, candidates: np.ndarray) -> Coding:
        """Code candidate vectors on the current templates (Algorithm 1 for each) and score them.

        Parameters
        ----------
        candidates : (n_candidates, patch_size**2) float32, unit-norm rows

        Returns
        -------
        Coding
        """
        p = self.params
        dots = candidate_template_dots(candidates, self.templates)
        ridge_c, ridge_w = p.ridges
        coded = code_candidates(candidates, dots, self.template_gram, self.template_sq_norms,
                                np.asarray(p.dictionary_sizes, dtype=np.int64), len(self.positive_templates),
                                ridge_c, ridge_w, p.coding == "constrained", p.n_iterations)
        error_positive, error_negative = coded["error_positive"], coded["error_negative"]
        sign = -1.0 if p.confidence == "corrected" else 1.0
        # log h: the ranking and the condensation weights are taken from it, never from h,
        # so no alpha can overflow into a tie.
        log_confidence = sign * p.alpha * (error_positive - error_negative)
        similarity = None
        if self.generative is not None:
            similarity = self._generative_similarity(candidates, log_confidence)
            term = p.generative_weight * np.log(np.maximum(similarity, 1e-300))
            # Only where the positives take part in the code: where the discriminative
            # likelihood is flat (the target hidden or lost), the term would hold the cloud
            # on whatever background it prefers instead of letting it spread and search.
            recognised = error_positive < REDETECT_TRIGGER
            floor = term[recognised].min() if recognised.any() else 0.0
            log_confidence = log_confidence + np.where(recognised, term, floor)
        return Coding(patches=candidates, dots=dots, neighbours=coded["neighbours"],
                      coefficients=coded["coefficients"], weights=coded["weights"], codes=coded["codes"],
                      error_positive=error_positive, error_negative=error_negative,
                      log_confidence=log_confidence, similarity=similarity)

    def _generative_similarity(self, candidates: np.ndarray, log_confidence: np.ndarray) -> np.ndarray:
        """The generative term's similarity (n,) of each candidate: the ``generative_candidates``
        most confident are coded locally, the others get the lowest of their similarities."""
        top = np.argsort(-log_confidence, kind="stable")[:self.params.generative_candidates]
        local = self.generative.similarity(candidates[top])["similarity"]
        similarity = np.full(len(candidates), local.min())
        similarity[top] = local
        return similarity

    def step(self, frame: np.ndarray) -> tuple[FrameResult, Coding, int]:
        """Estimate the target in ``frame`` (Algorithm 2, steps 2.1-2.4; no template update).

        Returns
        -------
        result : FrameResult
        coding : Coding
            Every candidate of the frame (the particles, then any re-detection candidates).
        best : int
            The row of ``coding`` that is the estimate.
        """
        p = self.params
        states = self.sample_particles()
        coding = self.encode(self.patches(frame, states))
        n_local = len(states)
        best = int(np.argmax(coding.log_confidence))
        searched = needs_search(p, coding.error_positive[best])
        if searched:
            states, coding = search(self, frame, states, coding)
            best = int(np.argmax(coding.log_confidence))
        log_confidence = coding.log_confidence
        self.particles = states
        self.log_weights = log_confidence
        n_pos = len(self.positive_templates)
        indices = coding.neighbours[best]
        codes = coding.codes[best]
        negative = indices >= n_pos
        n_negative_used = int(np.count_nonzero(np.abs(codes[negative]) > p.coefficient_tolerance))
        self.state = states[best].copy()
        result = FrameResult(
            state=self.state.copy(), box=state_to_box(self.state, p.patch_size),
            confidence=_exp_or_inf(log_confidence[best]), log_confidence=float(log_confidence[best]),
            error_positive=float(coding.error_positive[best]), error_negative=float(coding.error_negative[best]),
            template_indices=indices.copy(), codes=codes.copy(), coefficients=coding.coefficients[best].copy(),
            weights=coding.weights[best].copy(), n_positive_templates=n_pos, n_templates=len(self.templates),
            n_negative_used=n_negative_used, occluded=n_negative_used > p.occlusion_max_negative,
            code_sum_positive=float(codes[~negative].sum()), code_sum_negative=float(codes[negative].sum()),
            redetect_searched=bool(searched), redetected=best >= n_local,
        )
        self.last = result
        return result, coding, best

    def _update_templates(self, frame: np.ndarray, result: FrameResult, new: np.ndarray) -> None:
        """Algorithm 2, step 2.5: negatives always; positives (``new``, the estimate's (1, d)
        patch) unless occluded."""
        p = self.params
        negatives = self._sample_negatives(frame, self.state)
        positives = self.positive_templates
        kept = np.arange(len(positives), dtype=np.int64)
        blocked = p.occlusion_detection and result.occluded
        if not blocked and result.error_positive < p.update_error_threshold:
            if len(positives) < p.max_positive:
                positives = np.vstack([positives, new])
                kept = np.append(kept, -1)
            else:
                closest = int(np.argmin(((positives - new) ** 2).sum(axis=1)))
                positives = positives.copy()
                positives[closest] = new[0]
                kept[closest] = -1
            result.updated_positive = True
        self._set_templates(positives, negatives, kept)
