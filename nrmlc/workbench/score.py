"""Score trackers' result folders on the sequences of a data root.

What is scored
    A folder made by ``nrmlc benchmark`` (it has a ``benchmark.json``) says which sequences it
    ran, with which frame cap and seeds: unless ``--sequences`` or ``--max-frames`` say
    otherwise, every tracker is scored on those sequences (of every such folder) and frames
    (the smallest cap). :func:`format_scope` says what was scored, in one line.

Missing predictions
    Scored by :func:`nrmlc.workbench.metrics.evaluate` (see the docstring of
    :mod:`nrmlc.workbench.metrics` for every convention): a frame whose predicted row is
    missing (no file for the sequence, fewer lines than frames) or has no finite box counts as
    a failed frame, the same way in the success and the precision curves (see
    :data:`MISSING_RULE`).

Averages
    As the OTB toolkit (and got10k's ``ExperimentOTB``): a tracker's success
    and precision curves are the mean over sequences of its per-sequence
    curves; AUC is the mean of its success curve, precision@20 its precision
    curve at 20 px; mean overlap and mean CLE are means over sequences of
    the per-sequence means.

Where each tracker's files are found: :mod:`nrmlc.workbench.find`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nrmlc.errors import DataError, ParameterError
from nrmlc.workbench.find import find_result, primary_seed, result_sources, seed_folders
from nrmlc.workbench.manifest import read_manifest
from nrmlc.workbench.otb_results import find_otb_result, sequence_key
from nrmlc.workbench.results_layout import SEEDS_FOLDER, select_sequences

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
        {file stem: sequence name} (see :func:`nrmlc.workbench.find.parse_name_map`).
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

    Raises
    ------
    DataError
        Also when a result folder holds no result file for any of the scored sequences (a
        sequence folder or the data root given by mistake): its scores would be all zero.
    """
    if not list(result_folders):
        raise ParameterError("--results: give at least one result folder")
    if max_frames is not None and (isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer))
                                   or max_frames < 2):
        raise ParameterError(f"--max-frames must be an integer >= 2, got {max_frames!r}")
    notes = []
    sources = result_sources(result_folders, otb_trackers, _sequence_keys(data_root, sequences, name_map), notes)
    if not sources:
        raise DataError(f"{', '.join(map(str, result_folders))}: no tracker's results found")
    unique = _tracker_names(sources, names)
    manifests = _read_manifests(unique, sources, notes)
    scope = {"sequences_from": None, "max_frames_from": None, "seeds": {}}
    from_manifests = False
    if follow_manifests and manifests:
        sequences, max_frames, from_manifests = _follow_manifests(manifests, sequences, max_frames, data_root,
                                                                  scope, notes)
    chosen = _scorable_sequences(data_root, sequences, from_manifests, max_frames, skip_first, notes)
    trackers = [TrackerScores(name, folder, otb_tracker=otb) for name, (_, folder, otb) in zip(unique, sources)]
    found = _find_results(trackers, chosen, name_map, max_frames)
    _check_every_folder_has_results(trackers, chosen, found, data_root)
    if common_only:
        chosen = _common_sequences(chosen, trackers, found, notes)
    for tracker in trackers:
        _score_found(tracker, chosen, found, skip_first)
        if tracker.otb_tracker is not None:
            continue
        _score_other_seeds(tracker, chosen, name_map, max_frames, skip_first, all_seeds)
        manifest = manifests.get(tracker.name)
        if manifest is not None:
            _manifest_speeds(tracker, manifest, all_seeds)
            scope["seeds"][tracker.name] = _seed_scope(tracker, manifest)
    return Comparison([s.name for s, _ in chosen], trackers, notes, max_frames, scope)


def _tracker_names(sources: list, names) -> list[str]:
    """One name per source (default: the sources' own), a repeated name numbered ``-2``, ``-3``."""
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
    return unique


def _sequence_keys(data_root, sequences, name_map):
    """A callable giving the keys of the sequences that may be scored, and of the file stems
    ``name_map`` maps to them (listed once, and only when asked: see :func:`result_sources`)."""
    import functools
    import warnings

    @functools.cache
    def keys() -> frozenset:
        if sequences is not None:
            names = list(sequences)
        else:
            from nrmlc.data import list_sequences

            with warnings.catch_warnings():  # the root's warnings come when it is read for scoring
                warnings.simplefilter("ignore")
                names = [s.name for s in list_sequences(data_root)]
        found = {sequence_key(n) for n in names}
        return frozenset(found | {sequence_key(stem) for stem, target in (name_map or {}).items()
                                  if sequence_key(target) in found})

    return keys


def _read_manifests(names: list, sources: list, notes: list) -> dict:
    """{tracker name: benchmark.json} of the ``nrmlc benchmark`` folders among ``sources``; the
    runs whose file is not there are left out, with a note each."""
    manifests = {}
    for name, (_, folder, otb) in zip(names, sources):
        found = read_manifest(folder) if otb is None else None
        if found is not None:
            manifests[name] = found.data
            notes += [f"{name}: {line}" for line in found.unwritten]
    return manifests


def _follow_manifests(manifests: dict, sequences, max_frames, data_root, scope: dict, notes: list):
    """The sequences and frame cap the benchmark folders ran, where not given; ``scope`` says whose.

    Returns
    -------
    sequences : list of str or None
    max_frames : int or None
    from_manifests : bool
        Whether ``sequences`` came from the manifests (names the data root lacks are then noted,
        not refused).
    """
    from_manifests = False
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
    return sequences, max_frames, from_manifests


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


def _scorable_sequences(data_root, names, from_manifests: bool, max_frames, skip_first: bool, notes: list) -> list:
    """[(sequence, ground truth (n, 4))] of the chosen sequences with an annotated frame to score.

    Raises
    ------
    DataError
        When none has one.
    """
    from nrmlc.workbench.metrics import evaluate

    chosen = []
    for sequence in _chosen_sequences(data_root, names, from_manifests, notes):
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
    return chosen


def _find_results(trackers: list, chosen: list, name_map, max_frames) -> dict:
    """{(tracker name, sequence name): (path or None, boxes (m, 4) or None)}; the reasons for
    files not used go to each tracker's notes, a ``.mat`` file's recorded speed to its speeds."""
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
    return found


def _check_every_folder_has_results(trackers: list, chosen: list, found: dict, data_root) -> None:
    """Refuse a result folder none of whose trackers has a file for any scored sequence: it is
    no tracker's results (a sequence folder, the data root, misnamed files), not a tracker that
    failed everywhere."""
    by_folder: dict = {}
    for tracker in trackers:
        by_folder.setdefault(tracker.folder, []).append(tracker)
    for folder, here in by_folder.items():
        if any(found[t.name, s.name][0] is not None for t in here for s, _ in chosen):
            continue
        expected = ("<Seq>.txt or <Seq>_<Tracker>.mat" if here[0].otb_tracker is None
                    else ", ".join(f"<Seq>_{t.otb_tracker}.mat" for t in here))
        n = len(chosen)
        message = (f"{folder}: no result files ({expected}) for any of the {n} sequence{'s' if n != 1 else ''} "
                   f"of {data_root}")
        refused = [note for t in here for note in t.notes]  # files found but not used, and why
        if refused:
            message += f"; {refused[0]}" + (f" (and {len(refused) - 1} more)" if len(refused) > 1 else "")
        raise DataError(message)


def _common_sequences(chosen: list, trackers: list, found: dict, notes: list) -> list:
    """``chosen`` less the sequences some tracker has no file for (``--common``), with a note."""
    kept = [(s, t) for s, t in chosen if all(found[tr.name, s.name][0] is not None for tr in trackers)]
    dropped = [s.name for s, _ in chosen if all(s is not k for k, _ in kept)]
    if dropped:
        notes.append(f"--common: left out {', '.join(dropped)} (not every tracker has a result there)")
    if not kept:
        raise DataError("--common: no sequence has results from every tracker")
    return kept


def _score_found(tracker: TrackerScores, chosen: list, found: dict, skip_first: bool) -> None:
    """``tracker``'s files and evaluations on the ``chosen`` sequences; a sequence without a file is all failures."""
    from nrmlc.workbench.metrics import evaluate

    for sequence, truth in chosen:
        path, boxes = found[tracker.name, sequence.name]
        tracker.files[sequence.name] = path
        predicted = np.empty((0, 4)) if boxes is None else boxes
        tracker.evaluations[sequence.name] = evaluate(predicted, truth, skip_first=skip_first)
    tracker.speeds = {k: v for k, v in tracker.speeds.items() if k in tracker.evaluations}
    missing = [s.name for s, _ in chosen if tracker.files[s.name] is None]
    if missing:
        tracker.notes.append(f"no result file for {', '.join(missing)}: every frame counts as missing")


def _score_other_seeds(tracker: TrackerScores, chosen: list, name_map, max_frames, skip_first: bool,
                       all_seeds: bool) -> None:
    """The runs of a ``nrmlc benchmark`` folder's other seeds (``seeds/<seed>/``), scored with
    ``all_seeds``, else named in a note."""
    from nrmlc.workbench.metrics import evaluate

    others = seed_folders(tracker.folder)
    if others and not all_seeds:
        tracker.notes.append(f"{len(others)} more seed(s) in {tracker.folder / SEEDS_FOLDER} not scored "
                             f"(--all-seeds averages them)")
    if not (others and all_seeds):
        return
    tracker.seed_runs = [tracker.evaluations]
    tracker.seed_labels = [primary_seed(tracker.folder)] + [p.name for p in others]
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


def _seed_scope(tracker: TrackerScores, manifest: dict) -> str:
    """Which seeds of a ``nrmlc benchmark`` folder were scored, e.g. ``seed 0 of 0,1``."""
    in_folder = {seed for name in tracker.evaluations for seed in manifest["runs"].get(name, {})}
    scored = tracker.seed_labels if tracker.seed_runs else [primary_seed(tracker.folder)]
    return (f"seed{'s' if len(scored) > 1 else ''} {_seed_text(scored)}"
            + (f" of {_seed_text(in_folder)}" if set(in_folder) - set(scored) else ""))


def _seed_text(seeds) -> str:
    return ",".join(str(s) for s in sorted(seeds, key=int))


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

