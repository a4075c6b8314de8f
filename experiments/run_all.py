"""``make figures``: every figure and table of the paper, and ``figures/REPORT.md``.

Usage::

    python -m experiments.run_all [--data DIR] [--seeds N] [--sweep-seeds N] [--jobs J]
                                  [--dask SCHEDULER_ADDRESS] [--only a,b] [--max-frames N]

Steps:

1. build the :class:`~experiments.common.Context` (data, seeds, run cache);
2. collect the RunSpecs of every script (``runs(context)``) and its live
   OpenCV peer runs (``peer_runs(context)``), print the size of the grid,
   and run the union in one pool of warmed-up workers (cached runs are
   skipped, so a rerun or an interrupted run costs only what is missing);
3. call each script's ``main(context)`` in the paper's order (they read the
   cached results); a script that is not there is skipped with a note, one
   that fails is reported (traceback on stderr, a note in the report) and
   the others still run;
4. write ``figures/REPORT.md``; exit non-zero if any script failed.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import importlib
import os
import sys
import time
import traceback

from experiments import peers, report
from experiments.common import add_arguments, context_from_namespace, spec_frames
from nrmlc.errors import NrmlcError

#: Every script, in the paper's order: (module, whether it is ours to require).
#: The analysis scripts (theorem, Fig. 1/2, statistics, occlusion) are written
#: separately; when one is missing the report says so and the rest go on.
SCRIPTS = (
    ("experiments.theorem1_checks", False),
    ("experiments.fig1_coefficients", False),
    ("experiments.fig2_mean_gray", False),
    ("experiments.stats_nonnegativity", False),
    ("experiments.table1_table2_accuracy", True),
    ("experiments.fig3_qualitative", True),
    ("experiments.fig4_lambda_sweep", True),
    ("experiments.fig_occlusion", False),
    ("experiments.ablations", True),
    ("experiments.ablation_per_sequence_motion", True),
    ("experiments.ablation_oracle_recentring", True),
    ("experiments.ablation_synthetic_dev", True),
)

#: Rough tracking speed for the time estimate (frames per second per worker).
ESTIMATE_FPS_PER_WORKER = 80.0  # measured: ~85 fps per single-threaded worker (figures/bench.md)
#: Rough speed of OpenCV's MIL (frames per second per worker).
ESTIMATE_PEER_FPS = 15.0


def _short(module: str) -> str:
    return module.rsplit(".", 1)[-1]


def import_scripts(selected, notes: list, failures: list) -> list:
    """Import the selected scripts; missing ones become notes, broken ones failures."""
    modules = []
    for name, required in SCRIPTS:
        if selected is not None and _short(name) not in selected:
            continue
        try:
            modules.append(importlib.import_module(name))
        except ImportError as exc:
            if isinstance(exc, ModuleNotFoundError) and exc.name == name and not required:
                notes.append(f"{_short(name)}: not available (module {name} not found), skipped")
                print(f"[run_all] {_short(name)}: not available, skipped", file=sys.stderr)
            else:
                traceback.print_exc()
                failures.append((_short(name), f"import failed: {exc!r}"))
        except Exception as exc:  # a script that crashes on import is a failure, not a reason to stop
            traceback.print_exc()
            failures.append((_short(name), f"import failed: {exc!r}"))
    return modules


def collect_specs(context, modules, failures: list) -> tuple[dict, list]:
    """{script: its RunSpecs} for every script that has ``runs``, and the union of their ``peer_runs``."""
    specs, peer_specs = {}, {}
    for module in modules:
        try:
            if hasattr(module, "runs"):
                specs[_short(module.__name__)] = list(module.runs(context))
            if hasattr(module, "peer_runs"):
                peer_specs.update((spec.key(), spec) for spec in module.peer_runs(context))
        except Exception as exc:
            traceback.print_exc()
            failures.append((_short(module.__name__), f"runs() failed: {exc!r}"))
    return specs, sorted(peer_specs.values(), key=lambda s: -s.frames())


def grid_summary(context, specs_by_script: dict, peer_specs: list) -> tuple[list, dict, str]:
    """The union of the runs (unique, longest first), counts, and a printable summary."""
    version = context.cache.version
    unique = {}
    lines = []
    for script, specs in specs_by_script.items():
        keys = {s.key(version): s for s in specs}
        lines.append(f"  {script}: {len(keys)} runs, {sum(spec_frames(s) for s in keys.values())} frames")
        unique.update(keys)
    union = sorted(unique.values(), key=lambda s: -spec_frames(s))
    missing = [s for s in union if not context.cache.has(s)]
    frames = sum(spec_frames(s) for s in union)
    missing_frames = sum(spec_frames(s) for s in missing)
    peer_cache = peers.cache_for(context)
    peer_missing = [s for s in peer_specs if not peer_cache.has(s)]
    peer_frames = sum(s.frames() for s in peer_specs)
    peer_missing_frames = sum(s.frames() for s in peer_missing)
    workers = context.jobs or os.cpu_count() or 1
    estimate = (missing_frames / ESTIMATE_FPS_PER_WORKER + peer_missing_frames / ESTIMATE_PEER_FPS) / workers / 60
    text = "\n".join([f"[run_all] grid: {len(union)} NRMLC runs, {frames} frames ({frames - missing_frames} cached, "
                      f"{missing_frames} to compute); {len(peer_specs)} OpenCV runs, {peer_frames} frames "
                      f"({peer_missing_frames} to compute); shared runs counted once. Estimate: "
                      f"~{estimate:.0f} min on {workers} worker(s) at ~{ESTIMATE_FPS_PER_WORKER:.0f} fps each"]
                     + lines)
    counts = {"runs": len(union), "frames": frames, "missing_frames": missing_frames,
              "peer_runs": len(peer_specs), "peer_frames": peer_frames}
    return missing, counts, text


def warm_up() -> None:
    """Load (or compile) the tracker's numba kernels before any timed run.

    A process's first tracking run pays for loading the compiled kernels inside
    its timed ``init``/``update``; on short sequences that halves its fps. So
    every worker tracks a few synthetic frames with each coder first.
    """
    from nrmlc.data import SyntheticSequence, SyntheticSpec
    from nrmlc.tracker.params import TrackerParams
    from nrmlc.tracker.run import track_sequence

    sequence = SyntheticSequence(SyntheticSpec(name="warm-up", seed=0, n_frames=7))
    for coding in ("regularized", "constrained"):
        # 7 frames: past the first template update (every 5 frames), so its kernels load too.
        track_sequence(sequence, TrackerParams(n_particles=20, coding=coding), n_frames=7)


def _warm_worker() -> None:
    from nrmlc.config import set_threads

    set_threads(1)
    warm_up()


def run_grid(context, missing: list, peer_specs: list) -> None:
    """Compute the missing NRMLC runs and the live OpenCV runs in one pool of warmed-up workers."""
    executor, own = context.executor, False
    jobs = context.jobs or os.cpu_count() or 1
    if executor is None and jobs > 1 and (missing or peer_specs):
        executor = concurrent.futures.ProcessPoolExecutor(max_workers=jobs, initializer=_warm_worker)
        own = True
    elif executor is None and missing:
        from nrmlc.config import set_threads

        set_threads(1)
        warm_up()
    try:
        if missing:
            context.cache.run(missing, executor=executor, jobs=context.jobs)  # longest runs first
        if peer_specs:
            peers.cache_for(context).run(peer_specs, executor=executor, jobs=context.jobs)
    finally:
        if own:
            executor.shutdown(wait=True, cancel_futures=True)


def run_scripts(context, modules, failures: list) -> list[dict]:
    """Call every script's ``main(context)``; a failure becomes a section saying so."""
    sections = []
    for module in modules:
        name = _short(module.__name__)
        start = time.perf_counter()
        print(f"[run_all] {name} ...", file=sys.stderr, flush=True)
        try:
            section = module.main(context)
            if not isinstance(section, dict) or "title" not in section:
                raise TypeError(f"main() returned {type(section).__name__}, not a dict with a title")
            section = {"title": section["title"], "figures": list(section.get("figures", [])),
                       "markdown": section.get("markdown", "")}
        except Exception as exc:
            traceback.print_exc()
            failures.append((name, repr(exc)))
            section = {"title": f"{name}: FAILED", "figures": [],
                       "markdown": f"`{name}.main` raised `{exc!r}`; see the log for the traceback."}
        print(f"[run_all] {name} done in {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)
        sections.append(section)
    return sections


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m experiments.run_all",
                                     description="Run every experiment and write figures/REPORT.md.")
    add_arguments(parser)
    parser.add_argument("--dask", default=None, metavar="SCHEDULER_ADDRESS",
                        help="run the grid on a Dask distributed cluster (needs the 'distributed' package)")
    parser.add_argument("--only", default=None, metavar="SCRIPT[,SCRIPT]",
                        help="run only these scripts (short names, e.g. fig4_lambda_sweep,ablations)")
    parser.add_argument("--dry-run", action="store_true",
                        help="print the size of the grid (frames to track, estimated time) and stop")
    return parser


def main(argv=None) -> int:
    """Run everything; return the exit status (0, or 1 if any script failed)."""
    start = time.perf_counter()
    parser = build_parser()
    args = parser.parse_args(argv)
    selected = None if args.only is None else {s.strip() for s in args.only.split(",") if s.strip()}
    if selected is not None:
        unknown = selected - {_short(n) for n, _ in SCRIPTS}
        if unknown:
            parser.error(f"--only: unknown script(s) {', '.join(sorted(unknown))}; "
                         f"choose from {', '.join(_short(n) for n, _ in SCRIPTS)}")
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
                         "(pip install distributed); without --dask the grid runs in a local process pool")
        client = Client(args.dask)
        context.executor = client.get_executor()

    notes: list[str] = []
    failures: list[tuple[str, str]] = []
    try:
        print(f"[run_all] data: {context.data_label}; {len(context.sequences())} sequences; "
              f"{context.describe_grid()}", file=sys.stderr)
        modules = import_scripts(selected, notes, failures)
        specs, peer_specs = collect_specs(context, modules, failures)
        missing, counts, summary = grid_summary(context, specs, peer_specs)
        print(summary, file=sys.stderr, flush=True)
        if args.dry_run:
            return 1 if failures else 0
        try:
            run_grid(context, missing, peer_specs)
        except Exception as exc:
            # The scripts will retry what is missing and fail one by one; say where it started.
            traceback.print_exc()
            notes.append(f"the pooled grid failed ({exc!r}); scripts computed what they could on their own")
        sections = run_scripts(context, modules, failures)
        for name, message in failures:
            notes.append(f"{name}: FAILED ({message})")
        path = report.write_report(context, sections, notes, time.perf_counter() - start, counts)
        print(f"[run_all] wrote {path}", file=sys.stderr)
    finally:
        if client is not None:
            client.close()
    if failures:
        print(f"[run_all] {len(failures)} script(s) failed: {', '.join(n for n, _ in failures)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
