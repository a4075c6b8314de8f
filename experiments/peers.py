"""Peer trackers: OpenCV trackers and the paper's lineage run live, and the shipped per-frame peer results.

Three sources of peer numbers, all scored with :mod:`nrmlc.workbench.metrics` against
*our* ground truth, exactly like NRMLC:

1. **Live OpenCV trackers** (:func:`live_trackers`): ``cv2.TrackerMIL`` always
   (OpenCV's re-implementation of Babenko's MIL), and ``TrackerKCF`` /
   ``TrackerCSRT`` when the installed OpenCV has them (opencv-contrib), with OpenCV's
   defaults but for :data:`LIVE_PARAMETERS` (KCF's failure threshold). Each run
   has a fresh process of its own (:func:`run_live`), which makes it
   deterministic, so one run per sequence; each run is cached like the
   NRMLC runs (``<run cache>/peers/<key>.npz``, written atomically) with a key
   that hashes the tracker, the OpenCV version, the Intel IPP code path OpenCV
   dispatches to (:func:`opencv_ipp`), the sequence and the frame count, so a rerun
   recomputes nothing and an OpenCV upgrade, or a CPU whose IPP path differs,
   recomputes all.
   Their fps is the time spent in ``init`` and ``update`` (decoding excluded),
   as for NRMLC.
2. **Shipped results** (:func:`shipped_results`): ``<peer root>/<Tracker>/<Seq>.txt``
   (ASLA, IVT, KCF on the OTB-100 versions of the paper's sequences) and
   ``<peer root>/<Tracker>/sparsepack/<Seq>.txt`` (L1, MIL, IVT on the
   sparse-tracker versions). A file is used for one of our sequences only if
   it has one line per frame *and* its first box is the sequence's initial
   box (IoU >= 0.5): OTB-100 FaceOcc1 (892 lines) does not fit our pack
   Occlusion1 (898 frames), and the pack Car4 has 659 lines like our OTB Car4
   but is at twice the resolution. Every skipped file is reported with the
   reason.
3. **The lineage, live** (:data:`LINEAGE_LIVE`): the trackers of :mod:`nrmlc.lineage` (IVT,
   ASLA, L1, L1-APG, MTT) as the OTB benchmark's MATLAB runs them, through the run cache as ``nrmlc benchmark
   --tracker ivt`` runs them, one run per seed of the context (they are random, like NRMLC; MTT,
   the slowest, on fewer: :data:`LINEAGE_SEED_LIMIT`).
"""
from __future__ import annotations

import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from experiments.sequence_sets import PAPER_NAME_OF, paper_name
from nrmlc.workbench.jobs import CachedJob, sequence_identity
from nrmlc.workbench.run_cache import RunCache

#: Bump when the live runner's behaviour changes (it is part of every key, as is each
#: tracker's entry of :data:`LIVE_PARAMETERS`).
LIVE_RUNNER_VERSION = 3

#: OpenCV trackers tried, in column order (only the available ones are run).
LIVE_CANDIDATES = ("MIL", "KCF", "CSRT")

#: Parameters that differ from OpenCV's defaults. KCF as published (Henriques et al., TPAMI
#: 2015) moves to its response peak on every frame; OpenCV adds ``detect_thresh`` (0.5), below
#: which ``update`` reports a failure and neither moves the box nor learns. With OpenCV 5.0.0
#: the peak was below 0.5 on 0.31 to 1.00 of the frames of the development sequences
#: (Basketball from frame 1, Couple 0.97), so the default KCF stayed where it started: 0.094
#: mean overlap there, 0.353 with the threshold 0 (measured 2026-12-01;
#: docs/findings/opencv-kcf-csrt.md).
LIVE_PARAMETERS = {"KCF": {"detect_thresh": 0.0}}

#: The lineage's live trackers in the tables, by short name (:data:`nrmlc.lineage.TRACKERS`), in
#: column order. IVT's and ASLA's agreement with the benchmark's own files is measured
#: (docs/research/lineage-fidelity.md), L1's with the sparse-tracker pack's on Caviar1 and
#: Occlusion1/2; the benchmark shipped no L1-APG files, so its column sits beside the paper's
#: printed L1APG numbers.
LINEAGE_LIVE = ("ivt", "asla", "l1", "l1apg", "mtt")

#: How many of the context's seeds (its first) a lineage tracker runs, where not all: MTT codes
#: all 600 particles jointly for up to 100 steps (about 180 ms a frame on a 2-core EPYC), so five
#: seeds of the 21 sequences at hand would take about two core-hours; one takes 25 minutes.
LINEAGE_SEED_LIMIT = {"mtt": 1}

#: Shipped result folders, and the subfolders holding other versions of sequences.
SHIPPED_TRACKERS = ("L1", "MIL", "IVT", "ASLA", "KCF")
SHIPPED_SUBFOLDERS = ("", "sparsepack")



def opencv_version() -> str:
    import cv2

    return cv2.__version__


def opencv_ipp() -> str:
    """The Intel IPP build and code path OpenCV uses in this process (``'off'`` without IPP), e.g.
    ``'ippIP AVX2 (l9) 2026.0.0 (-) Mar 27 2026'``. IPP picks its path by the CPU, and CSRT's boxes
    follow it (AVX-512's ``k0`` against AVX2's ``l9``: docs/RELIABILITY.md#determinism);
    ``OPENCV_IPP=avx2`` (set by ``make figures PORTABLE=1``) holds it at AVX2 on any CPU."""
    import cv2

    return cv2.ipp.getIppVersion() if cv2.ipp.useIPP() else "off"


def _factory(name: str):
    """The OpenCV constructor of tracker ``name`` (``cv2.TrackerMIL_create`` or ``cv2.TrackerMIL.create``), or None."""
    import cv2

    create = getattr(cv2, f"Tracker{name}_create", None)
    if create is None:
        create = getattr(getattr(cv2, f"Tracker{name}", None), "create", None)
    return create


def _create(name: str):
    """A new OpenCV tracker ``name`` with :data:`LIVE_PARAMETERS` applied, or None if this
    OpenCV has none."""
    import cv2

    create = _factory(name)
    if create is None:
        return None
    changes = LIVE_PARAMETERS.get(name)
    if not changes:
        return create()
    params_type = getattr(cv2, f"Tracker{name}_Params", None) or getattr(cv2, f"Tracker{name}").Params
    params = params_type()
    for option, value in changes.items():
        setattr(params, option, value)
    return create(params)


def live_trackers() -> list[str]:
    """The OpenCV trackers available here (MIL always; KCF/CSRT need opencv-contrib)."""
    return [name for name in LIVE_CANDIDATES if _factory(name) is not None]


def live_label(name: str) -> str:
    """Column name of a live OpenCV tracker."""
    return f"{name} (OpenCV)"


@dataclass(frozen=True)
class LiveSpec(CachedJob):
    """One live OpenCV run: ``tracker`` on the first ``n_frames`` frames of ``sequence``.

    A job of :class:`nrmlc.workbench.run_cache.RunCache`, stored under ``<cache>/peers/``; its key
    does not depend on our code version (OpenCV's version is in it instead).
    """

    sequence: object
    tracker: str = "MIL"
    n_frames: int | None = None

    folder: ClassVar[str] = "peers"
    uses_kernels: ClassVar[bool] = False

    @property
    def label(self) -> str:
        return f"{self.tracker} (OpenCV) {self.sequence.name}"

    def description(self, version: str | None = None) -> dict:
        return {"tracker": self.tracker, "opencv": opencv_version(), "ipp": opencv_ipp(), "runner": LIVE_RUNNER_VERSION,
                "parameters": LIVE_PARAMETERS.get(self.tracker, {}),
                "sequence": sequence_identity(self.sequence), "sequence_name": self.sequence.name,
                "n_frames": self.n_frames}

    def execute(self) -> dict:
        return run_live(self)

    def result(self, arrays: dict) -> "PeerResult":
        return PeerResult(np.asarray(arrays["boxes"]), float(arrays["seconds_tracking"]),
                          f"live, OpenCV {opencv_version()}")


@dataclass
class PeerResult:
    """Boxes of a peer on one sequence.

    Attributes
    ----------
    boxes : (n, 4) float64
        1-based OTB boxes from frame 0 (NaN where the tracker reported a failure).
    seconds_tracking : float
        Time in ``init`` + ``update`` (NaN for shipped results).
    source : str
        Where the boxes come from (``live OpenCV 4.x`` or the file's path).
    """

    boxes: np.ndarray
    seconds_tracking: float = float("nan")
    source: str = ""

    @property
    def fps_tracking(self) -> float:
        n = len(self.boxes) - 1
        return n / self.seconds_tracking if self.seconds_tracking > 0 else float("nan")


def _to_cv_rect(box) -> tuple[int, int, int, int]:
    """1-based float OTB box -> 0-based integer OpenCV rect."""
    x, y, w, h = (float(v) for v in box)
    return (int(round(x - 1)), int(round(y - 1)), max(1, int(round(w))), max(1, int(round(h))))


def run_live(spec: LiveSpec) -> dict:
    """Run one OpenCV tracker over a sequence, in a fresh process of its own.

    OpenCV's MIL keeps random state from one tracker to the next within a process, and
    ``cv2.setRNGSeed`` does not reset it: the second MIL run on a sequence in one process gave
    other boxes than the first (Deer: up to 320 px apart), so a run's boxes depended on the
    runs its worker had done before. The first run of a fresh process is the same every time.

    Returns
    -------
    dict of arrays: ``boxes`` (n, 4) 1-based, ``seconds_tracking`` scalar.
    """
    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(_run_live_here, spec).result()


def _run_live_here(spec: LiveSpec) -> dict:
    """:func:`run_live` in the calling process."""
    tracker = _create(spec.tracker)
    if tracker is None:
        raise RuntimeError(f"OpenCV {opencv_version()} has no Tracker{spec.tracker}")
    sequence = spec.sequence
    n = spec.frames()
    boxes = np.full((n, 4), np.nan)
    init = sequence.init_box
    boxes[0] = init
    seconds = 0.0
    for index in range(n):
        frame = sequence.color_frame(index)
        tick = time.perf_counter()
        if index == 0:
            tracker.init(frame, _to_cv_rect(init))
            seconds += time.perf_counter() - tick
            continue
        ok, rect = tracker.update(frame)
        seconds += time.perf_counter() - tick
        if ok:
            x, y, w, h = (float(v) for v in rect)
            boxes[index] = (x + 1.0, y + 1.0, w, h)  # back to 1-based
    return {"boxes": boxes, "seconds_tracking": np.float64(seconds)}


def cache_for(context) -> RunCache:
    """The run cache (live runs are stored in its ``peers/`` folder)."""
    return context.cache


def live_specs(context, sequences=None) -> list[LiveSpec]:
    """One LiveSpec per (available OpenCV tracker, sequence); default: every given sequence."""
    sequences = context.sequences() if sequences is None else sequences
    return [LiveSpec(s, name, context.max_frames) for name in live_trackers() for s in sequences]


def live_results(context, sequences=None) -> dict:
    """{tracker: {sequence name: PeerResult}} for the live OpenCV trackers (cached)."""
    specs = live_specs(context, sequences)
    results = cache_for(context).run(specs, executor=context.executor, jobs=context.jobs)
    table: dict = {}
    for spec, result in zip(specs, results):
        table.setdefault(spec.tracker, {})[spec.sequence.name] = result
    return table


def lineage_label(name: str) -> str:
    """Column name of a live lineage tracker (``"ivt"`` -> ``"IVT (live)"``)."""
    return f"{name.upper()} (live)"


def lineage_seeds(name: str, context) -> list[int]:
    """The seeds lineage tracker ``name`` runs: the context's, cut to :data:`LINEAGE_SEED_LIMIT`."""
    seeds = list(context.seeds)
    return seeds[:LINEAGE_SEED_LIMIT.get(name, len(seeds))]


def lineage_specs(context, sequences=None) -> list:
    """One run per (lineage tracker of :data:`LINEAGE_LIVE`, sequence, seed of :func:`lineage_seeds`)."""
    from nrmlc.workbench.trackers import ImportedTracker

    sequences = context.sequences() if sequences is None else sequences
    return [ImportedTracker(name).job(s, seed, context.max_frames) for name in LINEAGE_LIVE for s in sequences
            for seed in lineage_seeds(name, context)]


def lineage_results(context, sequences=None) -> dict:
    """{column label: {sequence name: [TrackResult of each seed]}} for the live lineage (cached)."""
    sequences = context.sequences() if sequences is None else sequences
    specs = lineage_specs(context, sequences)
    results = iter(cache_for(context).run(specs, executor=context.executor, jobs=context.jobs))
    return {lineage_label(name): {s.name: [next(results) for _ in lineage_seeds(name, context)] for s in sequences}
            for name in LINEAGE_LIVE}


# --------------------------------------------------------------- shipped files
def _candidate_names(sequence_name: str) -> list[str]:
    """File stems a shipped result for this sequence may have (ours, the paper's, the OTB-100 one)."""
    names = [sequence_name]
    paper = paper_name(sequence_name)
    if paper is not None:
        names.append(paper)
    # Reverse aliases (a pack 'Cliffbar' result for an OTB 'ClifBar' folder and so on).
    names += [alias for alias, target in PAPER_NAME_OF.items() if target.lower() == sequence_name.lower()]
    seen, unique = set(), []
    for name in names:
        if name.lower() not in seen:
            seen.add(name.lower())
            unique.append(name)
    return unique


def _find_file(folder: Path, stems: list[str]) -> Path | None:
    if not folder.is_dir():
        return None
    files = {p.stem.lower(): p for p in folder.glob("*.txt")}
    for stem in stems:
        if stem.lower() in files:
            return files[stem.lower()]
    return None


@dataclass
class Shipped:
    """Shipped peer results usable on one sequence, and what was skipped (with reasons)."""

    results: dict = field(default_factory=dict)  # tracker -> PeerResult
    notes: list = field(default_factory=list)


def shipped_results(peer_root, sequence, trackers=SHIPPED_TRACKERS) -> Shipped:
    """Load and check the shipped per-frame results of each peer for ``sequence``.

    Parameters
    ----------
    peer_root : path or None
        The ``peer_results`` folder (None: nothing shipped).
    sequence : Sequence
    trackers : iterable of str

    Returns
    -------
    Shipped
        ``results[tracker]`` holds the first file (top folder, then
        ``sparsepack/``) that has one line per frame and starts at the
        sequence's initial box; every other candidate file is named in
        ``notes`` with the reason it was not used.
    """
    from nrmlc.data import read_box_file
    from nrmlc.workbench.metrics import first_box_mismatch

    found = Shipped()
    if peer_root is None:
        return found
    peer_root = Path(peer_root)
    stems = _candidate_names(sequence.name)
    for tracker in trackers:
        for sub in SHIPPED_SUBFOLDERS:
            path = _find_file(peer_root / tracker / sub if sub else peer_root / tracker, stems)
            if path is None:
                continue
            where = path.relative_to(peer_root)
            try:
                boxes = read_box_file(path)
            except Exception as exc:  # a broken file is a note, not a crash of the table
                found.notes.append(f"{tracker} on {sequence.name}: {where} unreadable ({exc})")
                continue
            if len(boxes) != len(sequence):
                found.notes.append(f"{tracker} on {sequence.name}: {where} has {len(boxes)} lines for "
                                   f"{len(sequence)} frames (another version of the sequence), not used")
                continue
            first = sequence.groundtruth[0]
            if np.isfinite(first).all():
                mismatch = first_box_mismatch(boxes, first)
                if mismatch:
                    found.notes.append(f"{tracker} on {sequence.name}: {where} starts at {mismatch[0]}, not at our "
                                       f"initial box {mismatch[1]} (IoU {mismatch[2]:.2f}; another version), not used")
                    continue
            found.results[tracker] = PeerResult(boxes, float("nan"), str(where))
            break  # the first fitting version wins; later folders hold other versions
    return found


def shipped_for(context, sequences=None) -> tuple[dict, list]:
    """{tracker: {sequence name: PeerResult}} of usable shipped results, and the notes."""
    sequences = context.sequences() if sequences is None else sequences
    root = context.shipped_peer_root()
    table: dict = {}
    notes: list = []
    if root is None:
        if not context.is_synthetic:
            notes.append(f"no shipped peer results found ({context.peer_root or context.data_root.parent / 'peer_results'}"
                         " missing)")
        return table, notes
    for sequence in sequences:
        shipped = shipped_results(root, sequence)
        for tracker, result in shipped.results.items():
            table.setdefault(tracker, {})[sequence.name] = result
        notes += shipped.notes
    milpack = root / "MIL" / "milpack"
    if milpack.is_dir():
        notes.append("MIL/milpack (Babenko's MIL-dataset runs on faceocc/faceocc2) not used: its rows follow "
                     "the MIL dataset's own frame range, not our frames")
    return table, notes
