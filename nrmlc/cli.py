"""Command line: ``python -m nrmlc <command> ...``.

Every command turns user errors (:class:`nrmlc.errors.NrmlcError`, bad files,
bad parameters) into one line on stderr and exit status 2; ``--debug`` shows
the traceback instead.
"""
from __future__ import annotations

import argparse
import functools
import inspect
import os
import re
import signal
import sys
import warnings
from pathlib import Path


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from nrmlc.workbench.evaluate_cli import run_evaluate_file, run_evaluate_folders

    if args.data is not None:  # result folders of any number of trackers (nrmlc/workbench/evaluate_cli.py)
        return run_evaluate_folders(args)
    return run_evaluate_file(args)


def _cmd_list(args: argparse.Namespace) -> int:
    """list the sequences found under a data root

    List every sequence found under ROOT, one line each: its name, frame count, frame size and how
    many frames have a ground-truth box. ROOT may be in the OTB layout (a folder per sequence with
    img/ and groundtruth_rect.txt) or the sparse-tracker pack layout.
    """
    from nrmlc.data import list_sequences

    for sequence in list_sequences(args.root):
        height, width = sequence.frame_size
        print(f"{sequence.name:16s} {len(sequence):5d} frames  {width}x{height}  "
              f"{int(sequence.annotated.sum()):5d} annotated")
    return 0


def _cmd_synth(args: argparse.Namespace) -> int:
    """write the synthetic sequences to OTB folders

    Write the synthetic test suite (the sequences 'make figures' uses without --data) as OTB folders
    OUT/synth-01, OUT/synth-02, ...: frames as PNG files in img/ and the exact boxes in
    groundtruth_rect.txt. The same seed gives the same frames. Every check (the folders, memory,
    free disk) runs before anything is written, and each sequence is written whole or not at all;
    in OUT, an earlier synthetic sequence of the same length is replaced, anything else is refused.
    """
    import cv2

    from nrmlc.data import SyntheticSequence, write_otb_sequence
    from nrmlc.data.synthetic import MAX_FRAMES, MAX_SEQUENCES, check_otb_destination, suite_specs
    from nrmlc.errors import ParameterError
    from nrmlc.io import check_output
    from nrmlc.resources import available_memory, free_disk, gigabytes

    for option, value, low, high in (("--count", args.count, 1, MAX_SEQUENCES), ("--frames", args.frames, 2, MAX_FRAMES),
                                     ("--seed", args.seed, 0, 2**63 - 1)):
        if not low <= value <= high:
            raise ParameterError(f"{option} must be in {low}..{high}, got {value}")
    # The folder must be creatable and writable; probe it with a file name inside it.
    check_output(os.path.join(args.out, "groundtruth_rect.txt"), "--out")
    specs = suite_specs(n_frames=args.frames, n_sequences=args.count, seed=args.seed)
    for spec in specs:
        check_otb_destination(os.path.join(args.out, spec.name), spec.n_frames)
    memory = available_memory()
    if memory is not None and specs[0].estimated_bytes() > memory:
        raise ParameterError(f"--frames {args.frames}: a sequence needs about {gigabytes(specs[0].estimated_bytes())} "
                             f"of memory, {gigabytes(memory)} is available")
    first = SyntheticSequence(specs[0])
    # PNG of the first frame, with a margin: the frames of a suite compress alike.
    frame_bytes = 1.25 * len(cv2.imencode(".png", first.raw_frame(0))[1]) + 4096
    need = frame_bytes * args.frames * args.count
    free = free_disk(args.out)
    if free is not None and need > free:
        raise ParameterError(f"--out {args.out}: {args.count} x {args.frames} frames need about {gigabytes(need)}, "
                             f"{gigabytes(free)} is free there; nothing was written")
    for index, spec in enumerate(specs):
        sequence = first if index == 0 else SyntheticSequence(spec)
        folder = write_otb_sequence(sequence, os.path.join(args.out, spec.name))
        print(folder)
        del sequence
        first = None  # one sequence in memory at a time
    return 0


def _cmd_params(args: argparse.Namespace) -> int:
    """list the tracker's parameters: group, default, range, meaning

    List every tracker parameter that 'nrmlc track' and 'nrmlc benchmark' accept as --param
    NAME=VALUE, grouped by the part of the algorithm it governs: its value in the preset, the values
    it may take, and a one-line meaning. With --preset paper, the paper preset's values, those that
    differ from the default's marked *.
    """
    from nrmlc.errors import NrmlcError
    from nrmlc.tracker import params as tracker_params

    if not hasattr(tracker_params, "describe_parameters"):
        raise NrmlcError("this version of nrmlc.tracker.params has no describe_parameters(); "
                         "the parameters are documented in TrackerParams' docstring")
    import shutil

    for line in format_parameter_table(tracker_params.describe_parameters(args.preset),
                                       tracker_params.describe_parameters("default") if args.preset != "default"
                                       else None, args.preset, width=shutil.get_terminal_size().columns):
        print(line)
    return 0


def parameter_value_text(value) -> str:
    """A parameter's value as ``--param NAME=VALUE`` takes it (``false``, ``2,2,0.01``, ``0.1``)."""
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (tuple, list)):
        return ",".join(parameter_value_text(v) for v in value)
    return str(value)


def format_parameter_table(rows: list[dict], reference: list[dict] | None = None,
                           preset: str = "default", width: int | None = None) -> list[str]:
    """The lines of ``nrmlc params``: one block per group, columns aligned across all blocks.

    Parameters
    ----------
    rows : list of dict
        :func:`nrmlc.tracker.params.describe_parameters`' entries (``name``, ``group``,
        ``default``, ``range``, ``meaning``), in the order to print within a group.
    reference : list of dict, optional
        The 'default' preset's entries: a value that differs from its is marked ``*``.
    preset : str
        The preset the values are from, for the header.
    width : int, optional
        Wrap the meanings to lines of this many characters (at least 30 characters of meaning
        per line), continued under the meaning column; None: one line per parameter.
    """
    import textwrap

    reference_values = {row["name"]: row["default"] for row in reference or []}
    changed = {row["name"] for row in rows
               if row["name"] in reference_values and reference_values[row["name"]] != row["default"]}
    value_title = preset
    cells = [(row["name"], parameter_value_text(row["default"]) + ("*" if row["name"] in changed else ""),
              str(row["range"]), str(row["meaning"])) for row in rows]
    widths = [max([len(title)] + [len(cell[i]) for cell in cells])
              for i, title in enumerate(("name", value_title, "range"))]
    groups: dict[str, list] = {}
    for row, cell in zip(rows, cells):
        groups.setdefault(str(row["group"]), []).append(cell)
    header = f"  {'name':{widths[0]}}  {value_title:{widths[1]}}  {'range':{widths[2]}}  meaning"
    indent = len(header) - len("meaning")
    lines = [f"Tracker parameters, preset '{preset}' (change one with --param NAME=VALUE):", "", header]
    for group, group_cells in groups.items():
        lines += ["", f"{group}:"]
        for name, value, value_range, meaning in group_cells:
            meaning_lines = (textwrap.wrap(meaning, max(30, width - indent)) or [""]) if width else [meaning]
            lines.append(f"  {name:{widths[0]}}  {value:{widths[1]}}  {value_range:{widths[2]}}  {meaning_lines[0]}")
            lines += [" " * indent + more for more in meaning_lines[1:]]
    if changed:
        lines += ["", f"* differs from the 'default' preset ({len(changed)} of {len(rows)} parameters)"]
    return lines


def add_command(commands, name: str, run) -> argparse.ArgumentParser:
    """Add subcommand ``name``, which calls ``run(args)``. Its one-line help (``nrmlc --help``) is
    the first line of ``run``'s docstring, its description (``nrmlc NAME --help``) the rest: each
    command's text is written once, beside its code."""
    summary, _, description = inspect.getdoc(run).partition("\n\n")
    parser = commands.add_parser(name, help=summary, description=" ".join(description.split()))
    parser.set_defaults(run=run)
    return parser


def _add_track(commands) -> None:
    from nrmlc.cli_track import add_track_command

    add_track_command(commands)


def _add_benchmark(commands) -> None:
    from nrmlc.workbench.benchmark import add_benchmark_command

    add_benchmark_command(commands)


#: Functions that each add one more subcommand (``add_parser`` + ``set_defaults(run=...)``).
#: A new command is a function here; its module is imported when the parser is built.
_EXTRA_COMMANDS = [_add_track, _add_benchmark]

# A value that starts with a minus sign and a digit, e.g. ``--init-box -5,10,20,20``:
# argparse takes it for an option unless it is a plain negative number.
_NEGATIVE_VALUE = re.compile(r"^-[0-9.]")


def _join_negative_values(argv: list[str]) -> list[str]:
    """``--opt -5,10`` -> ``--opt=-5,10`` for options that take a value."""
    joined: list[str] = []
    index = 0
    while index < len(argv):
        token = argv[index]
        if (token.startswith("--") and "=" not in token and index + 1 < len(argv)
                and _NEGATIVE_VALUE.match(argv[index + 1]) and token in _VALUE_OPTIONS):
            joined.append(f"{token}={argv[index + 1]}")
            index += 2
            continue
        joined.append(token)
        index += 1
    return joined


#: Long options that take a value (filled by build_parser).
_VALUE_OPTIONS: set[str] = set()


def invoked_name() -> str:
    """The command as the user typed it, for the usage line: ``nrmlc`` (the installed script),
    or ``python -m nrmlc``."""
    script = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else ""
    return "python -m nrmlc" if script in ("__main__.py", "-m", "-c", "") else script


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """argparse's help with ``(default: X)`` after every option that has a default worth
    naming: not None (the help says what happens without it), not a flag's False, not an
    empty list, and not where the help already names its default."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if ("default" in text or default is None or default is False or default is argparse.SUPPRESS
                or (isinstance(default, list) and not default)):
            return text
        return super()._get_help_string(action)


#: Appended to the help of every ``--param`` option that does not point there yet.
PARAMS_POINTER = "names, defaults and ranges: see `nrmlc params`"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=invoked_name(), formatter_class=HelpFormatter,
        description="NRMLC visual tracker: track sequences, evaluate results (OTB one-pass evaluation), "
                    "benchmark a data root, list the tracker's parameters. 'COMMAND --help' describes each.",
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks instead of one-line errors")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    evaluate = commands.add_parser("evaluate", help="score a result file, or several trackers' result folders, against "
                                   "ground truth (CLE, overlap, AUC, precision@20; OTB plots)")
    evaluate.add_argument("--results", required=True, nargs="+", metavar="R.txt|DIR",
                          help="tracker boxes, one x,y,w,h line per frame (or an OTB <Seq>_<Tracker>.mat file); "
                               "with --data, result folders (DIR, or DIR:A,B for some trackers of a .mat folder)")
    evaluate.add_argument("--groundtruth", metavar="G.txt", help="ground-truth boxes (OTB groundtruth_rect.txt)")
    evaluate.add_argument("--json", action="store_true", help="print the summary as JSON")
    evaluate.add_argument("--include-first", action="store_true", help="also score frame 1 (the given box)")
    from nrmlc.workbench.evaluate_cli import add_evaluate_arguments

    add_evaluate_arguments(evaluate)
    evaluate.set_defaults(run=_cmd_evaluate)

    listing = add_command(commands, "list", _cmd_list)
    listing.add_argument("root", help="folder of sequences (OTB or sparse-tracker pack layout)")

    synth = add_command(commands, "synth", _cmd_synth)
    synth.add_argument("--out", required=True, help="output folder")
    synth.add_argument("--frames", type=int, default=120, help="frames per sequence")
    synth.add_argument("--count", type=int, default=3, help="number of sequences")
    synth.add_argument("--seed", type=int, default=0, help="generator seed")

    from nrmlc.tracker.params import PRESETS

    params = add_command(commands, "params", _cmd_params)
    params.add_argument("--preset", default="default", choices=tuple(PRESETS),
                        help="show this parameter set's values")

    for add_more in _EXTRA_COMMANDS:
        add_more(commands)
    for command in commands.choices.values():
        # Also for the parsers other modules build: every --help names the defaults.
        command.formatter_class = HelpFormatter
        # Also accepted after the command name; SUPPRESS keeps a top-level --debug from being reset.
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                             help="show tracebacks instead of one-line errors")
        for action in command._actions:
            if action.nargs != 0:
                _VALUE_OPTIONS.update(option for option in action.option_strings if option.startswith("--"))
            if "--param" in action.option_strings and "nrmlc params" not in (action.help or ""):
                action.help = f"{action.help}; {PARAMS_POINTER}" if action.help else PARAMS_POINTER
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(_join_negative_values(list(sys.argv[1:] if argv is None else argv)))
    from nrmlc.errors import interrupt_requested

    # Warnings as one "warning: ..." line each (no source line); restored on return
    # so that calling main() from Python does not change the caller's formatting.
    format_warning = warnings.formatwarning
    # After an interrupt, none: what it cut short warns of its consequences (a numba cache not written).
    warnings.formatwarning = lambda message, category, *rest: (
        "" if interrupt_requested.is_set() else f"warning: {message}\n")
    # SIGTERM and SIGHUP (the terminal closed, an ssh session lost) end a run like Ctrl-C: outputs
    # in progress are dropped, their temporary files removed, earlier files kept. All three also
    # set interrupt_requested, in case the KeyboardInterrupt lands in a finaliser.
    interrupt_requested.clear()
    unraisable_hook = sys.unraisablehook
    sys.unraisablehook = functools.partial(_quiet_lost_interrupt, unraisable_hook)
    previous = {}
    if threading_main():
        previous[signal.SIGTERM] = signal.signal(signal.SIGTERM, _terminate)
        if hasattr(signal, "SIGHUP") and signal.getsignal(signal.SIGHUP) is signal.SIG_DFL:  # not under nohup
            previous[signal.SIGHUP] = signal.signal(signal.SIGHUP, _terminate)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not where SIGINT is ignored
            previous[signal.SIGINT] = signal.signal(signal.SIGINT, _terminate)
    try:
        return _run(args)
    finally:
        warnings.formatwarning = format_warning
        sys.unraisablehook = unraisable_hook
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def threading_main() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def _quiet_lost_interrupt(previous_hook, unraisable) -> None:
    """Python's report of an exception raised in a finaliser, except our own interrupt's (the
    flag carries it on, and the run ends with the one line "interrupted"), and except any once the
    interrupt has come: it can land inside a constructor (llvmlite's ``ObjectRef.__init__`` while
    numba compiles), whose half-built object then fails in its ``__del__``."""
    from nrmlc.errors import interrupt_requested

    lost_interrupt = isinstance(unraisable.exc_type, type) and issubclass(unraisable.exc_type, KeyboardInterrupt)
    if not (lost_interrupt or interrupt_requested.is_set()):
        previous_hook(unraisable)


def console_main() -> int:
    """The ``nrmlc`` command and ``python -m nrmlc``: :func:`main`, with :func:`_quiet_lost_interrupt`
    kept on for the rest of the process, since the half-built objects are collected at its exit."""
    sys.unraisablehook = functools.partial(_quiet_lost_interrupt, sys.unraisablehook)
    return main()


def _terminate(signum, frame) -> None:
    from nrmlc.errors import interrupt_requested

    interrupt_requested.set()
    raise KeyboardInterrupt


def _run(args: argparse.Namespace) -> int:
    from concurrent.futures import BrokenExecutor

    from nrmlc.errors import NrmlcError

    try:
        return int(args.run(args) or 0)
    except NrmlcError as error:
        if args.debug:
            raise
        print(f"error: {_one_line(error)}", file=sys.stderr)
        return 2
    except MemoryError as error:
        if args.debug:
            raise
        print(f"error: out of memory ({_one_line(error) if str(error) else 'MemoryError'}): {_memory_advice()}",
              file=sys.stderr)
        return 2
    except BrokenExecutor as error:
        # A worker process killed from outside (the kernel's out-of-memory killer, most often).
        if args.debug:
            raise
        print(f"error: a worker process ended abruptly ({_one_line(error)}); runs finished before it are kept "
              f"(a rerun resumes); if memory ran out, {_memory_advice()}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader of our output went away (``... | head``): stop quietly, as Unix tools do.
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 141
    except OSError as error:
        if args.debug:
            raise
        print(f"error: {_one_line(error)}", file=sys.stderr)
        return 2


def _memory_advice() -> str:
    """What to do when memory ran out, naming the limit that applies where it is known."""
    try:
        from nrmlc.resources import memory_ceiling

        ceiling = memory_ceiling()
    except Exception:  # reading /proc may itself fail this close to the limit
        ceiling = None
    where = f" (at most {ceiling[1]})" if ceiling else ""
    return (f"the run needs more memory than it may take{where}; use fewer workers (--jobs) or smaller "
            f"parameters (n_particles, patch_size), or raise the limit")


def _one_line(error: BaseException) -> str:
    return " ".join(part.strip() for part in str(error).splitlines() if part.strip()) or type(error).__name__


if __name__ == "__main__":
    sys.exit(main())
