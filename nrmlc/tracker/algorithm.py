"""The NRMLC tracker: Algorithm 2 of the paper calling Algorithm 1, one expert.

Per frame (:meth:`NRMLCTracker.update`, read against Sec. 3-4):

1. propagate the particles (eq. 1, :meth:`~NRMLCTracker.sample_particles`): resample last frame's
   particles in proportion to their confidence and diffuse them with the Gaussian motion model
   (IVT's ``estwarp_condens.m``), or draw them all around the previous estimate; keep them inside
   the frame;
2. warp them into unit-norm patch vectors (:mod:`nrmlc.kernels.warp`);
3. code each candidate (:meth:`~NRMLCTracker.encode`): its ``k_max`` nearest templates among
   ``[T_pos, T_neg]`` (:mod:`nrmlc.kernels.distance`) give the nested local dictionaries
   B^1..B^m; approximated LLC on each and the dictionary weights w (Algorithm 1,
   :mod:`nrmlc.kernels.coding`; its readable form is :mod:`nrmlc.testing.reference`);
4. confidence log h = -alpha (eps_pos - eps_neg), in the log domain so that no alpha overflows;
5. the estimate is the most confident candidate (:meth:`~NRMLCTracker.step`);
6. every ``update_interval`` frames, new negative templates around the estimate and, unless the
   target is judged occluded (LEN(neg*) > ``occlusion_max_negative``), the estimate joins the
   positives when eps_pos* < ``update_error_threshold`` (:meth:`~NRMLCTracker.update_templates`).

The additions beyond the paper plug in at named points, each a module with its own parameter
group (all off in the ``paper`` preset): brightness levelling where a frame comes in
(:mod:`~nrmlc.tracker.brightness`), the motion floor in the motion model
(:mod:`~nrmlc.tracker.motion_floor`), re-detection as a second source of candidates
(:mod:`~nrmlc.tracker.redetect`) and the generative term as a confidence term
(:mod:`~nrmlc.tracker.generative`). The pair of experts wraps two trackers
(:mod:`~nrmlc.tracker.experts`).
"""
from __future__ import annotations

import numpy as np

from nrmlc.data.image import as_gray_frame
from nrmlc.errors import ParameterError
from nrmlc.geometry import MIN_BOX_SIZE, box_to_state, clamp_states, clip_initial_box, state_to_box
from nrmlc.kernels.coding import code_candidates
from nrmlc.kernels.distance import candidate_template_dots, template_gram
from nrmlc.tracker import redetect
from nrmlc.tracker.brightness import levelled
from nrmlc.tracker.concurrency import OneCallAtATime
from nrmlc.tracker.eyes import ERROR_SCALE, seen
from nrmlc.tracker.generative import GenerativeTerm
from nrmlc.tracker.params import TrackerParams, resolve_params
from nrmlc.tracker.records import Coding, FrameResult
from nrmlc.tracker.templates import (SCM_PUSH_INIT, SCM_PUSH_UPDATE, negative_states, positive_states,
                                     scm_negative_states, scm_positive_states)


class NRMLCTracker(OneCallAtATime):
    """One NRMLC expert with the got10k Tracker interface (``init`` / ``update``).

    The default configuration runs two of them (:func:`nrmlc.tracker.experts.make_tracker`);
    this class reads every parameter group but the pair's.

    Parameters
    ----------
    seed : int
        Seed of the tracker's random generator (templates and particles). The same seed gives the
        same boxes, whatever the thread count.
    params : TrackerParams, optional
        Full parameter set; keyword arguments override single fields.
    **overrides
        Any :class:`TrackerParams` field, e.g. ``n_particles=300, coding="constrained"``.

    Attributes
    ----------
    last : FrameResult
        The last frame's result and diagnostics.
    """

    name = "NRMLC"

    def __init__(self, seed: int = 0, params: TrackerParams | None = None, **overrides) -> None:
        super().__init__()
        self.params = resolve_params(params, overrides)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ParameterError(f"parameter seed: must be a non-negative integer, got {seed!r}")
        self.seed = int(seed)
        self.rng = np.random.default_rng(self.seed)
        self.frame_index = -1
        self.state: np.ndarray | None = None
        self.last: FrameResult | None = None
        self.generative: GenerativeTerm | None = None
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

    # -- the got10k interface ----------------------------------------------------------------
    def init(self, image, box) -> None:
        """Start tracking the target in ``box`` (1-based x, y, w, h) of ``image`` (a numpy image
        or a PIL image): the first templates, and the generative term's model."""
        with self._alone("init"):
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
            if p.generative_weight > 0 and p.eyes == "gray":  # the generative term models gray local patches
                self.generative = GenerativeTerm(self.rng, self.patches(frame, self.state[None, :])[0], p)
            self.frame_index = 0
            self.last = None

    def update(self, image) -> np.ndarray:
        """Track into the next frame (Algorithm 2); returns the 1-based ``(x, y, w, h)`` box.

        Raises
        ------
        ParameterError
            Before ``init``, for a frame of another size, or when another thread is inside
            ``init`` or ``update`` of this tracker.
        """
        with self._alone("update"):
            return self.advance(self.prepared_frame(image))

    def prepared_frame(self, image) -> np.ndarray:
        """``image`` as the tracker sees it: (height, width) float32 gray, levelled
        (:mod:`~nrmlc.tracker.brightness`); checked against ``init``'s frame."""
        if self.state is None:
            raise ParameterError("call init(frame, box) before update(frame)")
        frame = as_gray_frame(image)
        if frame.shape != self.frame_shape:
            raise ParameterError(f"frame is {frame.shape[1]}x{frame.shape[0]} but init() saw "
                                 f"{self.frame_shape[1]}x{self.frame_shape[0]}")
        return levelled(frame, self.first_frame_mean, self.params)

    def advance(self, frame: np.ndarray, particles: tuple | None = None) -> np.ndarray:
        """Track into the next frame, given as :meth:`prepared_frame` returns it; returns the box.

        Parameters
        ----------
        frame : (height, width) float32
        particles : (states (n, 6) float64, candidates (n, d) float32), optional
            This frame's particles (:meth:`sample_particles`) and what the expert sees of them
            (:meth:`patches`), where a caller computed them with other experts' in one pass
            (:class:`~nrmlc.tracker.experts.ExpertPair`); default: sampled and seen here.
        """
        self.frame_index += 1
        result, coding, best = self.step(frame, particles)
        estimate_patch = coding.patches[best][None, :]
        if (self.frame_index + 1) % self.params.update_interval == 0:
            self.update_templates(frame, result, estimate_patch)
        if self.generative is not None:
            self.generative.learn(self.frame_index, estimate_patch)
        return result.box

    # -- one frame -----------------------------------------------------------------------------
    def step(self, frame: np.ndarray, particles: tuple | None = None) -> tuple[FrameResult, Coding, int]:
        """Estimate the target in ``frame`` (Algorithm 2, steps 2.1-2.4; no template update);
        ``particles`` as :meth:`advance`'s.

        Returns
        -------
        result : FrameResult
        coding : Coding
            Every candidate of the frame (the particles, then any re-detection candidates).
        best : int
            The row of ``coding`` that is the estimate.
        """
        p = self.params
        if particles is None:
            states = self.sample_particles()
            particles = states, self.patches(frame, states)
        states, candidates = particles
        coding = self.encode(candidates)
        n_particles = len(states)
        best = int(np.argmax(coding.log_confidence))
        searched = redetect.needs_search(p, coding.error_positive[best])
        if searched:
            states, coding = redetect.search(self, frame, states, coding)
            best = int(np.argmax(coding.log_confidence))
        self.particles = states
        self.log_weights = coding.log_confidence
        self.state = states[best].copy()
        self.last = self._result(coding, best, searched=searched, redetected=best >= n_particles)
        return self.last, coding, best

    def sample_particles(self) -> np.ndarray:
        """(n_particles, 6) states for this frame: last frame's particles resampled by confidence
        (condensation) or the estimate repeated, then diffused and clamped."""
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
        """Add the motion model's noise to ``states`` (n, 6) in place, with the translation noise
        ``translation_factor`` times larger (re-detection); clamp them."""
        p = self.params
        standard = self.rng.standard_normal((len(states), 6))
        noise = standard * np.asarray(p.motion_sigmas)
        if p.translation_noise == "relative":
            size = states[:, 2] * np.sqrt(0.5 * (1.0 + states[:, 4] ** 2))
            noise[:, 0:2] *= size[:, None]
            if p.translation_floor > 0:  # the motion floor replaces the relative std by its floored one
                noise[:, 0:2] = standard[:, 0:2] * p.translation_sigmas(size)
        if translation_factor != 1.0:
            noise[:, 0:2] *= translation_factor
        states[:, 0:2] += noise[:, 0:2]
        states[:, 2] *= np.exp(noise[:, 2])
        states[:, 3] += noise[:, 3]
        states[:, 4] *= np.exp(noise[:, 4])
        states[:, 5] += noise[:, 5]
        return clamp_states(states, self.frame_shape, MIN_BOX_SIZE, p.patch_size)

    def patches(self, frame: np.ndarray, states: np.ndarray) -> np.ndarray:
        """The vectors the tracker codes for ``states`` (n, 6) in ``frame`` (as ``update`` sees
        it): (n, d) float32 unit rows, in the expert's eyes (:mod:`nrmlc.tracker.eyes`; the gray
        patch: d = patch_size**2)."""
        return seen(frame, states, self.params.patch_size, self.params.eyes)

    def encode(self, candidates: np.ndarray) -> Coding:
        """Code candidate vectors on the current templates (Algorithm 1 for each) and score them.

        Parameters
        ----------
        candidates : (n_candidates, d) float32, unit-norm rows (:meth:`patches`)

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
        scale = ERROR_SCALE[p.eyes]
        if scale != 1.0:  # in the gray patch's units, which every threshold reads
            error_positive, error_negative = error_positive / scale, error_negative / scale
        sign = -1.0 if p.confidence == "corrected" else 1.0
        log_confidence = sign * p.alpha * (error_positive - error_negative)
        similarity = None
        if self.generative is not None:
            similarity, log_confidence = self.generative.add_to(candidates, log_confidence, error_positive)
        return Coding(patches=candidates, dots=dots, neighbours=coded["neighbours"],
                      coefficients=coded["coefficients"], weights=coded["weights"], codes=coded["codes"],
                      error_positive=error_positive, error_negative=error_negative,
                      log_confidence=log_confidence, similarity=similarity)

    def _result(self, coding: Coding, best: int, searched: bool, redetected: bool) -> FrameResult:
        """The estimate's :class:`FrameResult`: its box, errors, code and LEN(neg*)."""
        p = self.params
        n_pos = len(self.positive_templates)
        indices = coding.neighbours[best]
        codes = coding.codes[best]
        negative = indices >= n_pos
        n_negative_used = int(np.count_nonzero(np.abs(codes[negative]) > p.coefficient_tolerance))
        log_confidence = float(coding.log_confidence[best])
        return FrameResult(
            state=self.state.copy(), box=state_to_box(self.state, p.patch_size),
            confidence=float("inf") if log_confidence > 709.0 else float(np.exp(log_confidence)),
            log_confidence=log_confidence, error_positive=float(coding.error_positive[best]),
            error_negative=float(coding.error_negative[best]), template_indices=indices.copy(), codes=codes.copy(),
            coefficients=coding.coefficients[best].copy(), weights=coding.weights[best].copy(),
            n_positive_templates=n_pos, n_templates=len(self.templates), n_negative_used=n_negative_used,
            occluded=n_negative_used > p.occlusion_max_negative, code_sum_positive=float(codes[~negative].sum()),
            code_sum_negative=float(codes[negative].sum()), redetect_searched=bool(searched),
            redetected=bool(redetected))

    # -- templates (Sec. 3; Algorithm 2, step 2.5) ---------------------------------------------
    def update_templates(self, frame: np.ndarray, result: FrameResult, estimate_patch: np.ndarray) -> None:
        """New negatives always; the estimate's (1, d) patch joins the positives unless the target
        is occluded or not recognised well enough (at ``max_positive``, it replaces the closest)."""
        p = self.params
        negatives = self._sample_negatives(frame, self.state)
        positives = self.positive_templates
        kept = np.arange(len(positives), dtype=np.int64)
        blocked = p.occlusion_detection and result.occluded
        if not blocked and result.error_positive < p.update_error_threshold:
            if len(positives) < p.max_positive:
                positives = np.vstack([positives, estimate_patch])
                kept = np.append(kept, -1)
            else:
                closest = int(np.argmin(((positives - estimate_patch) ** 2).sum(axis=1)))
                positives = positives.copy()
                positives[closest] = estimate_patch[0]
                kept[closest] = -1
            result.updated_positive = True
        self._set_templates(positives, negatives, kept)

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
