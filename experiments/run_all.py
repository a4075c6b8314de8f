"""``make figures``: every figure and table of the paper, and ``REPORT.md``.

Usage::

    python -m experiments.run_all [--data DIR] [--out DIR] [--sequences A,B] [--seeds N]
                                  [--sweep-seeds N] [--ablation-seeds N] [--jobs J] [--max-frames N]
                                  [--only SCRIPT,SCRIPT] [--dry-run] [--dask SCHEDULER_ADDRESS]

Results go to ``out/figures/`` (git-ignored) unless ``--out`` names another
folder; the committed real-data results are written with ``--out figures``.

Steps:

1. build the :class:`~experiments.grid.Context` (data, seeds, run cache);
2. collect the jobs of every script (``runs(context)``: tracking runs, live
   peer runs of OpenCV and the lineage, recorded internals), print the size of the grid per script and
   an estimate of its time from a speed measured on this machine just then
   (:func:`measure_speed`; ``--dry-run`` stops here), and compute the missing ones in one pool of
   warmed-up workers (cached runs are skipped, so a rerun or an interrupted
   run costs only what is missing);
3. run each script (:func:`experiments.grid.run_script`: ``collect``, ``plot``,
   ``report``) in the paper's order, from the cached results; one that fails
   is reported (traceback on stderr, a note in the report) and the others
   still run;
4. write ``REPORT.md``, print one closing line (what was written, where, how long it took);
   exit non-zero if any script failed.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import time
import traceback
from pathlib import Path

from experiments import report
from experiments.grid import add_arguments, context_from_namespace, run_script
from nrmlc.errors import NrmlcError
from nrmlc.tracker.generative import LOCAL_SIZE

#: Every script, in the paper's order.
SCRIPTS = (
    "experiments.paper.theorem1_checks",
    "experiments.paper.fig1_coefficients",
    "experiments.paper.fig2_mean_gray",
    "experiments.paper.stats_nonnegativity",
    "experiments.paper.table1_table2_accuracy",
    "experiments.paper.fig3_qualitative",
    "experiments.paper.fig4_lambda_sweep",
    "experiments.paper.fig_occlusion",
    "experiments.paper.ablations",
    "experiments.paper.ablation_per_sequence_motion",
    "experiments.paper.ablation_oracle_recentring",
    "experiments.paper.ablation_oracle_gate",
    "experiments.paper.failure_mechanisms",
    "experiments.paper.scale_likelihood",
)

#: Frames timed by :func:`measure_speed` (after one untimed update): a second or two at the
#: speeds seen on 2-core machines, 30-100 frames/s per worker.
SPEED_FRAMES = 40
#: Work of one frame of OpenCV's MIL in 600-particle NRMLC frames: it ran at about 15 frames/s
#: per worker where NRMLC ran at about 95.
PEER_FRAME_COST = 95.0 / 15.0
#: The same for the lineage's live trackers (by factory): CPU time per frame on Car4, one thread
#: (IVT about 15 ms, ASLA about 65 ms, L1 about 17 ms, L1-APG about 23 ms), over the 600-particle
#: NRMLC frame's (about 17 ms).
LINEAGE_FRAME_COST = {"nrmlc.lineage.ivt:IVTTracker": 15.0 / 17.0, "nrmlc.lineage.asla:ASLATracker": 65.0 / 17.0,
                      "nrmlc.lineage.l1:L1Tracker": 17.0 / 17.0, "nrmlc.lineage.l1apg:L1APGTracker": 23.0 / 17.0}


def _short(module: str) -> str:
    return module.rsplit(".", 1)[-1]


def import_scripts(selected, failures: list) -> list:
    """Import the selected scripts; one that does not import is a failure (the others go on)."""
    modules = []
    for name in SCRIPTS:
        if selected is not None and _short(name) not in selected:
            continue
        try:
            modules.append(importlib.import_module(name))
        except Exception as exc:
            traceback.print_exc()
            failures.append((_short(name), f"import failed: {exc!r}"))
    return modules


def collect_jobs(context, modules, failures: list) -> dict:
    """{script: its jobs (``runs(context)``)} for every script."""
    jobs = {}
    for module in modules:
        try:
            jobs[_short(module.__name__)] = list(module.runs(context))
        except Exception as exc:
            traceback.print_exc()
            failures.append((_short(module.__name__), f"runs() failed: {exc!r}"))
    return jobs


def job_cost(job) -> float:
    """Work of a job in 600-particle NRMLC frames without the generative term (measured: the
    particle count scales the time about linearly; the exact constrained coder is about 1.3x
    slower)."""
    params = getattr(job, "params", None)
    if params is None:  # a peer: one of the lineage's, or OpenCV's
        return job.frames() * LINEAGE_FRAME_COST.get(getattr(job, "tracker", None), PEER_FRAME_COST)
    factor = params.n_particles / 600.0
    if getattr(params, "generative_weight", 0) > 0:
        # Measured when the generative term was adopted: SCM's full grid (150 candidates x 196 local
        # patches) adds 2.6 frames' work, 20 x 49 adds 0.18.
        n_local = ((params.patch_size - LOCAL_SIZE) // params.generative_step + 1) ** 2
        factor += 0.1 + 2.5 * params.generative_candidates * n_local / (150 * 196)
    if params.coding == "constrained":
        factor *= 1.3
    return job.frames() * factor


def measure_speed(n_frames: int = SPEED_FRAMES) -> float:
    """This machine's speed now, in the unit of :func:`job_cost`: 600-particle NRMLC frames
    (no generative term) per second in one thread, as a worker of the grid runs them.

    A synthetic run in this process, timed from its second update to its last (the kernels'
    loading, the initial templates and the first update left out; the frames' rendering counted,
    as a worker's decoding is). A few seconds; the first run after an install compiles the
    kernels first, which the grid would do anyway.
    """
    import time as clock

    import numba

    from nrmlc.config import set_threads
    from nrmlc.data import SyntheticSequence, SyntheticSpec
    from nrmlc.tracker.loop import track_sequence
    from nrmlc.tracker.params import TrackerParams

    sequence = SyntheticSequence(SyntheticSpec(name="speed", seed=0, n_frames=n_frames + 2))
    ticks: list[float] = []
    threads = numba.get_num_threads()
    set_threads(1)
    try:
        track_sequence(sequence, TrackerParams(n_particles=600, generative_weight=0.0), n_frames=n_frames + 2,
                       on_frame=lambda index, tracker, frame: ticks.append(clock.perf_counter()) if index else None)
    finally:
        set_threads(threads)
    return (len(ticks) - 1) / (ticks[-1] - ticks[0])


def grid_summary(context, jobs_by_script: dict, measure=measure_speed) -> tuple[list, dict, str]:
    """The union of the jobs, counts, and a printable summary (per script; shared jobs counted once),
    with an estimate of the time from ``measure()`` (frames/s per worker, see :func:`measure_speed`),
    called only when something is to be computed."""
    cache = context.cache
    unique: dict = {}
    lines = []
    for script, jobs in jobs_by_script.items():
        keys = {cache.path(j): j for j in jobs}
        nrmlc = [j for j in keys.values() if getattr(j, "uses_kernels", False)]
        new = [j for p, j in keys.items() if p not in unique and getattr(j, "uses_kernels", False)]
        lines.append(f"  {script}: {len(nrmlc)} NRMLC runs, {sum(j.frames() for j in nrmlc)} frames "
                     f"({sum(j.frames() for j in new)} not shared with the scripts above)"
                     + (f"; {len(keys) - len(nrmlc)} peer runs" if len(keys) > len(nrmlc) else ""))
        unique.update(keys)
    union = list(unique.values())
    present = {path for path in unique if path.is_file()}
    nrmlc = [j for j in union if getattr(j, "uses_kernels", False)]
    peers_ = [j for j in union if not getattr(j, "uses_kernels", False)]
    frames = sum(j.frames() for j in nrmlc)
    missing_frames = sum(j.frames() for j in nrmlc if cache.path(j) not in present)
    peer_frames = sum(j.frames() for j in peers_)
    peer_missing = sum(j.frames() for j in peers_ if cache.path(j) not in present)
    cost = sum(job_cost(j) for j in union if cache.path(j) not in present)
    text = "\n".join([f"[run_all] grid: {len(nrmlc)} NRMLC runs, {frames} frames ({frames - missing_frames} cached, "
                      f"{missing_frames} to compute); {len(peers_)} peer runs (OpenCV, the lineage), {peer_frames} frames "
                      f"({peer_missing} to compute). {estimate_text(context, cost, measure)}"]
                     + lines)
    counts = {"runs": len(nrmlc), "frames": frames, "missing_frames": missing_frames,
              "peer_runs": len(peers_), "peer_frames": peer_frames}
    return union, counts, text


def estimate_text(context, cost: float, measure=measure_speed) -> str:
    """``Estimate: ~N min on W worker(s) (...)``, the speed measured by ``measure()`` now."""
    if cost <= 0:
        return "Estimate: nothing to compute, every run is cached."
    print(f"[run_all] measuring this machine's speed ({SPEED_FRAMES} frames, one thread) ...", file=sys.stderr,
          flush=True)
    try:
        fps = float(measure())
    except Exception as exc:  # the grid's own runs will say what is wrong, with the job named
        return f"Estimate: none (the speed measurement failed: {exc!r})."
    cores = os.cpu_count() or 1
    workers = context.jobs or cores
    minutes = cost / fps / min(workers, cores) / 60
    where = ("measured just now on this machine; the cluster's may differ" if context.executor is not None
             else "measured just now on this machine")
    return (f"Estimate: ~{minutes:.0f} min on {workers} worker(s) (~{cost:.0f} 600-particle frame equivalents "
            f"at {fps:.0f} frames/s per worker, {where}).")


def written_since(folder, since: float) -> dict[str, int]:
    """How many ``.png``, ``.csv`` and ``.json`` files in ``folder`` were written at or after ``since``
    (``time.time()``)."""
    counts = {".png": 0, ".csv": 0, ".json": 0}
    for path in Path(folder).iterdir() if Path(folder).is_dir() else ():
        if path.suffix in counts and path.is_file() and path.stat().st_mtime >= since:
            counts[path.suffix] += 1
    return counts


def closing_line(folder, counts: dict[str, int], report_name: str, seconds: float, failures: list) -> str:
    """``[run_all] wrote 14 figures, 8 tables, 15 JSON files and REPORT.md to out/figures/ in 3.1 min``."""
    try:
        shown = os.path.relpath(folder)
    except ValueError:  # another drive
        shown = str(folder)
    if shown.startswith(".."):
        shown = str(folder)
    plural = lambda n, word: f"{n} {word}{'' if n == 1 else 's'}"
    line = (f"[run_all] wrote {plural(counts['.png'], 'figure')}, {plural(counts['.csv'], 'table')} (CSV), "
            f"{plural(counts['.json'], 'JSON file')} and {report_name} to {shown.rstrip(os.sep)}{os.sep} "
            f"in {f'{seconds / 60:.1f} min' if seconds >= 60 else f'{seconds:.0f} s'}")
    if failures:
        line += f"; {plural(len(failures), 'script')} failed: {', '.join(name for name, _ in failures)}"
    return line


def run_grid(context, union: list) -> None:
    """Compute every missing job in one pool of warmed-up workers, longest first."""
    context.cache.ensure(union, executor=context.executor, jobs=context.jobs)


def run_scripts(context, modules, failures: list) -> list[dict]:
    """Run every script from the cache; a failure becomes a section saying so."""
    sections = []
    for module in modules:
        name = _short(module.__name__)
        start = time.perf_counter()
        print(f"[run_all] {name} ...", file=sys.stderr, flush=True)
        try:
            section = run_script(module, context)
            if not isinstance(section, dict) or "title" not in section:
                raise TypeError(f"report() returned {type(section).__name__}, not a dict with a title")
            section = {"title": section["title"], "figures": list(section.get("figures", [])),
                       "markdown": section.get("markdown", "")}
        except Exception as exc:
            traceback.print_exc()
            failures.append((name, repr(exc)))
            section = {"title": f"{name}: FAILED", "figures": [],
                       "markdown": f"`{name}` raised `{exc!r}`; see the log for the traceback."}
        print(f"[run_all] {name} done in {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)
        sections.append(section)
    return sections


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m experiments.run_all",
        description="Run every experiment (figures, tables, ablations) and write REPORT.md beside them. "
                    "Without --data: the synthetic suite. Runs are cached in .cache/runs; a rerun computes "
                    "only what is missing.")
    add_arguments(parser)
    parser.add_argument("--dask", default=None, metavar="SCHEDULER_ADDRESS",
                        help="run the grid on a Dask distributed cluster (needs the 'distributed' package)")
    parser.add_argument("--only", default=None, metavar="SCRIPT[,SCRIPT]",
                        help="run only these scripts (short names: " + ", ".join(_short(n) for n in SCRIPTS) + ")")
    parser.add_argument("--dry-run", action="store_true",
                        help="print the grid (runs and frames per script, how many are cached, the time it "
                             "will take from a few seconds' measurement of this machine's speed) and stop "
                             "without running it")
    return parser


def main(argv=None) -> int:
    """Run everything; return the exit status (0, or 1 if any script failed).

    Warnings are printed as one ``warning: ...`` line each, without the source line (as the
    ``nrmlc`` command prints them); the caller's formatting is restored on return.
    """
    import warnings

    format_warning = warnings.formatwarning
    warnings.formatwarning = lambda message, category, *rest: f"warning: {message}\n"
    try:
        return _main(argv)
    finally:
        warnings.formatwarning = format_warning


def _main(argv=None) -> int:
    start = time.perf_counter()
    started_at = time.time() - 1.0  # file times: a second's slack for coarse clocks
    parser = build_parser()
    args = parser.parse_args(argv)
    selected = None if args.only is None else {s.strip() for s in args.only.split(",") if s.strip()}
    if selected is not None:
        unknown = selected - {_short(n) for n in SCRIPTS}
        if unknown:
            parser.error(f"--only: unknown script(s) {', '.join(sorted(unknown))}; "
                         f"choose from {', '.join(_short(n) for n in SCRIPTS)}")
    try:
        context = context_from_namespace(args)
        context.sequences()  # an empty or broken data root fails here, with the file named
    except NrmlcError as exc:  # a wrong --data or --param: one line, no traceback
        print(f"error: {exc}", file=sys.stderr)
        return 2
    client = None
    if args.dask:
        try:
            from distributed import Client
        except ImportError:
            parser.error("--dask needs the Dask 'distributed' package, which is not installed "
                         "(pip install -e .[cluster]); without --dask the grid runs in a local process pool")
        client = Client(args.dask)
        context.executor = client.get_executor()

    notes: list[str] = []
    failures: list[tuple[str, str]] = []
    try:
        print(f"[run_all] data: {context.data_label}; {len(context.sequences())} sequences; "
              f"{context.describe_grid()}", file=sys.stderr)
        modules = import_scripts(selected, failures)
        jobs = collect_jobs(context, modules, failures)
        union, counts, summary = grid_summary(context, jobs)
        print(summary, file=sys.stderr, flush=True)
        if args.dry_run:
            return 1 if failures else 0
        try:
            run_grid(context, union)
        except NrmlcError as exc:  # e.g. a numba target this CPU cannot run: one line, and stop
            print(f"error: {exc}", file=sys.stderr)
            return 2
        except Exception as exc:
            # The scripts will retry what is missing and fail one by one; say where it started.
            traceback.print_exc()
            notes.append(f"the pooled grid failed ({exc!r}); scripts computed what they could on their own")
        sections = run_scripts(context, modules, failures)
        for name, message in failures:
            notes.append(f"{name}: FAILED ({message})")
        path = report.write_report(context, sections, notes, time.perf_counter() - start, counts)
    finally:
        if client is not None:
            client.close()
    print(closing_line(path.parent, written_since(path.parent, started_at), path.name, time.perf_counter() - start,
                       failures), file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
