"""The tracker with the instruments only experiments need: the coding of every candidate of the
last frame, a probe before each frame, the estimate moved by hand, and runs that use them.

None of it changes a box: recording keeps what the tracker computed, a probe must draw nothing
from the tracker's generator, and only :func:`move_to` (re-centring on the ground truth, a
diagnostic) moves an estimate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nrmlc.errors import ParameterError
from nrmlc.geometry import as_box, box_to_state, usable_boxes
from nrmlc.tracker.algorithm import NRMLCTracker
from nrmlc.tracker.experts import ExpertPair
from nrmlc.tracker.loop import TrackResult, track_sequence
from nrmlc.tracker.params import TrackerParams, resolve_params
from nrmlc.tracker.records import Coding
from nrmlc.workbench.jobs import RunSpec


class RecordingTracker(NRMLCTracker):
    """An :class:`NRMLCTracker` that keeps the last frame's :class:`Coding` of every candidate
    (``last_coding``) and calls ``probe(frame_index, tracker, image)`` before each frame."""

    probe = None

    def step(self, frame, particles=None):
        result, coding, best = super().step(frame, particles)
        self.last_coding: Coding = coding
        return result, coding, best

    def update(self, image):
        if self.probe is not None:
            self.probe(self.frame_index + 1, self, image)
        return super().update(image)


class RecordingPair(ExpertPair):
    """An :class:`ExpertPair` of :class:`RecordingTracker` experts; ``last_coding`` is the chosen
    expert's, and ``probe`` sees the first expert (the templates its frame is tracked with)."""

    probe = None

    def __init__(self, seed: int = 0, params=None, expert_class=RecordingTracker, **overrides) -> None:
        super().__init__(seed, params, expert_class, **overrides)

    @property
    def last_coding(self) -> Coding:
        return self.experts[self.last.expert].last_coding

    def update(self, image):
        if self.probe is not None:
            self.probe(self.experts[0].frame_index + 1, self.experts[0], image)
        return super().update(image)


def recording_tracker(params: TrackerParams | None = None, seed: int = 0, probe=None):
    """The instrumented tracker ``params`` describe (a pair, or one expert where
    ``second_expert`` is 'off'), with ``probe`` set."""
    params = resolve_params(params, {})
    tracker = RecordingTracker(seed, params) if params.second_expert == "off" else RecordingPair(seed, params)
    tracker.probe = probe
    return tracker


def move_to(tracker, box) -> None:
    """Move ``tracker``'s estimate to ``box`` (1-based x, y, w, h), keeping the templates: the next
    ``update`` draws its particles around it; in a pair both experts move, and the size last
    recognised becomes the box's."""
    box = as_box(box)
    if not usable_boxes(box):
        raise ParameterError(f"box must be 4 finite numbers (x, y, w, h) with w, h > 0, got {box.tolist()}")
    if isinstance(tracker, ExpertPair):
        tracker.recognised_log_size = np.log(box[2:])
        for expert in tracker.experts:
            move_to(expert, box)
        return
    if tracker.state is None:
        raise ParameterError("call init(frame, box) before move_to(box)")
    tracker.state = box_to_state(box, tracker.params.patch_size)
    tracker.particles = None
    tracker.log_weights = None


def negative_shares(coding: Coding, dictionary_sizes) -> tuple[float, float]:
    """(share of negative entries among all candidates' c, within each k_j; share among their w):
    the non-negativity diagnostics of the ablation table and ``stats_nonnegativity``."""
    sizes = np.asarray(dictionary_sizes)
    within = np.arange(coding.coefficients.shape[2])[None, :] < sizes[:, None]  # (m, k_max)
    return float(np.mean(coding.coefficients[:, within] < 0)), float(np.mean(coding.weights < 0))


def track_instrumented(sequence, params: TrackerParams | None = None, seed: int = 0, n_frames: int | None = None,
                       recentre_boxes=None, recentre_every: int = 0, record_negative_shares: bool = False,
                       probe=None, on_frame=None, tracker=None) -> TrackResult:
    """:func:`nrmlc.tracker.loop.track_sequence` with the instruments.

    Parameters
    ----------
    recentre_boxes : (n_frames, 4) array, optional
        After every ``recentre_every``-th frame whose row here is finite, the estimate moves to
        that box (:func:`move_to`); the frame's recorded box is still the tracker's own. With the
        ground truth this measures localisation from a perfect start.
    recentre_every : int
        0 (never) or the re-centring period in frames.
    record_negative_shares : bool
        Also record, per frame, the shares of negative entries among all candidates' c and w
        (diagnostics ``negative_share_c``, ``negative_share_w``; :func:`negative_shares`).
    probe : callable(frame_index, tracker, image), optional
        Called before each frame after the first, with the expert whose templates the frame is
        tracked with; it must draw nothing from the tracker's generator.
    on_frame, tracker
        As :func:`~nrmlc.tracker.loop.track_sequence`; ``tracker`` defaults to
        :func:`recording_tracker`.
    """
    if isinstance(recentre_every, bool) or not isinstance(recentre_every, (int, np.integer)) or recentre_every < 0:
        raise ParameterError(f"recentre_every must be an integer >= 0, got {recentre_every!r}")
    if recentre_every and recentre_boxes is None:
        raise ParameterError("recentre_every needs recentre_boxes")
    if recentre_every:
        recentre_boxes = np.asarray(recentre_boxes, dtype=np.float64)
        if recentre_boxes.ndim != 2 or recentre_boxes.shape[1] != 4:
            raise ParameterError(f"recentre_boxes must have shape (n_frames, 4), got {recentre_boxes.shape}")
        usable = usable_boxes(recentre_boxes)
    if tracker is None:
        tracker = recording_tracker(params, seed, probe)
    shares = [(np.nan, np.nan)]

    def observe(index, tracker, frame):
        if index > 0:
            if record_negative_shares:
                shares.append(negative_shares(tracker.last_coding, tracker.params.dictionary_sizes))
            if recentre_every and index % recentre_every == 0 and index < len(usable) and usable[index]:
                move_to(tracker, recentre_boxes[index])
        if on_frame is not None:
            on_frame(index, tracker, frame)

    run = track_sequence(sequence, n_frames=n_frames, on_frame=observe, tracker=tracker)
    if record_negative_shares and len(shares) > 1:
        shares = np.array(shares, dtype=np.float64)
        run.diagnostics.update(negative_share_c=shares[:, 0], negative_share_w=shares[:, 1])
    return run


@dataclass(frozen=True)
class DiagnosticRun(RunSpec):
    """A tracking run with the instruments: a job of the run cache like :class:`RunSpec`, whose
    key also holds them.

    Attributes
    ----------
    recentre_every : int
        0 or move the estimate to the ground truth after every this many frames
        (:func:`track_instrumented`).
    negative_shares : bool
        Also record the per-frame negative shares of c and w.
    """

    recentre_every: int = 0
    negative_shares: bool = False

    def description(self, version: str) -> dict:
        description = super().description(version)
        if self.recentre_every:
            description["recentre_every"] = int(self.recentre_every)
        if self.negative_shares:
            description["negative_shares"] = True
        return description

    def execute(self) -> dict:
        truth = self.sequence.groundtruth if self.recentre_every else None
        return track_instrumented(self.sequence, self.params, seed=self.seed, n_frames=self.n_frames,
                                  recentre_boxes=truth, recentre_every=self.recentre_every,
                                  record_negative_shares=self.negative_shares).to_arrays()

    @classmethod
    def of(cls, spec: RunSpec, **instruments) -> "DiagnosticRun":
        """``spec`` with ``instruments`` (``recentre_every``, ``negative_shares``)."""
        return cls(spec.sequence, spec.params, spec.seed, spec.n_frames, spec.label, **instruments)
