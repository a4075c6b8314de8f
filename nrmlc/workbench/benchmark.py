"""``python -m nrmlc benchmark``: track every sequence of a data root into OTB result files.

Layout of the output folder (``--out``, e.g. ``results/NRMLC``)::

    results/NRMLC/
        Car4.txt                one x,y,w,h line per frame (1-based, OTB), the first seed
        Caviar1.txt ...
        seeds/<seed>/Car4.txt   every other seed (only when there are several)
        summary.csv             one row per (sequence, seed): overlap, CLE, AUC, precision@20, fps
        summary.json            the same, plus the mean over seeds per sequence and over sequences
        benchmark.json          settings, and one entry per finished (sequence, seed) run

The top-level ``<Seq>.txt`` files are what the OTB toolkits read (got10k's
``ExperimentOTB``, pysot, ``python -m nrmlc evaluate --results results/NRMLC``);
the first seed of the first invocation is the *primary* seed stored there, and
it stays so on later invocations.

Resuming: a run is finished when its entry is in ``benchmark.json``, the entry
was made from the data the sequence holds now (its content key, the one the run
cache keys on: :attr:`nrmlc.data.Sequence.identity`), and its result file holds
one box per tracked frame; a rerun skips it, whatever changed in the code since.
An entry whose file is missing or of another length, or whose sequence's frames
or ground truth changed since, is run again, with a warning naming the file.
The runs themselves go through :class:`nrmlc.workbench.run_cache.RunCache` (``--cache``,
default ``.cache/runs``), so a run interrupted before its file was written
is loaded from the cache, not recomputed; each run is recorded here as soon as
it is there, and one the cache cannot store (a full disk) is still recorded,
with a warning. All files are written atomically.

Several invocations may write one folder at once (``--sequences A`` and
``--sequences B`` started together): every read-modify-write of
``benchmark.json`` happens under an exclusive lock on ``.benchmark.lock`` in
the folder (``flock``), and each run's entry is merged into the manifest as
it is on disk, so none loses the other's runs; the summary is written from
the merged manifest. An invocation that has to wait for the lock says so, and
names the process holding it.

Nothing the user has is overwritten: an existing folder with ``.txt`` files
but no ``benchmark.json`` is refused, and so is a folder made with another
tracker (``--tracker``, :mod:`nrmlc.workbench.trackers`), other tracker
parameters, another frame cap or another data root (choose another ``--out``).
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import io as text_io
import json
import math
import os
import re
import sys
import warnings
from pathlib import Path

import numpy as np

from nrmlc import io
from nrmlc.errors import DataError, OutputError, ParameterError
from nrmlc.workbench.manifest import IDENTITY_FIELD, read_manifest
from nrmlc.workbench.results_layout import (LOCK_NAME, MANIFEST_NAME, SEEDS_FOLDER, SUMMARY_CSV, SUMMARY_JSON,
                                   has_suffix, parse_names, result_file, select_sequences)

#: Per-run scores, in the order of the summary columns.
SCORE_FIELDS = ("mean_overlap", "mean_center_error", "success_auc", "precision_20")
_RANGE = re.compile(r"^(\d+)-(\d+)$")


def parse_seeds(text: str) -> tuple[int, ...]:
    """``"0-4"`` -> (0, 1, 2, 3, 4); ``"0,3,7"`` -> (0, 3, 7); ranges and lists mix (``"0-2,9"``)."""
    seeds: list[int] = []
    for part in (p.strip() for p in str(text).split(",")):
        if not part:
            continue
        match = _RANGE.match(part)
        if match:
            first, last = int(match.group(1)), int(match.group(2))
            if last < first:
                raise ParameterError(f"--seeds {text!r}: range {part} ends before it starts")
            seeds.extend(range(first, last + 1))
        elif part.isdigit():
            seeds.append(int(part))
        else:
            raise ParameterError(f"--seeds {text!r}: expected non-negative integers and ranges like 0-4")
    if not seeds:
        raise ParameterError(f"--seeds {text!r}: no seed given")
    return tuple(dict.fromkeys(seeds))  # in order, without repeats


def _check_beside_inputs(path: Path, sequences, option: str = "--out") -> None:
    """Refuse an output folder (``--out``, ``--cache``) that is a sequence folder or inside one:
    ``--out``'s ``<Seq>.txt`` files would join that sequence (a sequence named ``groundtruth_rect``
    would even replace its ground truth), and files in its ``img/`` would become frames."""
    target = Path(os.path.realpath(path))
    for sequence in sequences:
        if sequence.path is None:
            continue
        folder = Path(os.path.realpath(sequence.path))
        if target == folder or folder in target.parents:
            raise ParameterError(f"{option} {path}: is inside the sequence folder {sequence.path}; write "
                                 f"{'the results' if option == '--out' else 'it'} elsewhere")


def _check_result_names(out: Path, sequences) -> None:
    """Refuse, before any run, a sequence whose result file name is longer (in bytes) than the
    file system of ``out`` allows: its run would be computed and then not written."""
    for sequence in sequences:
        problem = io.long_name(out / f"{sequence.name}.txt")
        if problem:
            raise DataError(f"{sequence.path or sequence.name}: its result file cannot be written in {out} "
                            f"({problem}); rename the sequence or leave it out with --sequences")


@contextlib.contextmanager
def _locked(out: Path, log=None):
    """Hold the folder's lock (exclusive ``flock`` on :data:`LOCK_NAME`): one writer of the manifest at a time.

    The holder writes its process id and host into the lock file, so that an invocation that has
    to wait says so, and for whom (through ``log``), instead of hanging without a word.
    """
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock (one invocation per folder at a time)
        yield
        return
    out.mkdir(parents=True, exist_ok=True)
    fd = _open_lock(out / LOCK_NAME)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if log is not None:
                log(f"benchmark: waiting for {out / LOCK_NAME}, held by {_lock_holder(fd)} "
                    f"(another benchmark writing into {out})")
            fcntl.flock(fd, fcntl.LOCK_EX)
        _write_holder(fd)
        yield
    finally:
        os.close(fd)  # releases the lock


def _open_lock(path: Path) -> int:
    """The lock file, opened for reading and writing (created if absent); refuse, in one line naming
    it, anything else by its name: a link (the holder's line would be written wherever it points),
    a folder, a FIFO or a device, or a file that cannot be opened."""
    import stat

    def refuse(what: str):
        raise OutputError(f"{path}: {what}, not the lock file nrmlc benchmark keeps there; remove it "
                          f"(it is made again) or choose another --out")

    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as exc:
        refuse(f"cannot be read ({exc.strerror or exc})")
    if mode is not None and stat.S_ISLNK(mode):
        refuse("a symbolic link")
    if mode is not None and not stat.S_ISREG(mode):
        refuse("a folder" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else "not a regular file")
    try:
        # No link followed, and no wait on a FIFO put there between the check and the open.
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o666)
    except OSError as exc:
        refuse(f"cannot be opened ({exc.strerror or exc})")
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        refuse("not a regular file")
    return fd


def _write_holder(fd: int) -> None:
    """Put this process's id and host in the held lock file (best effort: only a message reads it)."""
    import socket

    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()}\n".encode(), 0)
    except OSError:
        pass


def _lock_holder(fd: int) -> str:
    """Who holds the lock, as its holder wrote it (:func:`_write_holder`)."""
    try:
        text = os.pread(fd, 200, 0).decode(errors="replace").strip()
    except OSError:
        text = ""
    return text if text.startswith("pid ") else "another process"


def _read_manifest(out: Path, settings: dict) -> dict:
    """The folder's manifest, a new one for a new folder; refuse foreign or mismatched folders."""
    found = read_manifest(out, advice="repair or remove it, or choose another --out")
    if found is not None:
        for line in found.unwritten:
            warnings.warn(line)
        manifest = found.data
        stored = manifest["settings"]
        details = []
        # NRMLC's folders have no "tracker" (they have "params"); an imported tracker's has its name.
        trackers = stored.get("tracker"), settings.get("tracker")
        if trackers[0] != trackers[1]:
            old, new = (repr(t) if t is not None else "NRMLC" for t in trackers)
            details.append(f"tracker {old} there, {new} now")
        for key in sorted(set(stored) | set(settings)):
            old, new = stored.get(key), settings.get(key)
            if key == "tracker" or (key == "params" and trackers[0] != trackers[1]):
                continue
            if key == "params":
                # Fields added to TrackerParams since (or dropped) are not a difference.
                old, new = old or {}, new or {}
                details += [f"{f}={old[f]!r} there, {new[f]!r} now"
                            for f in sorted(set(old) & set(new)) if old[f] != new[f]]
            elif old != new:
                details.append(f"{key}={old!r} there, {new!r} now")
        if details:
            raise DataError(f"{out}: made with other settings ({'; '.join(details)}); "
                            f"choose another --out to keep both")
        return manifest
    if out.exists() and not out.is_dir():
        raise DataError(f"{out}: exists and is not a folder")
    held = _results_held(out) if out.is_dir() else None
    if held is not None:
        raise DataError(f"{out}: holds {held} but no {MANIFEST_NAME} (not made by nrmlc benchmark); "
                        f"choose another --out, nothing there is overwritten")
    return {"settings": settings, "primary_seed": None, "runs": {}}


#: Names in a folder, lower case, that ``nrmlc benchmark`` writes or ``nrmlc evaluate`` reads as results.
_RESULT_NAMES = (SUMMARY_CSV, SUMMARY_JSON, SEEDS_FOLDER)


def _results_held(out: Path) -> str | None:
    """What in ``out`` a benchmark would overwrite, or would make read otherwise (``<Seq>.txt``
    results, OTB ``.mat`` results, a summary, ``seeds/``; extensions and names in any case, as
    evaluate reads them; hidden names are no one's results), e.g. ``"Car4.TXT"``; None if nothing."""
    for entry in sorted(out.iterdir()):
        name = entry.name
        if (has_suffix(name, ".txt") or has_suffix(name, ".mat")
                or (not name.startswith(".") and name.lower() in _RESULT_NAMES)):
            return name
    return None


def _scores(boxes: np.ndarray, sequence) -> dict | None:
    """OTB scores of ``boxes`` on the first ``len(boxes)`` frames, or None without ground truth there."""
    from nrmlc.workbench.metrics import evaluate

    truth = sequence.groundtruth[: len(boxes)]
    try:
        evaluation = evaluate(boxes, truth)
    except DataError:  # no annotated frame after the first
        return None
    return evaluation.as_dict()


def run_benchmark(data_root, out, params=None, seeds=(0,), sequences: list[str] | None = None,
                  max_frames: int | None = None, jobs: int | None = None, executor=None, cache=None,
                  progress: bool = True, log=None, tracker=None) -> dict:
    """Track every selected (sequence, seed) that is not finished yet and write the results.

    Parameters
    ----------
    data_root : path
        Folder of sequences (any layout :func:`nrmlc.data.list_sequences` reads).
    out : path
        Output folder (see the module docstring for its layout).
    params : TrackerParams, optional
        Shorthand for ``tracker=NRMLCEntry(params)``.
    seeds : sequence of int
    sequences : list of str, optional
        Sequence names (default: all of the root).
    max_frames : int, optional
        Track only the first frames of each sequence (scored on those frames).
    jobs : int, optional
        Worker processes (default: all cores).
    executor : concurrent.futures.Executor, optional
        Where to run (e.g. a Dask client's ``get_executor()``).
    cache : nrmlc.workbench.run_cache.RunCache, optional
        Run cache (default: ``.cache/runs``).
    progress : bool
        Progress bar on stderr.
    log : callable(str), optional
        Where status lines go (default: stderr).
    tracker : entry, optional
        The tracker to run (:mod:`nrmlc.workbench.trackers`: ``NRMLCEntry(params)``, or
        ``ImportedTracker("package.module:factory")`` for any ``init`` / ``update`` tracker);
        default NRMLC with ``params``. Not both.

    Returns
    -------
    summary : dict
        What ``summary.json`` holds.
    """
    from nrmlc.data import read_box_file
    from nrmlc.workbench.jobs import _count, frames_tracked
    from nrmlc.workbench.run_cache import RunCache
    from nrmlc.workbench.trackers import NRMLCEntry, TrackerEntry
    from nrmlc.workbench.version import code_version

    log = log or (lambda line: print(line, file=sys.stderr, flush=True))
    if tracker is None:
        tracker = NRMLCEntry() if params is None else NRMLCEntry(params)
    elif params is not None:
        raise ParameterError("run_benchmark: give params (NRMLC's) or tracker, not both")
    if not isinstance(tracker, TrackerEntry):
        raise ParameterError(f"run_benchmark: tracker must have name, settings() and job() "
                             f"(nrmlc.workbench.trackers), got {type(tracker).__name__}")
    if max_frames is not None:
        max_frames = _count("--max-frames", max_frames, 2)
    seeds = tuple(_count("seed", s, 0) for s in seeds)
    if not seeds:
        raise ParameterError("run_benchmark: no seed given")
    out = Path(out)
    data_root = Path(data_root)
    io.check_folder(out, "--out")
    io.check_output(out / MANIFEST_NAME, "--out")
    if cache is not None:
        cache.check_folder()  # asked for by name: refused before any work if it cannot be written
    chosen = select_sequences(data_root, sequences)
    usable = []
    for sequence in chosen:
        try:
            sequence.init_box
        except DataError:  # e.g. a folder of frames without ground truth: nothing to start from
            warnings.warn(f"{sequence.path or sequence.name}: skipped, no ground-truth box on frame 1 to start from")
            continue
        usable.append(sequence)
    if not usable:
        raise DataError(f"{data_root}: no sequence with a ground-truth box on frame 1 to start from")
    chosen = usable
    _check_beside_inputs(out, chosen)
    cache = cache if cache is not None else RunCache()
    _check_beside_inputs(cache.folder, chosen, cache.label if cache.default else "--cache")
    _check_result_names(out, chosen)
    settings = json.loads(json.dumps({**tracker.settings(), "max_frames": max_frames,
                                      "data": str(data_root.resolve())}, default=str))
    with _locked(out, log):
        # Settled under the lock, and written at once: a second invocation started alongside
        # sees this one's settings and primary seed.
        manifest = _read_manifest(out, settings)
        if manifest["primary_seed"] is None:
            manifest["primary_seed"] = seeds[0]
            io.write_json(out / MANIFEST_NAME, manifest)
    primary = int(manifest["primary_seed"])

    unrecorded = []  # runs whose entry does not say what data they were made from

    def finished(sequence, seed: int) -> bool:
        entry = manifest["runs"].get(sequence.name, {}).get(str(seed))
        if entry is None:
            return False
        path = result_file(out, sequence.name, seed, primary)
        expected = frames_tracked(sequence, max_frames)
        problem = None
        recorded = entry.get(IDENTITY_FIELD)
        if recorded is None:
            unrecorded.append(path)
            return False
        if recorded != sequence.identity:
            problem = f"made from other data: the frames or ground truth of {sequence.path or sequence.name} changed since"
        elif not path.is_file():
            problem = "missing"
        elif entry["frames"] != expected:
            problem = f"its manifest entry says {entry['frames']} frames, the run tracks {expected}"
        else:
            try:
                rows = len(read_box_file(path, predictions=True))
            except DataError as exc:
                problem = str(exc)
            else:
                if rows != expected:
                    problem = f"{rows} boxes for {expected} frames"
        if problem is not None:
            warnings.warn(f"{path}: not a finished result ({problem}); running it again")
        return problem is None

    todo = [tracker.job(s, seed, max_frames) for s in chosen for seed in seeds if not finished(s, seed)]
    if unrecorded:
        warnings.warn(f"{out / MANIFEST_NAME}: {len(unrecorded)} runs (e.g. {unrecorded[0]}) do not record the data "
                      f"they were made from (an earlier nrmlc wrote them), so they may be stale; running them again "
                      f"(from the run cache where it holds them)")
    total = len(chosen) * len(seeds)
    # Said before the work starts: a run the shared cache holds takes no time and no worker.
    in_cache = sum(cache.has(spec) for spec in todo)
    log(f"benchmark: {len(chosen)} sequences x {len(seeds)} seeds -> {out}: "
        f"{total - len(todo)} finished, {len(todo)} to run"
        + (f" ({in_cache} of them from the run cache {cache.folder}, {len(todo) - in_cache} to compute)"
           if todo else ""))
    if todo:
        version = code_version()

        def record(spec, result) -> None:
            name = spec.sequence.name
            entry = {
                "frames": int(len(result.boxes)),
                "fps": None if math.isnan(result.fps_tracking) else float(result.fps_tracking),
                "scores": _scores(result.boxes, spec.sequence),
                "code_version": version,
                # The run cache's content key of the sequence: a rerun tells changed data from unchanged.
                IDENTITY_FIELD: spec.sequence.identity,
            }
            with _locked(out, log):
                # Merged into the manifest as it is now: another invocation may have added runs.
                current = _read_manifest(out, settings)
                # The file first, then its entry: an entry always has its file.
                io.write_boxes(result_file(out, name, spec.seed, primary), result.boxes)
                current["runs"].setdefault(name, {})[str(spec.seed)] = entry
                io.write_json(out / MANIFEST_NAME, current)

        # Each run is recorded as soon as it is there: one that fails later, an interrupt or a cache
        # that cannot be written loses none of those before it.
        cache.run(todo, executor=executor, jobs=jobs, progress=progress, on_result=record)
    with _locked(out, log):
        # From the manifest on disk: it holds the runs of every invocation into this folder.
        manifest = _read_manifest(out, settings)
        summary = summarize(manifest)
        write_summary(out, summary)
    log(f"results: {out}/<Seq>.txt" + (f", {out / SEEDS_FOLDER}/<seed>/<Seq>.txt" if len(set(seeds) | {primary}) > 1
                                        or (out / SEEDS_FOLDER).is_dir() else "")
        + f"; scores: {out / SUMMARY_CSV}, {out / SUMMARY_JSON}")
    return summary


def summarize(manifest: dict) -> dict:
    """Per-run rows, per-sequence means over seeds, and means over sequences (with ground truth)."""
    rows = []
    for name in sorted(manifest["runs"]):
        for seed in sorted(manifest["runs"][name], key=int):
            entry = manifest["runs"][name][seed]
            scores = entry.get("scores") or {}
            rows.append({"sequence": name, "seed": int(seed), "frames": entry["frames"],
                         "evaluated_frames": scores.get("n_frames"),
                         **{k: scores.get(k) for k in SCORE_FIELDS}, "fps": entry.get("fps")})

    def mean(values):
        values = [v for v in values if v is not None]
        return float(np.mean(values)) if values else None

    per_sequence = {}
    for name in sorted({r["sequence"] for r in rows}):
        mine = [r for r in rows if r["sequence"] == name]
        per_sequence[name] = {"seeds": [r["seed"] for r in mine],
                              **{k: mean(r[k] for r in mine) for k in SCORE_FIELDS + ("fps",)}}
    scored = [v for v in per_sequence.values() if v["success_auc"] is not None]
    overall = {"sequences": len(scored), **{k: mean(v[k] for v in scored) for k in SCORE_FIELDS + ("fps",)}}
    return {"settings": manifest["settings"], "primary_seed": manifest["primary_seed"], "runs": rows,
            "per_sequence": per_sequence, "mean_over_sequences": overall}


def write_summary(out: Path, summary: dict) -> None:
    """``summary.json`` and ``summary.csv`` (one row per run) in ``out``, atomically."""
    io.write_json(Path(out) / SUMMARY_JSON, summary)
    buffer = text_io.StringIO()
    columns = ["sequence", "seed", "frames", "evaluated_frames", *SCORE_FIELDS, "fps"]
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in summary["runs"]:
        writer.writerow({k: ("" if row[k] is None else row[k]) for k in columns})
    io.write_text(Path(out) / SUMMARY_CSV, buffer.getvalue())


def format_summary(summary: dict) -> str:
    """Per-sequence means over seeds as a text table, and their mean."""

    def cell(value, fmt):
        return "-" if value is None else format(value, fmt)

    lines = [f"{'sequence':16s} {'seeds':>5s} {'overlap':>8s} {'CLE px':>8s} {'AUC':>6s} {'P@20':>6s} {'fps':>7s}"]
    for name, row in summary["per_sequence"].items():
        lines.append(f"{name:16s} {len(row['seeds']):5d} {cell(row['mean_overlap'], '8.3f')} "
                     f"{cell(row['mean_center_error'], '8.1f')} {cell(row['success_auc'], '6.3f')} "
                     f"{cell(row['precision_20'], '6.3f')} {cell(row['fps'], '7.1f')}")
    total = summary["mean_over_sequences"]
    lines.append(f"{'mean of ' + str(total['sequences']):16s} {'':5s} {cell(total['mean_overlap'], '8.3f')} "
                 f"{cell(total['mean_center_error'], '8.1f')} {cell(total['success_auc'], '6.3f')} "
                 f"{cell(total['precision_20'], '6.3f')} {cell(total['fps'], '7.1f')}")
    return "\n".join(lines)


# ------------------------------------------------------------------ command line
def add_benchmark_command(commands) -> None:
    """Register ``benchmark`` on the subparsers of ``python -m nrmlc``."""
    bench = commands.add_parser(
        "benchmark", help="track every sequence of a data root into OTB result files (resumable)",
        description="Track every sequence of DATA with NRMLC (or your own tracker: --tracker) and write "
                    "OTB result files OUT/<Seq>.txt (the first seed; other seeds in OUT/seeds/<seed>/), "
                    "OUT/summary.csv and OUT/summary.json (overlap, CLE, AUC, precision@20, fps "
                    "where there is ground truth). A rerun skips every finished (sequence, seed).")
    bench.add_argument("data", metavar="DATA", help="data root: a folder of sequence folders")
    bench.add_argument("--out", required=True, metavar="DIR", help="results folder, e.g. results/NRMLC")
    bench.add_argument("--seeds", default="0", help="seeds, e.g. 0-4 or 0,2,5 (default 0)")
    bench.add_argument("--sequences", metavar="A,B", help="only these sequences (default: all)")
    from nrmlc.tracker.params import PRESETS

    bench.add_argument("--preset", choices=tuple(PRESETS),
                       help="named parameter set (TrackerParams.preset; default: 'default'), before --param")
    bench.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                       help="any tracker parameter, e.g. --param n_particles=300 (repeatable)")
    from nrmlc.workbench.trackers import CONTRACT

    bench.add_argument("--tracker", metavar="NAME|MODULE:FACTORY",
                       help="benchmark another tracker instead of NRMLC: one of the paper's lineage, live "
                            "(ivt: IVT as the OTB benchmark ran it; nrmlc/lineage), or your own, "
                            "package.module:factory, a callable "
                            f"(called with seed=SEED if it has a seed parameter) returning {CONTRACT}; "
                            "the module must be importable (PYTHONPATH); not with --preset or --param")
    bench.add_argument("--max-frames", type=int, metavar="N", help="track only the first N frames of each sequence")
    bench.add_argument("--jobs", type=int, metavar="N", help="worker processes (default: all cores)")
    bench.add_argument("--dask", metavar="ADDRESS", help="run on a Dask cluster (needs the 'distributed' package)")
    bench.add_argument("--cache", metavar="DIR", help="run cache folder (default: .cache/runs)")
    bench.set_defaults(run=_cmd_benchmark)


def _cmd_benchmark(args: argparse.Namespace) -> int:
    from nrmlc.workbench.run_cache import RunCache
    from nrmlc.tracker.params import TrackerParams, parse_param_assignment
    from nrmlc.workbench.trackers import ImportedTracker, NRMLCEntry

    if args.tracker is not None:
        nrmlc_only = [option for option, given in (("--preset", args.preset), ("--param", args.param)) if given]
        if nrmlc_only:
            raise ParameterError(f"--tracker {args.tracker}: {' and '.join(nrmlc_only)} set NRMLC's parameters; "
                                 f"give them without --tracker, or give your tracker's settings in its factory")
        tracker = ImportedTracker(args.tracker)
    else:
        base = TrackerParams.preset(args.preset) if args.preset else TrackerParams()
        tracker = NRMLCEntry(base.replace(**dict(parse_param_assignment(text) for text in args.param)))
    if args.jobs is not None and args.jobs < 1:
        raise ParameterError(f"--jobs must be >= 1, got {args.jobs}")
    executor = None
    if args.dask:
        try:
            from distributed import Client
        except ImportError:
            raise ParameterError("--dask needs the Dask 'distributed' package (pip install -e .[cluster])") from None
        executor = Client(args.dask).get_executor()
    summary = run_benchmark(args.data, args.out, seeds=parse_seeds(args.seeds), sequences=parse_names(args.sequences),
                            max_frames=args.max_frames, jobs=args.jobs, executor=executor,
                            cache=RunCache(args.cache) if args.cache else None, tracker=tracker)
    print(format_summary(summary))
    return 0
