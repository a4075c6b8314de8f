"""Command line: ``python -m nrmlc <command> ...``.

Every command turns user errors (:class:`nrmlc.errors.NrmlcError`, bad files,
bad parameters) into one line on stderr and exit status 2; ``--debug`` shows
the traceback instead.
"""
from __future__ import annotations

import argparse
import json
import sys
import warnings


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from nrmlc.data import read_box_file
    from nrmlc.metrics import evaluate_files

    n_predicted, n_annotated = len(read_box_file(args.results)), len(read_box_file(args.groundtruth))
    if n_annotated < n_predicted:
        warnings.warn(f"{args.groundtruth}: {n_annotated} ground-truth boxes for {n_predicted} result boxes; "
                      f"only the first {n_annotated} frames are evaluated")
    result = evaluate_files(args.results, args.groundtruth, skip_first=not args.include_first)
    summary = result.as_dict()
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"frames evaluated : {result.n_frames} ({result.n_missing} missing predictions)")
        print(f"mean CLE         : {result.mean_center_error:.2f} px")
        print(f"mean overlap     : {result.mean_overlap:.4f}")
        print(f"success AUC      : {result.success_auc:.4f}")
        print(f"precision@20     : {result.precision_20:.4f}")
    return 0


def _cmd_list(args: argparse.Namespace) -> int:
    from nrmlc.data import list_sequences

    for sequence in list_sequences(args.root):
        height, width = sequence.frame_size
        print(f"{sequence.name:16s} {len(sequence):5d} frames  {width}x{height}  "
              f"{int(sequence.annotated.sum()):5d} annotated")
    return 0


def _cmd_synth(args: argparse.Namespace) -> int:
    from nrmlc.data import synthetic_suite, write_otb_sequence

    for sequence in synthetic_suite(n_frames=args.frames, n_sequences=args.count, seed=args.seed):
        folder = write_otb_sequence(sequence, f"{args.out}/{sequence.name}")
        print(folder)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m nrmlc",
        description="NRMLC visual tracker: track sequences, evaluate results (OTB one-pass evaluation).",
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks instead of one-line errors")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    evaluate = commands.add_parser("evaluate", help="score a result file against ground truth (CLE, overlap, AUC, precision@20)")
    evaluate.add_argument("--results", required=True, metavar="R.txt", help="tracker boxes, one x,y,w,h line per frame")
    evaluate.add_argument("--groundtruth", required=True, metavar="G.txt", help="ground-truth boxes (OTB groundtruth_rect.txt)")
    evaluate.add_argument("--json", action="store_true", help="print the summary as JSON")
    evaluate.add_argument("--include-first", action="store_true", help="also score frame 1 (the given box)")
    evaluate.set_defaults(run=_cmd_evaluate)

    listing = commands.add_parser("list", help="list the sequences found under a data root")
    listing.add_argument("root", help="folder of sequences (OTB or sparse-tracker pack layout)")
    listing.set_defaults(run=_cmd_list)

    synth = commands.add_parser("synth", help="write the synthetic sequences to OTB folders")
    synth.add_argument("--out", required=True, help="output folder")
    synth.add_argument("--frames", type=int, default=120, help="frames per sequence")
    synth.add_argument("--count", type=int, default=3, help="number of sequences")
    synth.add_argument("--seed", type=int, default=0, help="generator seed")
    synth.set_defaults(run=_cmd_synth)

    try:
        from nrmlc.tracker.cli import add_track_command
    except ImportError:  # the tracker is optional for the evaluation tools
        pass
    else:
        add_track_command(commands)
    for command in commands.choices.values():
        # Also accepted after the command name; SUPPRESS keeps a top-level --debug from being reset.
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                             help="show tracebacks instead of one-line errors")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # Warnings as one "warning: ..." line each (no source line); restored on return
    # so that calling main() from Python does not change the caller's formatting.
    format_warning = warnings.formatwarning
    warnings.formatwarning = lambda message, category, *rest: f"warning: {message}\n"
    try:
        return _run(args)
    finally:
        warnings.formatwarning = format_warning


def _run(args: argparse.Namespace) -> int:
    from nrmlc.errors import NrmlcError

    try:
        return int(args.run(args) or 0)
    except NrmlcError as error:
        if args.debug:
            raise
        print(f"error: {_one_line(error)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except OSError as error:
        if args.debug:
            raise
        print(f"error: {_one_line(error)}", file=sys.stderr)
        return 2


def _one_line(error: BaseException) -> str:
    return " ".join(part.strip() for part in str(error).splitlines() if part.strip()) or type(error).__name__


if __name__ == "__main__":
    sys.exit(main())
