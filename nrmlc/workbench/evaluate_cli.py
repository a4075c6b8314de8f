"""The ``evaluate`` command: score one result file, or compare any number of trackers' result folders.

``python -m nrmlc evaluate --results results/NRMLC results/MyTracker PEERS/IVT --data DATA --plot out.png``

A *result folder* holds one ``<Seq>.txt`` per sequence (or the OTB toolkit's
``<Seq>_<Tracker>.mat`` files; :mod:`nrmlc.workbench.find` says how they are found). Any
tracker's folder works; its name in the table and the plots is the folder's name unless
``--names`` says otherwise. Nothing here is specific to NRMLC: adding a tracker to the
comparison is adding its folder. What is scored, and how: :mod:`nrmlc.workbench.score`; the
table, CSV and plots: :mod:`nrmlc.workbench.report`.

``nrmlc.cli`` builds the command line; this module adds the folder form's options
(:func:`add_evaluate_arguments`) and runs either form (:func:`run_evaluate_file`,
:func:`run_evaluate_folders`). Outputs are checked before any work: none may be an input. They are
written together (:class:`nrmlc.io.Together`): an interrupt, a full disk or a refused
``--speed-plot`` leaves every earlier file as it was, never a new CSV beside an old plot.
Memory running out is a one-line error naming the file being read, never a tracker scored as
failing (:mod:`nrmlc.workbench.results_layout`).
"""
from __future__ import annotations

import argparse
import functools
import json
import sys
import warnings
from pathlib import Path

import numpy as np

from nrmlc import io
from nrmlc.errors import DataError, ParameterError
from nrmlc.data.boxes import MAX_BOX_FILE_BYTES
from nrmlc.workbench.find import parse_name_map, split_results_entry
from nrmlc.workbench.report import check_plot_path, format_table, plot_comparison, write_csv
from nrmlc.workbench.results_layout import InputTooLarge, check_input_file, parse_names, reading
from nrmlc.workbench.score import MISSING_RULE, Comparison, TrackerScores, compare

#: The output options of ``evaluate``, in the order they are checked.
OUTPUT_OPTIONS = ("--plot", "--csv", "--attribute-plot", "--speed-plot")


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


def check_outputs(args: argparse.Namespace, inputs=(), input_folders=()) -> None:
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
        check_input_file(path, "result file", MAX_BOX_FILE_BYTES)  # absent: the reader says "not found"
        with reading(path, "result file"):
            return read_box_file(path, predictions=True)
    from nrmlc.workbench.otb_results import read_otb_result

    result = read_otb_result(path)
    boxes = result.boxes[max(0, -result.offset):]
    if result.offset > 0:
        warnings.warn(f"{path}: starts at frame {result.offset + 1} (startFrame {result.start_frame}, annoBegin "
                      f"{result.anno_begin}); frames 1-{result.offset} count as missing predictions")
        boxes = np.vstack([np.full((result.offset, 4), np.nan), boxes])
    return boxes


def _memory_is_an_error(run):
    """``run``, with memory running out anywhere in it a one-line error (exit status 2), never a
    traceback; the readers name the file when it runs out there (:func:`~nrmlc.workbench.results_layout.reading`)."""
    @functools.wraps(run)
    def guarded(args):
        try:
            return run(args)
        except MemoryError:
            raise InputTooLarge("evaluate: ran out of memory; nothing written (free memory, or score fewer "
                                "sequences or trackers at once)") from None

    return guarded


@_memory_is_an_error
def run_evaluate_file(args: argparse.Namespace) -> int:
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
        with _Outputs() as outputs:
            if args.csv:
                write_csv(comparison, outputs.stage(args.csv))
            if args.plot:
                plot_comparison(comparison, outputs.stage(args.plot))
    return 0


@_memory_is_an_error
def run_evaluate_folders(args: argparse.Namespace) -> int:
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
    written, speed_notes = _write_outputs(args, comparison, scores)
    for note in comparison.notes + notes + [f"{t.name}: {n}" for t in comparison.trackers for n in t.notes] \
            + speed_notes:
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
    for line in written:
        print(line, file=sys.stderr)
    return 0


class _Outputs(io.Together):
    """:class:`nrmlc.io.Together` for writers that take a path: each output is drawn into a
    temporary file beside it (:meth:`stage`), and all are renamed over their targets together."""

    def stage(self, path) -> Path:
        """A temporary file with ``path``'s extension, committed to ``path`` with the others."""
        tmp = io.temporary_for(path)
        self.file(tmp, path)
        return tmp


def _write_outputs(args: argparse.Namespace, comparison: Comparison, scores: list) -> tuple[list, list]:
    """Every output of the folder form, all or none: the speed plot, which can be refused, first.

    Returns
    -------
    written : list of str
        One line per plot written, for stderr.
    notes : list of str
        The speed plot's notes (trackers left out).
    """
    from nrmlc.errors import interrupt_requested

    written, notes = [], []
    with _Outputs() as outputs:
        if args.speed_plot:
            from nrmlc.workbench.speed import plot_speed

            _, notes = plot_speed(comparison, outputs.stage(args.speed_plot))
        if args.csv:
            from nrmlc.workbench.attributes import attribute_csv_rows

            write_csv(comparison, outputs.stage(args.csv), attribute_csv_rows(scores))
        if args.plot:
            plot_comparison(comparison, outputs.stage(args.plot))
            written.append(f"plots: {args.plot}")
        if args.attribute_plot:
            from nrmlc.workbench.attributes import plot_attributes

            plot_attributes(comparison, scores, outputs.stage(args.attribute_plot))
            written.append(f"attribute plot: {args.attribute_plot}")
        if args.speed_plot:
            written.append(f"speed plot: {args.speed_plot}")
        if interrupt_requested.is_set():
            raise KeyboardInterrupt  # a signal whose KeyboardInterrupt a finaliser swallowed
    return written, notes
