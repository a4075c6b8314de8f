"""Running the tracker over a whole sequence, with per-frame diagnostics."""
from __future__ import annotations

import time
from dataclasses import dataclass, field, fields

import numpy as np

from nrmlc.errors import ParameterError
from nrmlc.tracker.experts import make_tracker
from nrmlc.tracker.params import TrackerParams
from nrmlc.tracker.records import FrameResult

#: FrameResult fields stored per frame in a TrackResult (frame 0 gets NaN / 0).
DIAGNOSTIC_FIELDS = tuple(f.name for f in fields(FrameResult) if f.name not in ("state", "box"))


@dataclass
class TrackResult:
    """Boxes, states and diagnostics of one tracking run.

    Attributes
    ----------
    boxes : (n_frames, 4) float64
        1-based OTB boxes; row 0 is the initial box.
    states : (n_frames, 6) float64
    diagnostics : dict of str -> (n_frames, ...) arrays
        One array per :class:`FrameResult` field (row 0 holds NaN or 0).
    seconds_tracking : float
        Time spent in ``init`` and ``update`` (frame decoding excluded).
    seconds_total : float
        Wall time including frame decoding.
    """

    boxes: np.ndarray
    states: np.ndarray
    diagnostics: dict = field(default_factory=dict)
    seconds_tracking: float = 0.0
    seconds_total: float = 0.0

    @property
    def fps_tracking(self) -> float:
        return (len(self.boxes) - 1) / self.seconds_tracking if self.seconds_tracking > 0 else float("nan")

    @property
    def fps_total(self) -> float:
        return (len(self.boxes) - 1) / self.seconds_total if self.seconds_total > 0 else float("nan")

    def to_arrays(self) -> dict:
        arrays = {"boxes": self.boxes, "states": self.states,
                  "seconds_tracking": np.float64(self.seconds_tracking),
                  "seconds_total": np.float64(self.seconds_total)}
        arrays.update({f"diag_{k}": v for k, v in self.diagnostics.items()})
        return arrays

    @classmethod
    def from_arrays(cls, arrays) -> "TrackResult":
        diagnostics = {k[5:]: np.asarray(arrays[k]) for k in arrays if k.startswith("diag_")}
        return cls(np.asarray(arrays["boxes"]), np.asarray(arrays["states"]), diagnostics,
                   float(arrays["seconds_tracking"]), float(arrays["seconds_total"]))


def _stack(results: list[FrameResult], name: str) -> np.ndarray:
    first = np.asarray(getattr(results[0], name))
    filler = np.zeros_like(first) if first.dtype.kind in "biu" else np.full(first.shape, np.nan)
    return np.stack([filler] + [np.asarray(getattr(r, name)) for r in results[1:]])


def track_sequence(sequence, params: TrackerParams | None = None, seed: int = 0, n_frames: int | None = None,
                   init_box=None, progress: bool = False, on_frame=None, tracker=None) -> TrackResult:
    """Track ``sequence`` from its first frame.

    Parameters
    ----------
    sequence : nrmlc.data.Sequence
    params : TrackerParams, optional
    seed : int
    n_frames : int, optional
        Track only the first ``n_frames`` frames.
    init_box : (4,) array, optional
        Initial box; defaults to ``sequence.init_box``.
    progress : bool
        Show a tqdm progress bar on stderr.
    on_frame : callable(frame_index, tracker, frame), optional
        Called after every frame (e.g. to draw a video or collect statistics).
    tracker : optional
        The tracker to run (anything with ``init``, ``update``, ``initial_box``, ``state`` and
        ``last``, e.g. a subclass for a diagnostic); ``params`` and ``seed`` are then its own.
        Default: :func:`~nrmlc.tracker.experts.make_tracker` of ``params`` and ``seed``.

    Returns
    -------
    TrackResult
    """
    if tracker is None:
        tracker = make_tracker(params, seed)
    if n_frames is not None and (isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer))
                                 or n_frames < 1):
        raise ParameterError(f"n_frames must be an integer >= 1 (or None: all frames), got {n_frames!r}")
    total = len(sequence) if n_frames is None else max(1, min(int(n_frames), len(sequence)))
    box = sequence.init_box if init_box is None else init_box
    frames = iter(sequence)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=total, desc=f"{sequence.name}", unit="frame", leave=False, disable=None)
    start = time.perf_counter()
    tracking = 0.0
    boxes, states, results = [], [], [None]
    for index in range(total):
        frame = next(frames)
        tick = time.perf_counter()
        if index == 0:
            tracker.init(frame, box)
            boxes.append(np.array(tracker.initial_box, dtype=np.float64))
            states.append(tracker.state.copy())
        else:
            boxes.append(tracker.update(frame))
            states.append(tracker.last.state.copy())  # the output's (the chosen expert's, in a pair)
            results.append(tracker.last)
        tracking += time.perf_counter() - tick
        if on_frame is not None:
            on_frame(index, tracker, frame)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    total_seconds = time.perf_counter() - start
    diagnostics = {}
    if len(results) > 1:
        results[0] = results[1]  # template for the frame-0 filler row
        diagnostics = {name: _stack(results, name) for name in DIAGNOSTIC_FIELDS}
    return TrackResult(np.array(boxes), np.array(states), diagnostics, tracking, total_seconds)
