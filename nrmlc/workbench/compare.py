"""Compare trackers: score result folders against a data root, print a table, draw OTB plots.

``python -m nrmlc evaluate --results results/NRMLC results/MyTracker PEERS/IVT --data DATA --plot out.png``

A *result folder* holds one ``<Seq>.txt`` per sequence, one ``x,y,w,h`` line
per frame from frame 1 (the OTB toolkit's layout; what ``nrmlc benchmark``
writes). Any tracker's folder works; its name in the table and the plots is
the folder's name unless ``--names`` says otherwise. Nothing here is specific
to NRMLC: adding a tracker to the comparison is adding its folder.

Finding a sequence's file in a folder
    The file stem is the sequence's name (case-insensitive), or a name that
    ``--name-map FILE_STEM=SEQUENCE`` maps to it (e.g. ``FaceOcc1=Occlusion1``).
    The folder itself is searched first, then its subfolders one level down
    in name order (e.g. ``peer_results/IVT/sparsepack/``). A file is taken
    only if its first box is the sequence's initial box (IoU >= 0.5, when
    frame 1 is annotated): results on another version of a sequence (another
    resolution or frame range) are refused, with a note. Among the files that
    pass, one with exactly one line per frame wins over one with another
    line count.

Other result layouts
    A folder of the OTB toolkit's own ``<Seq>_<Tracker>.mat`` files (and no ``.txt``) is one
    tracker per ``<Tracker>`` (:mod:`nrmlc.workbench.otb_results`); ``DIR:A,B`` or ``--otb-trackers A,B``
    selects some. Sequence names match without regard to case and to the benchmark's spellings
    of a target number (``Skating2.1`` is ``Skating2-1``, :func:`nrmlc.workbench.otb_results.sequence_key`);
    two files of one folder level that name the same sequence (``car4.txt``, ``Car4.txt``) are
    refused.

What is scored
    A folder made by ``nrmlc benchmark`` (it has a ``benchmark.json``) says which sequences it
    ran, with which frame cap and seeds: unless ``--sequences`` or ``--max-frames`` say
    otherwise, every tracker is scored on those sequences (of every such folder) and frames
    (the smallest cap). The first line of the table says what was scored.

Missing predictions
    Scored by :func:`nrmlc.workbench.metrics.evaluate` (see the docstring of
    :mod:`nrmlc.workbench.metrics` for every convention): a frame whose predicted row is
    missing (no file for the sequence, fewer lines than frames) or not a
    has no finite box counts as a failed frame, the same way in the success
    and the precision curves (see :data:`MISSING_RULE`).

Averages
    As the OTB toolkit (and got10k's ``ExperimentOTB``): a tracker's success
    and precision curves are the mean over sequences of its per-sequence
    curves; AUC is the mean of its success curve, precision@20 its precision
    curve at 20 px; mean overlap and mean CLE are means over sequences of
    the per-sequence means.
"""
from __future__ import annotations

import argparse
import csv
import io as text_io
import json
import math
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nrmlc import io
from nrmlc.errors import DataError, ParameterError
from nrmlc.workbench.otb_results import find_otb_result, is_otb_results_folder, select_trackers, sequence_key
from nrmlc.workbench.results_layout import MANIFEST_NAME, SEEDS_FOLDER, parse_names, select_sequences

#: How a missing prediction is scored, for ``--help`` and the table's footnote;
#: it restates the "Missing predictions" paragraph of :mod:`nrmlc.workbench.metrics`.
MISSING_RULE = (
    "A scored frame without a prediction (no result file for the sequence, fewer lines than frames, a NaN "
    "or 0,0,0,0 row, an infinite value or one beyond 1e9 px) is a failed frame: overlap 0 and centre "
    "error +inf, so it fails every threshold of both the success and the precision plot and lowers AUC, "
    "precision@20 and the mean overlap alike. The mean CLE can only average frames that have a box, so "
    "the table gives the count of missing frames beside it. A finite box of zero or negative size is "
    "scored as it is (overlap 0, the error of its centre). Frame 1 (the given box) and frames without "
    "ground truth are not scored (nrmlc.workbench.metrics).")


SCORE_NAMES = ("success_auc", "precision_20", "mean_overlap", "mean_center_error")

#: What the means of the table are over, for its footnote.
MEANS_RULE = ("means over every scored sequence: one without a result ('-') counts as every frame failed "
              "(--common keeps only the sequences every tracker has); CLE over the frames with a prediction only")


@dataclass
class TrackerScores:
    """One tracker's results on the compared sequences.

    Attributes
    ----------
    name : str
    folder : Path
    files : dict of sequence name -> Path or None (no usable file)
    evaluations : dict of sequence name -> nrmlc.workbench.metrics.Evaluation
        Every compared sequence has one; a sequence without a file is all failures.
    seed_runs : list of dict
        With ``all_seeds``: one ``evaluations``-like dict per scored seed
        folder (``folder`` itself first, then ``folder/seeds/<seed>``).
    seed_labels : list of str
        The seed of each of ``seed_runs`` (the top folder's from its
        ``benchmark.json``, ``""`` if unknown).
    notes : list of str
        Files not used and why; line-count mismatches.
    otb_tracker : str or None
        The ``<Tracker>`` of a folder of OTB ``.mat`` results (None: a folder of ``<Seq>.txt``).
    speeds : dict of sequence name -> (fps, frames)
        The recorded speed of the runs scored (``.mat`` files' ``fps``, ``benchmark.json``'s).
    """

    name: str
    folder: Path
    files: dict = field(default_factory=dict)
    evaluations: dict = field(default_factory=dict)
    seed_runs: list = field(default_factory=list)
    seed_labels: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    otb_tracker: str | None = None
    speeds: dict = field(default_factory=dict)

    @property
    def runs(self) -> list:
        """The scored runs: one dict {sequence: Evaluation} per seed (just ``evaluations`` by default)."""
        return self.seed_runs or [self.evaluations]

    @property
    def success(self) -> np.ndarray:
        """(21,) mean over seeds and sequences of the success curves."""
        return np.mean([[e.success for e in run.values()] for run in self.runs], axis=(0, 1))

    @property
    def precision(self) -> np.ndarray:
        """(51,) mean over seeds and sequences of the precision curves."""
        return np.mean([[e.precision for e in run.values()] for run in self.runs], axis=(0, 1))

    @property
    def fps(self) -> float | None:
        """Frames per second over the scored sequences with a recorded speed: total frames over total time."""
        known = [(f, n) for f, n in self.speeds.values() if f is not None and f > 0 and n > 0]
        if not known:
            return None
        return float(sum(n for _, n in known) / sum(n / f for f, n in known))

    def sequence_auc(self, sequence: str) -> float:
        """Success AUC on one sequence (mean over seeds)."""
        return float(np.mean([run[sequence].success_auc for run in self.runs]))

    def summary(self) -> dict:
        """Overall scores (means over seeds and sequences) and coverage counts."""
        from nrmlc.workbench.metrics import PRECISION_AT, PRECISION_THRESHOLDS

        evaluations = [e for run in self.runs for e in run.values()]
        cle = [e.mean_center_error for e in evaluations if not math.isnan(e.mean_center_error)]
        precision_index = int(np.flatnonzero(PRECISION_THRESHOLDS == PRECISION_AT)[0])
        per_seed_auc = [np.mean([e.success_auc for e in run.values()]) for run in self.runs]
        return {
            "tracker": self.name,
            "folder": str(self.folder),
            "seeds": len(self.runs),
            "sequences": len(self.evaluations),
            "sequences_with_results": sum(p is not None for p in self.files.values()),
            "frames": int(sum(e.n_frames for e in evaluations)),
            "missing_frames": int(sum(e.n_missing for e in evaluations)),
            "success_auc": float(np.mean(self.success)),
            "success_auc_std_over_seeds": float(np.std(per_seed_auc)) if len(self.runs) > 1 else None,
            "precision_20": float(self.precision[precision_index]),
            "mean_overlap": float(np.mean([e.mean_overlap for e in evaluations])),
            "mean_center_error": float(np.mean(cle)) if cle else None,
            "fps": self.fps,
            "fps_sequences": sum(1 for f, _ in self.speeds.values() if f is not None),
        }


@dataclass
class Comparison:
    """Every tracker scored on the same sequences."""

    sequences: list
    trackers: list  # of TrackerScores
    notes: list = field(default_factory=list)
    max_frames: int | None = None  # scored only the first frames of each sequence
    scope: dict = field(default_factory=dict)  # what was scored and why (format_scope)

    def as_dict(self) -> dict:
        return {
            "scored": format_scope(self),
            "sequences": list(self.sequences),
            "max_frames": self.max_frames,
            "missing_predictions": MISSING_RULE,
            "trackers": [
                {**t.summary(),
                 "per_sequence": {name: {**e.as_dict(), "file": None if t.files[name] is None else str(t.files[name]),
                                         "success_auc_mean_over_seeds": t.sequence_auc(name)}
                                  for name, e in t.evaluations.items()},
                 "success_curve": t.success.tolist(), "precision_curve": t.precision.tolist(),
                 "notes": list(t.notes)}
                for t in self.trackers],
            "notes": list(self.notes),
        }


def parse_name_map(items) -> dict:
    """``["FaceOcc1=Occlusion1", "A=B,C=D"]`` -> {file stem (lower case): sequence name (lower case)}."""
    mapping = {}
    for item in items or ():
        for pair in (p.strip() for p in str(item).split(",")):
            if not pair:
                continue
            stem, sep, sequence = (s.strip() for s in pair.partition("="))
            if not sep or not stem or not sequence:
                raise ParameterError(f"--name-map {pair!r}: expected FILE_STEM=SEQUENCE")
            mapping[stem.lower()] = sequence.lower()
    return mapping


def _candidates(folder: Path, sequence_name: str, name_map: dict) -> list[Path]:
    """Result files that may hold ``sequence_name``: the folder first, then its subfolders.

    Raises
    ------
    DataError
        For two files of one folder whose names differ only by case or by the spelling of a
        target number (``car4.txt``, ``Car4.txt``): which one is meant cannot be known.
    """
    key = sequence_key(sequence_name)
    stems = {key} | {sequence_key(stem) for stem, target in name_map.items() if sequence_key(target) == key}
    folders = [folder] + sorted((p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")),
                                key=lambda p: p.name)
    found = []
    for where in folders:
        here = sorted(p for p in where.glob("*.txt") if sequence_key(p.stem) in stems and p.is_file())
        by_stem: dict = {}
        for path in here:
            by_stem.setdefault(sequence_key(path.stem), []).append(path)
        for same in by_stem.values():
            if len(same) > 1:
                raise DataError(f"{same[0]} and {same[1]} both name sequence {sequence_name} (their names differ "
                                f"only by case or spelling); keep one")
        found += here
    return found


def find_result(folder, sequence, name_map=None, max_frames: int | None = None):
    """The result file of ``sequence`` in ``folder`` and its boxes (see the module docstring).

    Returns
    -------
    path : Path or None
    boxes : (m, 4) float64 or None
    notes : list of str
        Candidates refused, and a line-count mismatch of the file taken.
    """
    from nrmlc.data import read_box_file
    from nrmlc.geometry import usable_boxes
    from nrmlc.workbench.metrics import first_box_mismatch

    folder = Path(folder)
    n_frames = len(sequence) if max_frames is None else min(len(sequence), max_frames)
    first = sequence.groundtruth[0]
    check_first = bool(usable_boxes(first[None, :])[0])
    notes, fitting = [], []
    for path in _candidates(folder, sequence.name, name_map or {}):
        try:
            boxes = read_box_file(path, predictions=True)
        except DataError as exc:
            notes.append(f"{path}: not used, unreadable ({exc})")
            continue
        mismatch = first_box_mismatch(boxes, first) if check_first and len(boxes) and np.isfinite(boxes[0]).all() else None
        if mismatch:
            notes.append(f"{path}: not used, its first box {mismatch[0]} is not {sequence.name}'s initial box "
                         f"{mismatch[1]} (IoU {mismatch[2]:.2f}; results on another version of the sequence?)")
            continue
        fitting.append((path, boxes))
    if not fitting:
        return None, None, notes
    exact = [(p, b) for p, b in fitting if len(b) == len(sequence) or (max_frames is not None and len(b) >= n_frames)]
    path, boxes = (exact or fitting)[0]
    if not exact:
        if len(boxes) < n_frames:
            notes.append(f"{path}: {len(boxes)} lines for {n_frames} frames; the last "
                         f"{n_frames - len(boxes)} count as missing predictions")
        else:
            notes.append(f"{path}: {len(boxes)} lines for {len(sequence)} frames; extra lines ignored")
    return path, boxes[:n_frames], notes


def split_results_entry(entry) -> tuple[Path, list[str] | None]:
    """``"DIR"`` -> (DIR, None); ``"DIR:ASLA,IVT"`` -> (DIR, ["ASLA", "IVT"]) when DIR is a folder.

    A path that exists as written is never split (a folder name may hold a colon).
    """
    text = str(entry)
    path = Path(text)
    if path.exists() or ":" not in text:
        return path, None
    folder, _, selection = text.rpartition(":")
    if not folder or not Path(folder).is_dir():
        return path, None
    names = [n.strip() for n in selection.split(",") if n.strip()]
    if not names:
        raise ParameterError(f"--results {text}: no tracker named after the ':'")
    return Path(folder), names


def result_sources(entries, otb_trackers=None) -> list[tuple[str, Path, str | None]]:
    """One ``(name, folder, OTB tracker or None)`` per tracker of the ``--results`` entries.

    A folder of ``<Seq>.txt`` files is one tracker named after the folder; a folder of OTB
    ``<Seq>_<Tracker>.mat`` files is one tracker per ``<Tracker>`` (those of ``DIR:A,B``, else
    those of ``otb_trackers``, else all), named ``<Tracker>``.
    """
    sources = []
    for entry in entries:
        folder, wanted = split_results_entry(entry)
        if not folder.is_dir():
            raise DataError(f"{folder}: result folder {'is not a folder' if folder.exists() else 'not found'}")
        if is_otb_results_folder(folder):
            for tracker in select_trackers(folder, wanted or otb_trackers):
                sources.append((tracker, folder, tracker))
        elif wanted is not None:
            raise ParameterError(f"--results {entry}: ':{','.join(wanted)}' selects trackers of a folder of OTB "
                                 f"<Seq>_<Tracker>.mat files; {folder} is a folder of <Seq>.txt files")
        else:
            sources.append((folder.resolve().name, folder, None))
    return sources


def read_manifest(folder) -> dict | None:
    """The ``benchmark.json`` of a ``nrmlc benchmark`` folder, None for any other folder.

    Raises
    ------
    DataError
        For a ``benchmark.json`` that is not a benchmark manifest.
    """
    path = Path(folder) / MANIFEST_NAME
    if not path.is_file():
        return None
    try:
        manifest = json.loads(path.read_text())
        settings, runs = manifest["settings"], manifest.get("runs", {})
        if not isinstance(settings, dict) or not isinstance(runs, dict):
            raise TypeError("settings and runs must be objects")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DataError(f"{path}: not a benchmark manifest ({exc})") from None
    return manifest


def _seed_text(seeds) -> str:
    return ",".join(str(s) for s in sorted(seeds, key=int))


def _chosen_sequences(data_root, names, from_manifests: bool, notes: list) -> list:
    """``select_sequences``; names taken from manifests that the root lacks are noted and left out."""
    if not from_manifests:
        return select_sequences(data_root, names)
    try:
        return select_sequences(data_root, names)
    except DataError:
        from nrmlc.data import list_sequences

        by_key = {sequence_key(s.name): s for s in list_sequences(data_root)}
        absent = [n for n in names if sequence_key(n) not in by_key]
        notes.append(f"{len(absent)} sequence(s) of benchmark.json not in {data_root}, not scored: "
                     f"{', '.join(absent)}")
        return list({by_key[sequence_key(n)].name: by_key[sequence_key(n)]
                     for n in names if sequence_key(n) in by_key}.values())


def compare(result_folders, data_root, names=None, sequences=None, name_map=None, max_frames=None,
            common_only: bool = False, skip_first: bool = True, all_seeds: bool = False,
            otb_trackers=None, follow_manifests: bool = True) -> Comparison:
    """Score each result folder on the sequences of ``data_root``.

    Parameters
    ----------
    result_folders : list of paths
        Folders of ``<Seq>.txt`` files (one tracker each) or of OTB ``<Seq>_<Tracker>.mat``
        files (one tracker per ``<Tracker>``; ``"DIR:A,B"`` selects some).
    data_root : path
        Folder of sequences with ground truth (any layout :func:`nrmlc.data.list_sequences` reads).
    names : list of str, optional
        Tracker names, one per tracker in the order of the folders (default: a ``.txt`` folder's
        name, a ``.mat`` tracker's ``<Tracker>``; repeated names get ``-2``, ``-3``).
    sequences : list of str, optional
        Only these sequences (default: those of the ``nrmlc benchmark`` folders given, else every
        sequence of the root with ground truth).
    name_map : dict, optional
        {file stem: sequence name} (see :func:`parse_name_map`).
    max_frames : int, optional
        Score only the first frames of each sequence (default: the smallest frame cap of the
        ``nrmlc benchmark`` folders given, else every frame).
    common_only : bool
        Score only the sequences every tracker has a file for.
    skip_first : bool
        Do not score frame 1 (the given box), the OTB convention.
    all_seeds : bool
        Also score the other seeds of a ``nrmlc benchmark`` folder
        (``<folder>/seeds/<seed>/``) and average over seeds.
    otb_trackers : list of str, optional
        The trackers to take from folders of ``.mat`` files without a ``DIR:A,B`` selection.
    follow_manifests : bool
        Take the default sequences and frame cap from the ``benchmark.json`` of the folders.

    Returns
    -------
    Comparison
    """
    from nrmlc.workbench.metrics import evaluate

    if not list(result_folders):
        raise ParameterError("--results: give at least one result folder")
    sources = result_sources(result_folders, otb_trackers)
    if not sources:
        raise DataError(f"{', '.join(map(str, result_folders))}: no tracker's results found")
    if names is None:
        names = [name for name, _, _ in sources]
    if len(names) != len(sources):
        raise ParameterError(f"--names: {len(names)} names for {len(sources)} trackers "
                             f"({', '.join(n for n, _, _ in sources)})")
    seen: dict = {}
    unique = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        unique.append(name if seen[name] == 1 else f"{name}-{seen[name]}")
    if max_frames is not None and max_frames < 2:
        raise ParameterError(f"--max-frames must be >= 2, got {max_frames}")

    notes = []
    manifests = {}
    for name, (_, folder, otb) in zip(unique, sources):
        manifest = read_manifest(folder) if otb is None else None
        if manifest is not None:
            manifests[name] = manifest
    scope = {"sequences_from": None, "max_frames_from": None, "seeds": {}}
    from_manifests = False
    if follow_manifests and manifests:
        if sequences is None:
            ran = sorted({n for m in manifests.values() for n in m["runs"]}, key=str.lower)
            if ran:
                sequences, from_manifests = ran, True
                scope["sequences_from"] = ", ".join(manifests)
        if max_frames is None:
            caps = {n: m["settings"].get("max_frames") for n, m in manifests.items()}
            limited = {n: int(c) for n, c in caps.items() if c is not None}
            if limited:
                max_frames = min(limited.values())
                scope["max_frames_from"] = ", ".join(n for n, c in limited.items() if c == max_frames)
                if len(set(caps.values())) > 1:
                    notes.append("the benchmark folders were made with different frame caps ("
                                 + ", ".join(f"{n}: {'none' if c is None else c}" for n, c in caps.items())
                                 + f"): every tracker is scored on the first {max_frames} frames")
        for name, manifest in manifests.items():
            ran_on = manifest["settings"].get("data")
            if ran_on and Path(ran_on).resolve() != Path(data_root).resolve():
                notes.append(f"{name} was run on {ran_on}, scored here on {data_root}")

    chosen = []
    for sequence in _chosen_sequences(data_root, sequences, from_manifests, notes):
        truth = sequence.groundtruth
        if max_frames is not None:
            truth = truth[:max_frames]
        try:
            evaluate(truth, truth, skip_first=skip_first)
        except DataError:
            notes.append(f"{sequence.name}: no annotated frame to score, left out")
            continue
        chosen.append((sequence, truth))
    if not chosen:
        raise DataError(f"{data_root}: no sequence with ground truth to score")

    trackers = [TrackerScores(name, folder, otb_tracker=otb) for name, (_, folder, otb) in zip(unique, sources)]
    found = {}
    for tracker in trackers:
        for sequence, truth in chosen:
            if tracker.otb_tracker is not None:
                path, boxes, fps, why = find_otb_result(tracker.folder, tracker.otb_tracker, sequence, max_frames,
                                                        name_map)
                if path is not None:
                    tracker.speeds[sequence.name] = (fps, len(truth))
            else:
                path, boxes, why = find_result(tracker.folder, sequence, name_map, max_frames)
            found[tracker.name, sequence.name] = (path, boxes)
            tracker.notes += why
    if common_only:
        kept = [(s, t) for s, t in chosen if all(found[tr.name, s.name][0] is not None for tr in trackers)]
        dropped = [s.name for s, _ in chosen if all(s is not k for k, _ in kept)]
        if dropped:
            notes.append(f"--common: left out {', '.join(dropped)} (not every tracker has a result there)")
        if not kept:
            raise DataError("--common: no sequence has results from every tracker")
        chosen = kept
    for tracker in trackers:
        for sequence, truth in chosen:
            path, boxes = found[tracker.name, sequence.name]
            tracker.files[sequence.name] = path
            predicted = np.empty((0, 4)) if boxes is None else boxes
            tracker.evaluations[sequence.name] = evaluate(predicted, truth, skip_first=skip_first)
        tracker.speeds = {k: v for k, v in tracker.speeds.items() if k in tracker.evaluations}
        missing = [s.name for s, _ in chosen if tracker.files[s.name] is None]
        if missing:
            tracker.notes.append(f"no result file for {', '.join(missing)}: every frame counts as missing")
        if tracker.otb_tracker is not None:
            continue
        manifest = manifests.get(tracker.name)
        others = seed_folders(tracker.folder)
        if others and not all_seeds:
            tracker.notes.append(f"{len(others)} more seed(s) in {tracker.folder / SEEDS_FOLDER} not scored "
                                 f"(--all-seeds averages them)")
        if others and all_seeds:
            tracker.seed_runs = [tracker.evaluations]
            tracker.seed_labels = [_primary_seed(tracker.folder)] + [p.name for p in others]
            for seed_folder in others:
                run = {}
                for sequence, truth in chosen:
                    path, boxes, why = find_result(seed_folder, sequence, name_map, max_frames)
                    tracker.notes += why
                    if path is None:
                        tracker.notes.append(f"{seed_folder}: no result file for {sequence.name}: "
                                             f"every frame counts as missing")
                    run[sequence.name] = evaluate(np.empty((0, 4)) if boxes is None else boxes, truth,
                                                  skip_first=skip_first)
                tracker.seed_runs.append(run)
        if manifest is not None:
            _manifest_speeds(tracker, manifest, all_seeds)
            primary = _primary_seed(tracker.folder)
            in_folder = {seed for name in tracker.evaluations for seed in manifest["runs"].get(name, {})}
            scored = tracker.seed_labels if tracker.seed_runs else [primary]
            scope["seeds"][tracker.name] = (f"seed{'s' if len(scored) > 1 else ''} {_seed_text(scored)}"
                                            + (f" of {_seed_text(in_folder)}" if set(in_folder) - set(scored) else ""))
    comparison = Comparison([s.name for s, _ in chosen], trackers, notes, max_frames)
    comparison.scope = scope
    return comparison


def _manifest_speeds(tracker: TrackerScores, manifest: dict, all_seeds: bool) -> None:
    """``tracker.speeds`` from a benchmark manifest's runs (the scored seeds' frames and fps)."""
    primary = str(manifest.get("primary_seed"))
    for name in tracker.evaluations:
        runs = manifest["runs"].get(name, {})
        chosen = [r for seed, r in runs.items() if all_seeds or seed == primary]
        timed = [(r.get("fps"), r.get("frames") or 0) for r in chosen if r.get("fps")]
        if timed:
            frames = sum(n for _, n in timed)
            tracker.speeds[name] = (frames / sum(n / f for f, n in timed), frames)


def format_scope(comparison: Comparison) -> str:
    """One line: how many sequences were scored (and whose list), the frame cap, the seeds."""
    scope = comparison.scope or {}
    n = len(comparison.sequences)
    text = f"scored: {n} sequence{'s' if n != 1 else ''}"
    if scope.get("sequences_from"):
        text += f" (those run in the benchmark.json of {scope['sequences_from']})"
    if comparison.max_frames is None:
        text += ", all frames"
    else:
        text += f", the first {comparison.max_frames} frames"
        if scope.get("max_frames_from"):
            text += f" (the --max-frames of {scope['max_frames_from']})"
    seeds = scope.get("seeds") or {}
    if seeds:
        text += "; " + ", ".join(f"{name} {label}" for name, label in seeds.items())
        if len(seeds) < len(comparison.trackers):
            text += ", the other trackers their one result per sequence"
    else:
        text += "; one result per tracker and sequence"
    return text


def _primary_seed(folder) -> str:
    """The seed of a ``nrmlc benchmark`` folder's top-level files ("" if it does not say)."""
    try:
        return str(json.loads((Path(folder) / MANIFEST_NAME).read_text())["primary_seed"])
    except (OSError, ValueError, KeyError, TypeError):
        return ""


def seed_folders(folder) -> list[Path]:
    """The other seeds' folders of a ``nrmlc benchmark`` folder, ``<folder>/seeds/<seed>``, by seed."""
    root = Path(folder) / SEEDS_FOLDER
    if not root.is_dir():
        return []
    found = [p for p in root.iterdir() if p.is_dir() and p.name.isdigit()]
    return sorted(found, key=lambda p: int(p.name))


def format_table(comparison: Comparison, per_sequence: bool = True) -> str:
    """What was scored (first line), per-sequence AUC (one column per tracker), the overall scores, as text."""
    lines = [format_scope(comparison), ""]
    names = [t.name for t in comparison.trackers]
    width = max(8, *(len(n) for n in names))
    if per_sequence:
        lines.append("success AUC per sequence ('-': no result file, scored as all frames missing)"
                     + (" (mean over seeds)" if any(len(t.runs) > 1 for t in comparison.trackers) else ""))
        lines.append(f"{'sequence':16s} " + " ".join(f"{n:>{width}s}" for n in names))
        for sequence in comparison.sequences:
            cells = []
            for tracker in comparison.trackers:
                value = tracker.sequence_auc(sequence)
                cells.append(f"{'-' if tracker.files[sequence] is None else format(value, '.3f'):>{width}s}")
            lines.append(f"{sequence:16s} " + " ".join(cells))
        lines.append("")
    several = any(len(t.runs) > 1 for t in comparison.trackers)
    timed = any(t.fps is not None for t in comparison.trackers)
    seeds_header = f" {'seeds':>5s} {'AUC sd':>6s}" if several else ""
    lines.append(f"{'tracker':{width}s} {'seqs':>7s}{seeds_header} {'AUC':>6s} {'P@20':>6s} {'overlap':>8s} "
                 f"{'CLE px':>8s} {'missing frames':>15s}" + (f" {'fps':>8s}" if timed else ""))
    for tracker in sorted(comparison.trackers, key=lambda t: -t.summary()["success_auc"]):
        s = tracker.summary()
        cle = "-" if s["mean_center_error"] is None else f"{s['mean_center_error']:.1f}"
        spread = s["success_auc_std_over_seeds"]
        seeds = f" {s['seeds']:>5d} {'-' if spread is None else format(spread, '.3f'):>6s}" if several else ""
        fps = (f" {'-' if s['fps'] is None else format(s['fps'], '.1f'):>8s}") if timed else ""
        lines.append(f"{s['tracker']:{width}s} {s['sequences_with_results']:>3d}/{s['sequences']:<3d}{seeds} "
                     f"{s['success_auc']:6.3f} {s['precision_20']:6.3f} {s['mean_overlap']:8.3f} {cle:>8s} "
                     f"{s['missing_frames']:>7d}/{s['frames']:<7d}{fps}")
    n = len(comparison.sequences)
    lines.append(f"('seqs': with a result / scored; {MEANS_RULE.replace('every scored sequence', f'the {n} scored')}"
                 + ("; fps: as each tracker's results record it, total frames over total time, on the "
                    "authors' machines for published results" if timed else "") + ")")
    if several:
        lines.append("(scores are means over seeds and sequences; 'AUC sd': standard deviation over seeds)")
    return "\n".join(lines)


def check_plot_path(path, option: str = "--plot") -> None:
    """Refuse a plot file name whose ending matplotlib cannot write (before any work is done)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    formats = FigureCanvasAgg(Figure()).get_supported_filetypes()
    suffix = Path(path).suffix.lstrip(".").lower()
    if suffix not in formats:
        raise ParameterError(f"{option} {path}: cannot write a '{suffix}' file; use one of {', '.join(sorted(formats))}")


def _legend_name(tracker: TrackerScores) -> str:
    return tracker.name if len(tracker.runs) == 1 else f"{tracker.name} ({len(tracker.runs)} seeds)"


def plot_comparison(comparison: Comparison, path, title: str = "") -> Path:
    """OTB success and precision plots of every tracker side by side, written atomically to ``path``.

    Legends give AUC (success) and precision@20 (precision), trackers sorted by them.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from nrmlc.workbench.metrics import PRECISION_AT, PRECISION_THRESHOLDS, SUCCESS_THRESHOLDS

    styles = ["-", "--", "-.", ":"]
    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.4))
    summaries = {t.name: t.summary() for t in comparison.trackers}
    by_auc = sorted(comparison.trackers, key=lambda t: -summaries[t.name]["success_auc"])
    by_precision = sorted(comparison.trackers, key=lambda t: -summaries[t.name]["precision_20"])
    colours = {t.name: f"C{i % 10}" for i, t in enumerate(comparison.trackers)}
    for i, tracker in enumerate(by_auc):
        left.plot(SUCCESS_THRESHOLDS, tracker.success, styles[(i // 10) % 4], color=colours[tracker.name], lw=1.8,
                  label=f"{_legend_name(tracker)} [{summaries[tracker.name]['success_auc']:.3f}]")
    for i, tracker in enumerate(by_precision):
        right.plot(PRECISION_THRESHOLDS, tracker.precision, styles[(i // 10) % 4], color=colours[tracker.name],
                   lw=1.8, label=f"{_legend_name(tracker)} [{summaries[tracker.name]['precision_20']:.3f}]")
    n = len(comparison.sequences)
    scope = f"{n} sequence{'s' if n != 1 else ''}"
    if comparison.max_frames is not None:
        scope += f", first {comparison.max_frames} frames"
    left.set(xlabel="Overlap threshold", ylabel="Success rate", xlim=(0, 1), ylim=(0, 1.02),
             title=f"Success plots of OPE ({scope})")
    right.set(xlabel="Location error threshold (px)", ylabel="Precision", xlim=(0, PRECISION_THRESHOLDS[-1]),
              ylim=(0, 1.02), title=f"Precision plots of OPE ({scope})")
    right.axvline(PRECISION_AT, color="0.6", lw=0.8, ls=":")
    for axis, where in ((left, "lower left"), (right, "lower right")):
        axis.grid(True, alpha=0.4)
        axis.legend(loc=where, fontsize=8, title="AUC" if axis is left else f"precision@{PRECISION_AT:g}",
                    title_fontsize=8)
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    buffer = text_io.BytesIO()
    figure.savefig(buffer, format=Path(path).suffix.lstrip(".").lower(), dpi=130)
    plt.close(figure)
    return io.write_bytes(path, buffer.getvalue())


CSV_COLUMNS = ("tracker", "seed", "sequence", "file", "frames", "missing_frames", *SCORE_NAMES, "fps",
               "sequences", "attribute")


def write_csv(comparison: Comparison, path, attribute_rows=()) -> Path:
    """One row per (tracker, seed, sequence), one ``ALL`` row per tracker (means over seeds and
    sequences, ``sequences`` the count), and the ``attribute_rows`` (dicts of :data:`CSV_COLUMNS`), atomically.

    A sequence without a result file has empty score cells (its frames all count as missing
    in the ``ALL`` row).
    """
    buffer = text_io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n", restval="")
    writer.writeheader()
    for tracker in comparison.trackers:
        labels = tracker.seed_labels or [_primary_seed(tracker.folder)]
        for label, run in zip(labels, tracker.runs):
            for name, evaluation in run.items():
                d = evaluation.as_dict()
                file = tracker.files[name] if run is tracker.evaluations else None
                absent = run is tracker.evaluations and file is None
                speed = tracker.speeds.get(name, (None, 0))[0] if run is tracker.evaluations else None
                writer.writerow({"tracker": tracker.name, "seed": label, "sequence": name, "file": file or "",
                                 "frames": d["n_frames"], "missing_frames": d["n_missing"],
                                 **{k: "" if d[k] is None or absent else d[k] for k in SCORE_NAMES},
                                 "fps": "" if speed is None else speed})
        s = tracker.summary()
        writer.writerow({"tracker": tracker.name, "seed": "", "sequence": "ALL", "file": "", "frames": s["frames"],
                         "missing_frames": s["missing_frames"],
                         **{k: "" if s[k] is None else s[k] for k in SCORE_NAMES},
                         "fps": "" if s["fps"] is None else s["fps"], "sequences": s["sequences"]})
    for row in attribute_rows:
        writer.writerow(row)
    return io.write_text(path, buffer.getvalue())


# ------------------------------------------------------------------ command line
#: The output options of ``evaluate``, in the order they are checked.
OUTPUT_OPTIONS = ("--plot", "--csv", "--attribute-plot", "--speed-plot")



@dataclass(frozen=True)
class EvaluateOptions:
    """The options of ``evaluate``, as given (``nrmlc.cli`` builds this from its command line)."""

    results: tuple = ()
    groundtruth: str | None = None
    json: bool = False
    include_first: bool = False
    data: str | None = None
    names: str | None = None
    sequences: str | None = None
    name_map: tuple = ()
    otb_trackers: str | None = None
    all_seeds: bool = False
    common: bool = False
    max_frames: int | None = None
    attributes: str | None = None
    attribute_plot: str | None = None
    speed_plot: str | None = None
    plot: str | None = None
    csv: str | None = None


#: The folder form's options of ``evaluate``, in ``--help`` order: (option, ``add_argument`` keywords).
_EVALUATE_OPTIONS = (
    ("--data", dict(metavar="DATA", help="data root with ground truth: score result FOLDERS (one <Seq>.txt per "
                                         "sequence, or OTB <Seq>_<Tracker>.mat files) on its sequences")),
    ("--names", dict(metavar="A,B", help="tracker names, in the order of --results (default: the folders' names, "
                                         "a .mat tracker's <Tracker>)")),
    ("--sequences", dict(metavar="A,B", help="only these sequences (default: those a 'nrmlc benchmark' folder "
                                             "given ran, else all with ground truth)")),
    ("--name-map", dict(action="append", default=[], metavar="FILE_STEM=SEQUENCE",
                        help="a result file named FILE_STEM.txt holds SEQUENCE, e.g. FaceOcc1=Occlusion1 "
                             "(repeatable, or comma-separated)")),
    ("--otb-trackers", dict(metavar="A,B", help="from folders of OTB <Seq>_<Tracker>.mat files, only these "
                                                "trackers (default: all; --results DIR:A,B selects per folder)")),
    ("--all-seeds", dict(action="store_true", help="also score every other seed of a 'nrmlc benchmark' folder "
                                                   "(DIR/seeds/<seed>/) and average over seeds")),
    ("--common", dict(action="store_true", help="score only the sequences every tracker has a result file for")),
    ("--max-frames", dict(type=int, metavar="N", help="score only the first N frames (default: the smallest "
                                                      "--max-frames of the 'nrmlc benchmark' folders given, "
                                                      "else all)")),
    ("--attributes", dict(metavar="DIR", help="OTB attribute files (<Seq>.txt: 11 flags "
                                              "IV,OPR,SV,OCC,DEF,MB,FM,IPR,OV,BC,LR): also success AUC and "
                                              "precision@20 per attribute (table, --csv rows)")),
    ("--attribute-plot", dict(metavar="OUT.png", help="with --attributes: heatmaps tracker x attribute (AUC, and "
                                                      "AUC minus the tracker's overall AUC)")),
    ("--speed-plot", dict(metavar="OUT.png", help="success AUC against fps (log scale) for the trackers whose "
                                                  "results record their speed (OTB .mat files, 'nrmlc "
                                                  "benchmark' folders)")),
    ("--plot", dict(metavar="OUT.png", help="draw the success and precision plots of all trackers")),
    ("--csv", dict(metavar="OUT.csv", help="write per-sequence and overall scores")),
)


def add_evaluate_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of the folder form of ``evaluate`` (the single-file form's stay in nrmlc.cli)."""
    parser.description = (
        "Score tracker results (OTB one-pass evaluation). One file: --results R.txt|R.mat --groundtruth G.txt. "
        "Any number of trackers: --results DIR [DIR ...] --data DATA, where each DIR holds one <Seq>.txt "
        "per sequence (the layout of 'nrmlc benchmark' and of the OTB toolkits), or the OTB toolkit's own "
        "<Seq>_<Tracker>.mat files (one tracker per <Tracker>; DIR:ASLA,IVT or --otb-trackers selects "
        "some); prints a table whose first line says what was scored, and --plot draws the success and "
        "precision plots of all of them. A tracker's name is its folder's name (a .mat tracker's: "
        "<Tracker>; --names to change them); its files are looked up by sequence name, without regard to "
        "case and to the benchmark's spellings (Skating2.1 is Skating2-1), in DIR, then in DIR's "
        "subfolders, and a file whose first box is not the sequence's initial box is not used. A 'nrmlc "
        "benchmark' folder (with benchmark.json) sets the default sequences and frame cap for every "
        "tracker: what it ran. Outputs must not be inputs: no output inside DATA or a results folder.")
    parser.epilog = "Missing predictions: " + MISSING_RULE
    for option, spec in _EVALUATE_OPTIONS:
        parser.add_argument(option, **spec)


def check_outputs(args: EvaluateOptions, inputs=(), input_folders=()) -> None:
    """Refuse, before any work, an output that is an input, lies inside an input folder, or is given twice."""
    given = [(option, getattr(args, option[2:].replace("-", "_"), None)) for option in OUTPUT_OPTIONS]
    given = [(option, path) for option, path in given if path is not None]
    for option, path in given:
        io.check_output(path, option, inputs=inputs, input_folders=input_folders,
                        folder_role="this evaluation reads (ground truth or results)")
        if option != "--csv":
            check_plot_path(path, option)
    for i, (option, path) in enumerate(given):
        for other, other_path in given[:i]:
            if _same_path(path, other_path):
                raise ParameterError(f"{option} {path}: the same file as {other} {other_path}; give two files")


def _same_path(a, b) -> bool:
    import os

    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _file_boxes(path) -> np.ndarray:
    """A single result file's boxes: ``x,y,w,h`` lines, or an OTB ``.mat`` file aligned to its annotation rows."""
    from nrmlc.data import read_box_file

    if Path(path).suffix.lower() != ".mat":
        return read_box_file(path, predictions=True)
    from nrmlc.workbench.otb_results import read_otb_result

    result = read_otb_result(path)
    boxes = result.boxes[max(0, -result.offset):]
    if result.offset > 0:
        warnings.warn(f"{path}: starts at frame {result.offset + 1} (startFrame {result.start_frame}, annoBegin "
                      f"{result.anno_begin}); frames 1-{result.offset} count as missing predictions")
        boxes = np.vstack([np.full((result.offset, 4), np.nan), boxes])
    return boxes


def run_evaluate_file(args: EvaluateOptions) -> int:
    """``evaluate --results R.txt|R.mat --groundtruth G.txt``: the scores, each with the frames behind it."""
    from nrmlc.data import read_box_file
    from nrmlc.workbench.metrics import evaluate

    if args.groundtruth is None or len(args.results) != 1:
        raise ParameterError("evaluate: give one --results R.txt with --groundtruth G.txt, "
                             "or result folders with --data DATA")
    for option in ("--attributes", "--attribute-plot", "--speed-plot", "--otb-trackers"):
        if getattr(args, option[2:].replace("-", "_"), None) is not None:
            raise ParameterError(f"{option} is for result folders with --data DATA")
    result_path = args.results[0]
    check_outputs(args, inputs=[result_path, args.groundtruth])
    predicted = _file_boxes(result_path)
    truth = read_box_file(args.groundtruth)
    n_predicted, n_annotated = len(predicted), len(truth)
    if n_annotated < n_predicted:
        warnings.warn(f"{args.groundtruth}: {n_annotated} ground-truth boxes for {n_predicted} result boxes; "
                      f"only the first {n_annotated} frames are evaluated")
    elif n_predicted < n_annotated:
        warnings.warn(f"{result_path}: {n_predicted} result boxes for {n_annotated} ground-truth boxes; "
                      f"the annotated frames after frame {n_predicted} count as failures")
    try:
        result = evaluate(predicted, truth, skip_first=not args.include_first)
    except DataError as exc:
        raise DataError(f"{args.groundtruth}: {exc}") from None
    n, missing = result.n_frames, result.n_missing
    have = n - missing
    predicted_overlap = float(np.sum(result.overlaps) / have) if have else None
    where = "the annotated frames" + ("" if args.include_first else " after frame 1")
    summary = {**result.as_dict(), "n_predicted": have, "mean_overlap_predicted_frames": predicted_overlap,
               "frames": (f"n_frames: {where}; mean_center_error and mean_overlap_predicted_frames: the n_predicted "
                          f"of them with a prediction; mean_overlap, success_auc, precision_20: all n_frames, a "
                          f"missing prediction failing")}
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        all_frames = f"all {n} frames" + (", missing = failed" if missing else "")
        cle = "-" if not have else f"{result.mean_center_error:.2f} px"
        overlap_extra = "" if not missing or predicted_overlap is None else \
            f"; {predicted_overlap:.4f} over the {have} with a prediction"
        print(f"frames evaluated : {n} ({where}): {have} with a prediction, {missing} missing predictions")
        print(f"mean CLE         : {cle} (the {have} frames with a prediction)")
        print(f"mean overlap     : {result.mean_overlap:.4f} ({all_frames}{overlap_extra})")
        print(f"success AUC      : {result.success_auc:.4f} ({all_frames})")
        print(f"precision@20     : {result.precision_20:.4f} ({all_frames})")
    if args.csv or args.plot:
        name = Path(result_path).stem
        sequence = Path(args.groundtruth).stem
        tracker = TrackerScores(name, Path(result_path).parent, files={sequence: Path(result_path)},
                                evaluations={sequence: result})
        comparison = Comparison([sequence], [tracker], max_frames=None,
                                scope={"seeds": {}, "sequences_from": None, "max_frames_from": None})
        if args.csv:
            write_csv(comparison, args.csv)
        if args.plot:
            plot_comparison(comparison, args.plot)
    return 0


def run_evaluate_folders(args: EvaluateOptions) -> int:
    """``evaluate --results DIR [DIR ...] --data DATA ...``: table on stdout, notes on stderr."""
    if args.groundtruth:
        raise ParameterError("--groundtruth is for one result file; with --data give result folders")
    if args.attribute_plot is not None and args.attributes is None:
        raise ParameterError("--attribute-plot needs --attributes DIR")
    folders = [split_results_entry(entry)[0] for entry in args.results]
    check_outputs(args, input_folders=[args.data, *folders] + ([args.attributes] if args.attributes else []))
    names = None if args.names is None else [n.strip() for n in args.names.split(",")]
    otb_trackers = None if args.otb_trackers is None else parse_names(args.otb_trackers)
    comparison = compare(args.results, args.data, names=names,
                         sequences=parse_names(args.sequences), name_map=parse_name_map(args.name_map),
                         max_frames=args.max_frames, common_only=args.common,
                         skip_first=not args.include_first, all_seeds=args.all_seeds, otb_trackers=otb_trackers)
    scores, notes = [], []
    if args.attributes:
        from nrmlc.workbench.attributes import attribute_scores, read_attributes

        attributes, notes = read_attributes(args.attributes, comparison.sequences)
        scores = attribute_scores(comparison, attributes)
    for note in comparison.notes + notes + [f"{t.name}: {n}" for t in comparison.trackers for n in t.notes]:
        print(f"note: {note}", file=sys.stderr)
    if args.json:
        result = comparison.as_dict()
        if args.attributes:
            result["attributes"] = [{"code": s.code, "name": s.name, "sequences": s.sequences,
                                     "success_auc": s.success_auc, "precision_20": s.precision_20} for s in scores]
        print(json.dumps(result, indent=2))
    else:
        print(format_table(comparison))
        if args.attributes:
            from nrmlc.workbench.attributes import format_attribute_table

            print()
            print(format_attribute_table(comparison, scores))
    if args.csv:
        from nrmlc.workbench.attributes import attribute_csv_rows

        write_csv(comparison, args.csv, attribute_csv_rows(scores))
    if args.plot:
        plot_comparison(comparison, args.plot)
        print(f"plots: {args.plot}", file=sys.stderr)
    if args.attribute_plot:
        from nrmlc.workbench.attributes import plot_attributes

        plot_attributes(comparison, scores, args.attribute_plot)
        print(f"attribute plot: {args.attribute_plot}", file=sys.stderr)
    if args.speed_plot:
        from nrmlc.workbench.speed import plot_speed

        _, left_out = plot_speed(comparison, args.speed_plot)
        for note in left_out:
            print(f"note: {note}", file=sys.stderr)
        print(f"speed plot: {args.speed_plot}", file=sys.stderr)
    return 0
