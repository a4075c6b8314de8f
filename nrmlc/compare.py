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

Missing predictions
    Scored by :func:`nrmlc.metrics.evaluate` (see the docstring of
    :mod:`nrmlc.metrics` for every convention): a frame whose predicted row is
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
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nrmlc import io
from nrmlc.benchmark import SEEDS_FOLDER, parse_names, select_sequences
from nrmlc.errors import DataError, ParameterError

#: How a missing prediction is scored, for ``--help`` and the table's footnote;
#: it restates the "Missing predictions" paragraph of :mod:`nrmlc.metrics`.
MISSING_RULE = (
    "A scored frame without a prediction (no result file for the sequence, fewer lines than frames, a NaN "
    "or 0,0,0,0 row, an infinite value or one beyond 1e9 px) is a failed frame: overlap 0 and centre "
    "error +inf, so it fails every threshold of both the success and the precision plot and lowers AUC, "
    "precision@20 and the mean overlap alike. The mean CLE can only average frames that have a box, so "
    "the table gives the count of missing frames beside it. A finite box of zero or negative size is "
    "scored as it is (overlap 0, the error of its centre). Frame 1 (the given box) and frames without "
    "ground truth are not scored (nrmlc.metrics).")

#: A result file is taken for a sequence only when its first box overlaps the initial box this much.
FIRST_BOX_MIN_IOU = 0.5

SCORE_NAMES = ("success_auc", "precision_20", "mean_overlap", "mean_center_error")


@dataclass
class TrackerScores:
    """One tracker's results on the compared sequences.

    Attributes
    ----------
    name : str
    folder : Path
    files : dict of sequence name -> Path or None (no usable file)
    evaluations : dict of sequence name -> nrmlc.metrics.Evaluation
        Every compared sequence has one; a sequence without a file is all failures.
    seed_runs : list of dict
        With ``all_seeds``: one ``evaluations``-like dict per scored seed
        folder (``folder`` itself first, then ``folder/seeds/<seed>``).
    seed_labels : list of str
        The seed of each of ``seed_runs`` (the top folder's from its
        ``benchmark.json``, ``""`` if unknown).
    notes : list of str
        Files not used and why; line-count mismatches.
    """

    name: str
    folder: Path
    files: dict = field(default_factory=dict)
    evaluations: dict = field(default_factory=dict)
    seed_runs: list = field(default_factory=list)
    seed_labels: list = field(default_factory=list)
    notes: list = field(default_factory=list)

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

    def sequence_auc(self, sequence: str) -> float:
        """Success AUC on one sequence (mean over seeds)."""
        return float(np.mean([run[sequence].success_auc for run in self.runs]))

    def summary(self) -> dict:
        """Overall scores (means over seeds and sequences) and coverage counts."""
        from nrmlc.metrics import PRECISION_AT, PRECISION_THRESHOLDS

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
        }


@dataclass
class Comparison:
    """Every tracker scored on the same sequences."""

    sequences: list
    trackers: list  # of TrackerScores
    notes: list = field(default_factory=list)
    max_frames: int | None = None  # scored only the first frames of each sequence

    def as_dict(self) -> dict:
        return {
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
    """Result files that may hold ``sequence_name``: the folder first, then its subfolders."""
    stems = {sequence_name.lower()} | {stem for stem, target in name_map.items() if target == sequence_name.lower()}
    folders = [folder] + sorted((p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")),
                                key=lambda p: p.name)
    found = []
    for where in folders:
        found += sorted(p for p in where.glob("*.txt") if p.stem.lower() in stems and p.is_file())
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
    from nrmlc.metrics import overlaps

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
        if check_first and len(boxes) and np.isfinite(boxes[0]).all():
            iou = float(overlaps(boxes[0], first))
            if not iou >= FIRST_BOX_MIN_IOU:
                notes.append(f"{path}: not used, its first box {np.round(boxes[0], 1).tolist()} is not "
                             f"{sequence.name}'s initial box {np.round(first, 1).tolist()} (IoU {iou:.2f}; "
                             f"results on another version of the sequence?)")
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


def compare(result_folders, data_root, names=None, sequences=None, name_map=None, max_frames=None,
            common_only: bool = False, skip_first: bool = True, all_seeds: bool = False) -> Comparison:
    """Score each result folder on the sequences of ``data_root``.

    Parameters
    ----------
    result_folders : list of paths
    data_root : path
        Folder of sequences with ground truth (any layout :func:`nrmlc.data.list_sequences` reads).
    names : list of str, optional
        Tracker names (default: the folders' names; repeated names get ``-2``, ``-3``).
    sequences : list of str, optional
        Only these sequences (default: every sequence of the root with ground truth).
    name_map : dict, optional
        {file stem: sequence name} (see :func:`parse_name_map`).
    max_frames : int, optional
        Score only the first frames of each sequence (for results made with a frame cap).
    common_only : bool
        Score only the sequences every tracker has a file for.
    skip_first : bool
        Do not score frame 1 (the given box), the OTB convention.
    all_seeds : bool
        Also score the other seeds of a ``nrmlc benchmark`` folder
        (``<folder>/seeds/<seed>/``) and average over seeds.

    Returns
    -------
    Comparison
    """
    from nrmlc.metrics import evaluate

    folders = [Path(f) for f in result_folders]
    if not folders:
        raise ParameterError("--results: give at least one result folder")
    for folder in folders:
        if not folder.is_dir():
            raise DataError(f"{folder}: result folder {'is not a folder' if folder.exists() else 'not found'}")
    if names is None:
        names = [f.resolve().name for f in folders]
    if len(names) != len(folders):
        raise ParameterError(f"--names: {len(names)} names for {len(folders)} result folders")
    seen: dict = {}
    unique = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        unique.append(name if seen[name] == 1 else f"{name}-{seen[name]}")
    if max_frames is not None and max_frames < 2:
        raise ParameterError(f"--max-frames must be >= 2, got {max_frames}")

    notes = []
    chosen = []
    for sequence in select_sequences(data_root, sequences):
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

    trackers = [TrackerScores(name, folder) for name, folder in zip(unique, folders)]
    found = {}
    for tracker in trackers:
        for sequence, _ in chosen:
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
        missing = [s.name for s, _ in chosen if tracker.files[s.name] is None]
        if missing:
            tracker.notes.append(f"no result file for {', '.join(missing)}: every frame counts as missing")
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
    return Comparison([s.name for s, _ in chosen], trackers, notes, max_frames)


def _primary_seed(folder) -> str:
    """The seed of a ``nrmlc benchmark`` folder's top-level files ("" if it does not say)."""
    from nrmlc.benchmark import MANIFEST_NAME

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
    """Per-sequence AUC (one column per tracker) and the overall scores, as text."""
    lines = []
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
    seeds_header = f" {'seeds':>5s} {'AUC sd':>6s}" if several else ""
    lines.append(f"{'tracker':{width}s} {'seqs':>7s}{seeds_header} {'AUC':>6s} {'P@20':>6s} {'overlap':>8s} "
                 f"{'CLE px':>8s} {'missing frames':>15s}")
    for tracker in sorted(comparison.trackers, key=lambda t: -t.summary()["success_auc"]):
        s = tracker.summary()
        cle = "-" if s["mean_center_error"] is None else f"{s['mean_center_error']:.1f}"
        spread = s["success_auc_std_over_seeds"]
        seeds = f" {s['seeds']:>5d} {'-' if spread is None else format(spread, '.3f'):>6s}" if several else ""
        lines.append(f"{s['tracker']:{width}s} {s['sequences_with_results']:>3d}/{s['sequences']:<3d}{seeds} "
                     f"{s['success_auc']:6.3f} {s['precision_20']:6.3f} {s['mean_overlap']:8.3f} {cle:>8s} "
                     f"{s['missing_frames']:>7d}/{s['frames']:<7d}")
    if several:
        lines.append("(scores are means over seeds and sequences; 'AUC sd': standard deviation over seeds)")
    return "\n".join(lines)


def check_plot_path(path) -> None:
    """Refuse a plot file name whose ending matplotlib cannot write (before any work is done)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    formats = FigureCanvasAgg(Figure()).get_supported_filetypes()
    suffix = Path(path).suffix.lstrip(".").lower()
    if suffix not in formats:
        raise ParameterError(f"--plot {path}: cannot write a '{suffix}' file; use one of {', '.join(sorted(formats))}")


def _legend_name(tracker: TrackerScores) -> str:
    return tracker.name if len(tracker.runs) == 1 else f"{tracker.name} ({len(tracker.runs)} seeds)"


def plot_comparison(comparison: Comparison, path, title: str = "") -> Path:
    """OTB success and precision plots of every tracker side by side, written atomically to ``path``.

    Legends give AUC (success) and precision@20 (precision), trackers sorted by them.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from nrmlc.metrics import PRECISION_AT, PRECISION_THRESHOLDS, SUCCESS_THRESHOLDS

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


def write_csv(comparison: Comparison, path) -> Path:
    """One row per (tracker, seed, sequence) plus one ``ALL`` row per tracker (means over seeds and
    sequences), atomically."""
    buffer = text_io.StringIO()
    columns = ["tracker", "seed", "sequence", "file", "frames", "missing_frames", *SCORE_NAMES]
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for tracker in comparison.trackers:
        labels = tracker.seed_labels or [_primary_seed(tracker.folder)]
        for label, run in zip(labels, tracker.runs):
            for name, evaluation in run.items():
                d = evaluation.as_dict()
                file = tracker.files[name] if run is tracker.evaluations else None
                writer.writerow({"tracker": tracker.name, "seed": label, "sequence": name, "file": file or "",
                                 "frames": d["n_frames"], "missing_frames": d["n_missing"],
                                 **{k: "" if d[k] is None else d[k] for k in SCORE_NAMES}})
        s = tracker.summary()
        writer.writerow({"tracker": tracker.name, "seed": "", "sequence": "ALL", "file": "", "frames": s["frames"],
                         "missing_frames": s["missing_frames"],
                         **{k: "" if s[k] is None else s[k] for k in SCORE_NAMES}})
    return io.write_text(path, buffer.getvalue())


# ------------------------------------------------------------------ command line
def add_evaluate_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of the folder form of ``evaluate`` (the single-file form's stay in nrmlc.cli)."""
    parser.description = (
        "Score tracker results (OTB one-pass evaluation). One file: --results R.txt --groundtruth G.txt. "
        "Any number of trackers: --results DIR [DIR ...] --data DATA, where each DIR holds one <Seq>.txt "
        "per sequence (the layout of 'nrmlc benchmark' and of the OTB toolkits); prints a table, and "
        "--plot draws the success and precision plots of all of them. A tracker's name is its folder's "
        "name (--names to change it); its files are looked up by sequence name in DIR, then in DIR's "
        "subfolders, and a file whose first box is not the sequence's initial box is not used.")
    parser.epilog = "Missing predictions: " + MISSING_RULE
    parser.add_argument("--data", metavar="DATA",
                        help="data root with ground truth: score result FOLDERS (one <Seq>.txt per sequence) "
                             "on its sequences")
    parser.add_argument("--names", metavar="A,B", help="tracker names, in the order of --results "
                                                        "(default: the folders' names)")
    parser.add_argument("--sequences", metavar="A,B", help="only these sequences (default: all with ground truth)")
    parser.add_argument("--name-map", action="append", default=[], metavar="FILE_STEM=SEQUENCE",
                        help="a result file named FILE_STEM.txt holds SEQUENCE, e.g. FaceOcc1=Occlusion1 "
                             "(repeatable, or comma-separated)")
    parser.add_argument("--all-seeds", action="store_true",
                        help="also score every other seed of a 'nrmlc benchmark' folder (DIR/seeds/<seed>/) and "
                             "average over seeds")
    parser.add_argument("--common", action="store_true",
                        help="score only the sequences every tracker has a result file for")
    parser.add_argument("--max-frames", type=int, metavar="N",
                        help="score only the first N frames (results made with --max-frames)")
    parser.add_argument("--plot", metavar="OUT.png", help="draw the success and precision plots of all trackers")
    parser.add_argument("--csv", metavar="OUT.csv", help="write per-sequence and overall scores")


def run_evaluate_folders(args: argparse.Namespace) -> int:
    """``evaluate --results DIR [DIR ...] --data DATA ...``: table on stdout, notes on stderr."""
    if args.groundtruth:
        raise ParameterError("--groundtruth is for one result file; with --data give result folders")
    for option, path in (("--plot", args.plot), ("--csv", args.csv)):
        if path is not None:
            io.check_output(path, option)
    if args.plot is not None:
        check_plot_path(args.plot)
    names = None if args.names is None else [n.strip() for n in args.names.split(",")]
    comparison = compare(args.results, args.data, names=names,
                         sequences=parse_names(args.sequences), name_map=parse_name_map(args.name_map),
                         max_frames=args.max_frames, common_only=args.common,
                         skip_first=not args.include_first, all_seeds=args.all_seeds)
    for note in comparison.notes + [f"{t.name}: {n}" for t in comparison.trackers for n in t.notes]:
        print(f"note: {note}", file=sys.stderr)
    if args.json:
        print(json.dumps(comparison.as_dict(), indent=2))
    else:
        print(format_table(comparison))
    if args.csv:
        write_csv(comparison, args.csv)
    if args.plot:
        plot_comparison(comparison, args.plot)
        print(f"plots: {args.plot}", file=sys.stderr)
    return 0
