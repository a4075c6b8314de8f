"""The pair of experts (*ours*; ``second_expert = 'off'`` is the paper): two NRMLC trackers track
every frame apart, and the pair reports one box.

The second expert has the same parameters and seed but a template update every frame and eyes
of its own (``partner_eyes``: gradient cells, :mod:`nrmlc.tracker.eyes`;
:meth:`ExpertParams.partner_params`), so the two fail on different frames. Each frame's output is
the estimate of the expert whose recent eps_pos* (an exponential average, in the gray patch's
units) is lower; where
their boxes agree, their blend; on a frame neither recognises, the output's size moves toward the
last recognised output's. Each expert goes on from its own estimate: the choice, the blend and the
held size change only what is reported. Evidence: docs/DEVIATIONS.md.
"""
from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from typing import Literal

import numpy as np

from nrmlc.errors import ParameterError
from nrmlc.geometry import box_iou, box_to_state
from nrmlc.tracker.concurrency import OneCallAtATime
from nrmlc.tracker.eyes import seen_by_each
from nrmlc.tracker.parameter_fields import CheckedParams, bounded
from nrmlc.tracker.records import FrameResult


@dataclass(frozen=True)
class ExpertParams(CheckedParams):
    """The pair's parameters (:mod:`nrmlc.tracker.experts`).

    Attributes
    ----------
    second_expert : {'every_frame', 'off'}
        'every_frame': a second expert that updates its templates every frame; 'off': one tracker
        (the paper).
    partner_eyes : {'gradient', 'gray'}
        What the second expert sees (:mod:`nrmlc.tracker.eyes`): 'gradient', gradient-orientation
        cells; 'gray', the gray patch, as the first expert.
    expert_memory : float
        The weight of the past in each expert's average eps_pos* (0.95: about 20 frames).
    expert_blend_iou : float
        Where the two experts' boxes overlap at least this much (IoU), the output is their blend
        (:func:`blend_experts`); 1 never blends.
    unrecognised_size_share : float
        On a frame where neither expert's eps_pos* is below ``unrecognised_gate``, the output
        keeps its centre and its log width and height move this share of the way to those of the
        last output whose frame an expert recognised (:func:`held_size`); 0 reports the experts'
        size.
    unrecognised_gate : float
        The eps_pos* at or above which an expert does not recognise the target.
    """

    second_expert: Literal["every_frame", "off"] = "every_frame"
    partner_eyes: Literal["gradient", "gray"] = "gradient"
    expert_memory: float = bounded(0.95, 0, 1, high_open=True)
    expert_blend_iou: float = bounded(0.5, 0, 1)
    unrecognised_size_share: float = bounded(0.7, 0, 1)
    unrecognised_gate: float = bounded(0.15, 0, 1, low_open=True)

    def partner_params(self):
        """The second expert's parameters: these with an update every frame, its own eyes and no pair."""
        return self.replace(second_expert="off", update_interval=1, eyes=self.partner_eyes)


def choose_expert(average: np.ndarray, errors: np.ndarray, memory: float) -> tuple[np.ndarray, int]:
    """One frame of the pair's choice.

    Parameters
    ----------
    average : (2,) float64
        Each expert's running average of eps_pos* (first, second) before this frame; 0 at the first.
    errors : (2,) float64
        This frame's eps_pos* of each expert's estimate.
    memory : float
        The weight of the past (``expert_memory``), in [0, 1).

    Returns
    -------
    average : (2,) float64
        ``memory * average + (1 - memory) * errors``.
    chosen : int
        1 where the second expert's average is strictly lower, else 0 (the first on a tie).
    """
    average = memory * average + (1.0 - memory) * errors
    return average, int(average[1] < average[0])


def blend_experts(boxes: np.ndarray, errors: np.ndarray, min_iou: float) -> np.ndarray | None:
    """The blend of the two experts' boxes where they agree: two estimates of one box whose errors
    are partly independent, so their mean is nearer the truth than either.

    Parameters
    ----------
    boxes : (2, 4) float64
        The two experts' boxes ``x, y, w, h`` (w, h > 0).
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
    """The output on a frame where neither expert recognises the target: a lost tracker's box
    drifts small, and the size last recognised is the best it has.

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
                   params: ExpertParams, scores: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, bool]:
    """What the pair reports on a frame: the chosen expert's box, or the two's blend where they
    agree (:func:`blend_experts`); where neither expert's eps_pos* is under ``unrecognised_gate``,
    with its size moved toward the last recognised output's (:func:`held_size`).

    Parameters
    ----------
    boxes : (2, 4) float64
        The two experts' boxes ``x, y, w, h`` (w, h > 0).
    errors : (2,) float64
        This frame's eps_pos* of each.
    chosen : int
        The expert :func:`choose_expert` chose, 0 or 1.
    recognised_log_size : (2,) float64
        log(w), log(h) of the last output whose frame an expert recognised.
    params : ExpertParams
    scores : (2,) float64, optional
        What the blend weighs the experts by (default ``errors``).

    Returns
    -------
    box : (4,) float64
        The output.
    recognised_log_size : (2,) float64
        The output's log size where an expert recognises the target; else the one given.
    moved : bool
        Whether ``box`` is the blend or a held size rather than ``boxes[chosen]``.
    """
    box = blend_experts(boxes, errors if scores is None else scores, params.expert_blend_iou)
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


class ExpertPair(OneCallAtATime):
    """Two NRMLC experts that report one box, with the got10k Tracker interface.

    Parameters
    ----------
    seed : int
        Both experts' seed.
    params : TrackerParams, optional
        The first expert's parameters (``second_expert`` not 'off'); the second's are
        :meth:`ExpertParams.partner_params`. Keyword arguments override single fields.
    expert_class : callable(seed, params), optional
        What each expert is (default :class:`~nrmlc.tracker.algorithm.NRMLCTracker`; a subclass
        for a diagnostic).

    Attributes
    ----------
    experts : tuple of two NRMLCTracker
    last : FrameResult
        The output's result: the chosen expert's, with the reported box and its state.
    """

    name = "NRMLC"

    def __init__(self, seed: int = 0, params=None, expert_class=None, **overrides) -> None:
        from nrmlc.tracker.algorithm import NRMLCTracker  # the trackers' module needs this one's group

        expert_class = expert_class or NRMLCTracker
        first = expert_class(seed, params, **overrides)
        if first.params.second_expert == "off":
            raise ParameterError("parameter second_expert: an ExpertPair needs a second expert, got 'off' "
                                 "(make_tracker gives one NRMLCTracker then)")
        super().__init__()
        self.params = first.params
        self.seed = first.seed
        self.experts = (first, expert_class(seed, self.params.partner_params()))
        self.average_errors = np.zeros(2)
        self.recognised_log_size: np.ndarray | None = None
        self.last: FrameResult | None = None

    @property
    def initial_box(self) -> np.ndarray | None:
        return self.experts[0].initial_box

    @property
    def state(self) -> np.ndarray | None:
        """The output's state (the first expert's at ``init``)."""
        return self.experts[0].state if self.last is None else self.last.state

    def init(self, image, box) -> None:
        """Start both experts on ``box`` (1-based x, y, w, h) of ``image``."""
        with self._alone("init"):
            first, second = self.experts
            first.init(image, box)
            with warnings.catch_warnings():  # the same frame and box: the first expert has said it all
                warnings.simplefilter("ignore")
                second.init(image, box)
            self.average_errors = np.zeros(2)
            self.recognised_log_size = np.log(np.asarray(box, dtype=np.float64)[2:])
            self.last = None

    def update(self, image) -> np.ndarray:
        """Track ``image`` with both experts; returns the output box ``(x, y, w, h)``, 1-based."""
        with self._alone("update"):
            self._advance_experts(image)
            results = [expert.last for expert in self.experts]
            errors = np.array([result.error_positive for result in results])
            self.average_errors, chosen = choose_expert(self.average_errors, errors, self.params.expert_memory)
            last = results[0] if chosen == 0 else dataclasses.replace(results[1], expert=1)
            box, self.recognised_log_size, moved = experts_output(
                np.stack([result.box for result in results]), errors, chosen, self.recognised_log_size, self.params)
            if moved:
                last = dataclasses.replace(last, box=box, state=box_to_state(box, self.params.patch_size))
            self.last = last
            return last.box

    def _advance_experts(self, image) -> None:
        """Both experts into the next frame, sharing what they can: the frame (prepared once:
        the partner's parameters change nothing of its preparation, and both levelled by the same
        first frame) and one pass of each seeing kernel over both experts' particles
        (:func:`~nrmlc.tracker.eyes.seen_by_each`). Each expert's boxes are those it gives alone."""
        frame = self.experts[0].prepared_frame(image)
        states = [expert.sample_particles() for expert in self.experts]
        seen = seen_by_each(frame, states, self.params.patch_size, [expert.params.eyes for expert in self.experts])
        for expert, own_states, own_seen in zip(self.experts, states, seen):
            expert.advance(frame, (own_states, own_seen))


def make_tracker(params=None, seed: int = 0, **overrides):
    """The tracker ``params`` describe: an :class:`ExpertPair` (the default), or one
    :class:`NRMLCTracker` where ``second_expert`` is 'off' (the ``paper`` preset).

    Parameters
    ----------
    params : TrackerParams, optional
        Default :class:`~nrmlc.tracker.params.TrackerParams`; keyword arguments override single fields.
    seed : int
    """
    from nrmlc.tracker.algorithm import NRMLCTracker
    from nrmlc.tracker.params import resolve_params

    params = resolve_params(params, overrides)
    return NRMLCTracker(seed, params) if params.second_expert == "off" else ExpertPair(seed, params)
