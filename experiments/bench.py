"""Kernel and tracker timings: ``make bench`` = ``python -m experiments.bench [--data DIR]``.

Prints a markdown report and saves it as ``figures/bench.md``, with every
number in ``figures/bench.json``:

* per kernel -- warp, distances + k nearest, coding (regularized, constrained,
  plain), weights and confidence (``combine_dictionaries``) -- and per whole
  tracker frame (``NRMLCTracker.step``), at N = 100, 300, 600, 1200 particles,
  each with its ratio to a plain numpy reference of the same computation
  measured in the same run;
* end to end: tracker fps on the synthetic default sequence (and on
  ``<data>/Car4`` when ``--data`` is given), frame decoding excluded and
  included, and OpenCV's TrackerMIL on the same frames;
* thread set-ups: the tracker's fps and CPU time per frame with numba and
  BLAS at 1 or all threads, OpenMP spin-waiting or not, each in a fresh
  subprocess (the evidence for the thread policy);
* start-up: numba compile time cold (empty cache) and warm (on-disk cache),
  each in a fresh subprocess;
* the machine: CPU, threads, library versions, load average.

References (what "plain numpy" means, column ``reference`` of the table):

* warp: ``nrmlc.testing.reference.warp_patches_reference``, the test oracle (a
  loop over particles, each vectorised in float64 numpy);
* distances + KNN: ``nrmlc.testing.reference.reference_dots`` (the oracle, float64
  ``einsum``), the ``|y|^2 + |t|^2 - 2 y.t`` expansion and a stable argsort.
  A second row, ``distances+knn (numpy BLAS)``, uses the same sgemm as the
  kernel (``Y @ T.T``) with ``np.argpartition`` + sort: the fair comparison for
  the selection part, since the product itself is BLAS either way;
* coding / weights: ``nrmlc.testing.reference.reference_encode`` and
  ``reference_combine``, the oracles (a loop over candidates solving each small
  problem with ``np.linalg``; SLSQP for the constrained QP). They cost the same
  for every candidate, so they are timed on a subset of candidates and scaled
  linearly to N (the column ``reference on`` says how many);
* tracker frame: no separate reference; its ``reference`` is the sum of the
  kernel references at that N (an estimate, marked as such).

Threads: the bench applies :func:`nrmlc.config.set_threads` (default: all
cores); ``--blas-threads`` overrides the BLAS count it sets, to compare
policies. See the README's Performance section.

Timings are medians over repeats after a warm-up call. The machine may be
shared: the load average before and after the run is recorded, and wall and
process-CPU medians are both kept in the JSON.
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parent.parent

#: Particle counts of the cost-vs-N table.
PARTICLE_COUNTS = (100, 300, 600, 1200)
#: Candidates the per-candidate references are timed on (then scaled to N).
REFERENCE_SUBSET = {"regularized": 120, "plain": 60, "constrained": 12}
MODES = ("regularized", "constrained", "plain")


# ---------------------------------------------------------------------------
# timing
# ---------------------------------------------------------------------------

def measure(function, repeats: int, warmup: int = 1) -> dict:
    """Median / min wall time and median process-CPU time of ``function()``, in ms."""
    for _ in range(warmup):
        function()
    walls, cpus = [], []
    for _ in range(repeats):
        cpu = time.process_time()
        wall = time.perf_counter()
        function()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return {"ms": 1e3 * float(np.median(walls)), "min_ms": 1e3 * float(np.min(walls)),
            "cpu_ms": 1e3 * float(np.median(cpus)), "repeats": repeats}


def _load_average() -> list | None:
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except OSError:  # pragma: no cover - not on Linux
        return None


# ---------------------------------------------------------------------------
# machine
# ---------------------------------------------------------------------------

def machine_info(n_threads: int) -> dict:
    import cv2
    import llvmlite
    import numba
    import scipy
    from threadpoolctl import threadpool_info

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:  # pragma: no cover
        pass
    blas = [{k: d.get(k) for k in ("internal_api", "version", "num_threads", "threading_layer", "architecture")}
            for d in threadpool_info() if d.get("user_api") == "blas"]
    try:
        layer = numba.threading_layer()
    except ValueError:  # no parallel kernel has run yet
        layer = None
    return {
        "cpu": cpu, "logical_cores": os.cpu_count(), "threads": n_threads,
        "numba_threads": numba.get_num_threads(), "numba_threading_layer": layer,
        "blas": blas, "opencv_threads": cv2.getNumThreads(),
        "python": platform.python_version(), "numpy": np.__version__, "numba": numba.__version__,
        "llvmlite": llvmlite.__version__, "scipy": scipy.__version__, "opencv": cv2.__version__,
        "platform": platform.platform(),
    }


# ---------------------------------------------------------------------------
# kernels
# ---------------------------------------------------------------------------

def _warmed_tracker(sequence, n_frames: int):
    """A tracker run over the first frames, so its templates include updates."""
    from nrmlc.tracker.nrmlc_tracker import NRMLCTracker

    tracker = NRMLCTracker(seed=0)
    frames = [sequence.frame(i) for i in range(n_frames + 1)]
    tracker.init(frames[0], sequence.init_box)
    for frame in frames[1:n_frames]:
        tracker.update(frame)
    return tracker, frames[n_frames]


def _numpy_blas_knn(candidates, templates, template_sq_norms, k):
    """Distances + k nearest in plain numpy with the kernel's own sgemm."""
    dots = (candidates @ templates.T).astype(np.float64)
    sq_norms = np.einsum("ij,ij->i", candidates, candidates, dtype=np.float64)
    distances = np.maximum(sq_norms[:, None] + template_sq_norms[None, :] - 2.0 * dots, 0.0)
    part = np.argpartition(distances, k - 1, axis=1)[:, :k]
    order = np.take_along_axis(distances, part, axis=1).argsort(axis=1, kind="stable")
    return np.take_along_axis(part, order, axis=1)


def bench_kernels(sequence, counts, repeats: int, reference_repeats: int, warm_frames: int,
                  reference_subset: dict) -> list[dict]:
    """One row per (kernel, N): kernel time, reference time, ratio."""
    from nrmlc.geometry import state_to_affine
    from nrmlc.kernels.coding import combine_dictionaries, encode_dictionaries
    from nrmlc.kernels.distance import candidate_template_dots, nearest_templates, squared_norms
    from nrmlc.kernels.warp import warp_patches
    from nrmlc.testing.reference import (
        reference_combine,
        reference_dots,
        reference_encode,
        reference_nearest,
        warp_patches_reference,
    )

    base, frame = _warmed_tracker(sequence, warm_frames)
    params = base.params
    sizes = np.asarray(params.dictionary_sizes, dtype=np.int64)
    k_max = params.k_max
    templates = base.templates
    gram = base.template_gram
    t_norms = base.template_sq_norms
    n_positive = len(base.positive_templates)
    rows = []

    def add(kernel, n, timing, reference=None, reference_name="", subset=None):
        row = {"kernel": kernel, "n_particles": n, "n_templates": len(templates), **timing}
        if reference is not None:
            scale = n / subset if subset else 1.0
            row.update(reference=reference_name, reference_ms=reference["ms"] * scale,
                       reference_on=subset or n, speedup=reference["ms"] * scale / timing["ms"])
        rows.append(row)
        print(f"  {kernel:28s} N={n:5d} {timing['ms']:9.3f} ms"
              + (f"   reference {row['reference_ms']:10.1f} ms  x{row['speedup']:.0f}" if reference else ""),
              flush=True)
        return row

    for n in counts:
        tracker = copy.deepcopy(base)
        tracker.params = params.replace(n_particles=n)
        states = tracker.sample_particles()
        affines = np.ascontiguousarray(state_to_affine(states))
        candidates = warp_patches(frame, affines)
        frame_reference = 0.0

        row = add("warp", n, measure(lambda: warp_patches(frame, affines), repeats),
                  measure(lambda: warp_patches_reference(frame, affines), reference_repeats, 0),
                  "nrmlc/testing/reference.py (oracle)")
        frame_reference += row["reference_ms"]

        def knn():
            dots = candidate_template_dots(candidates, templates)
            return nearest_templates(dots, squared_norms(candidates), t_norms, k_max)

        def knn_reference():
            dots = reference_dots(candidates, templates)
            sq = np.einsum("ij,ij->i", candidates, candidates, dtype=np.float64)
            return reference_nearest(sq[:, None] + t_norms[None, :] - 2.0 * dots, k_max)

        timing = measure(knn, repeats)
        row = add("distances+knn", n, timing, measure(knn_reference, reference_repeats, 0),
                  "nrmlc/testing/reference.py einsum + stable argsort (oracle)")
        frame_reference += row["reference_ms"]
        add("distances+knn (numpy BLAS)", n, timing,
            measure(lambda: _numpy_blas_knn(candidates, templates, t_norms, k_max), reference_repeats, 0),
            "numpy sgemm + argpartition")

        dots = candidate_template_dots(candidates, templates)
        sq_norms = squared_norms(candidates)
        neighbours, _ = nearest_templates(dots, sq_norms, t_norms, k_max)
        for mode in MODES:
            ridge_c, ridge_w = params.replace(coding=mode).ridges
            constrained = mode == "constrained"
            subset = min(n, reference_subset[mode])

            def encode(ridge_c=ridge_c, constrained=constrained):
                return encode_dictionaries(gram, dots, sq_norms, neighbours, sizes, ridge_c, constrained)

            coefficients = encode()
            row = add(f"coding {mode}", n, measure(encode, repeats),
                      measure(lambda: reference_encode(candidates[:subset], templates, neighbours[:subset], sizes,
                                                       ridge_c, constrained), reference_repeats, 0),
                      "nrmlc/testing/reference.py reference_encode (oracle)", subset)
            if mode == params.coding:
                frame_reference += row["reference_ms"]

            def combine(ridge_w=ridge_w, constrained=constrained, coefficients=coefficients):
                return combine_dictionaries(gram, dots, sq_norms, neighbours, coefficients, sizes, n_positive,
                                            ridge_w, constrained, params.n_iterations)

            row = add(f"weights+confidence {mode}", n, measure(combine, repeats),
                      measure(lambda: reference_combine(candidates[:subset], templates, neighbours[:subset],
                                                        coefficients[:subset], sizes, n_positive, ridge_w,
                                                        constrained, params.n_iterations), reference_repeats, 0),
                      "nrmlc/testing/reference.py reference_combine (oracle)", subset)
            if mode == params.coding:
                frame_reference += row["reference_ms"]

        for mode in MODES:
            if mode != params.coding and n != 600:
                continue
            stepper = copy.deepcopy(tracker)
            stepper.params = tracker.params.replace(coding=mode)
            timing = measure(lambda: stepper.step(frame), repeats)
            row = add(f"tracker frame {mode}", n, timing)
            if mode == params.coding:
                row.update(reference="sum of the kernel references (estimate)", reference_ms=frame_reference,
                           reference_on=n, speedup=frame_reference / timing["ms"])
    return rows


# ---------------------------------------------------------------------------
# end to end
# ---------------------------------------------------------------------------

def _mil_fps(sequence, n_frames: int) -> dict:
    """OpenCV TrackerMIL on the same frames, decoding excluded (frames preloaded)."""
    import cv2

    frames = [sequence.color_frame(i) for i in range(n_frames)]
    x, y, w, h = (float(v) for v in sequence.init_box)
    box = (int(round(x - 1)), int(round(y - 1)), max(1, int(round(w))), max(1, int(round(h))))
    tracker = cv2.TrackerMIL.create()
    start = time.perf_counter()
    tracker.init(frames[0], box)
    for frame in frames[1:]:
        tracker.update(frame)
    seconds = time.perf_counter() - start
    return {"tracker": "OpenCV TrackerMIL", "frames": n_frames, "fps_tracking": (n_frames - 1) / seconds}


def bench_end_to_end(sequence, n_frames: int | None, repeats: int) -> list[dict]:
    from nrmlc.tracker.params import TrackerParams
    from nrmlc.tracker.run import track_sequence

    total = len(sequence) if n_frames is None else min(n_frames, len(sequence))
    track_sequence(sequence, TrackerParams(), seed=0, n_frames=min(total, 8))  # warm-up (compilation)
    rows = []
    for mode in MODES:
        runs = [track_sequence(sequence, TrackerParams(coding=mode), seed=0, n_frames=total)
                for _ in range(repeats if mode == "regularized" else 1)]
        tracking = float(np.median([r.fps_tracking for r in runs]))
        overall = float(np.median([r.fps_total for r in runs]))
        rows.append({"sequence": sequence.name, "tracker": f"NRMLC {mode}", "frames": total, "runs": len(runs),
                     "fps_tracking": tracking, "fps_total": overall})
        print(f"  {sequence.name}: NRMLC {mode:12s} {tracking:7.1f} fps (decoding excluded), "
              f"{overall:7.1f} fps (included)", flush=True)
    mil = _mil_fps(sequence, total)
    mil["sequence"] = sequence.name
    rows.append(mil)
    print(f"  {sequence.name}: OpenCV TrackerMIL  {mil['fps_tracking']:7.1f} fps (decoding excluded)", flush=True)
    return rows


# ---------------------------------------------------------------------------
# start-up
# ---------------------------------------------------------------------------

_STARTUP_CHILD = r"""
import json, sys, time
start = time.perf_counter()
import numpy as np
from nrmlc.config import set_threads
from nrmlc.tracker.nrmlc_tracker import NRMLCTracker
imported = time.perf_counter()
set_threads(int(sys.argv[1]))
rng = np.random.default_rng(0)
frame = rng.random((120, 160)).astype(np.float32)
tracker = NRMLCTracker(seed=0)
tracker.init(frame, (40.0, 30.0, 40.0, 32.0))
tracker.update(frame)
done = time.perf_counter()
print(json.dumps({"import_s": imported - start, "first_frame_s": done - imported, "total_s": done - start}))
"""


def _startup_run(cache_dir: str, n_threads: int) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    wall = time.perf_counter()
    output = subprocess.run([sys.executable, "-c", _STARTUP_CHILD, str(n_threads)], env=env, cwd=str(REPO_ROOT),
                            capture_output=True, text=True, check=True)
    result = json.loads(output.stdout.strip().splitlines()[-1])
    result["process_s"] = time.perf_counter() - wall
    return result


def bench_startup(n_threads: int, warm_repeats: int = 2) -> dict:
    """Import + first tracked frame in fresh processes: empty cache, then the cache it wrote."""
    with tempfile.TemporaryDirectory(prefix="nrmlc-numba-cache-") as cache_dir:
        cold = _startup_run(cache_dir, n_threads)
        warm = [_startup_run(cache_dir, n_threads) for _ in range(warm_repeats)]
    best = min(warm, key=lambda r: r["total_s"])
    print(f"  cold (empty numba cache): {cold['total_s']:.2f} s (import {cold['import_s']:.2f} s); "
          f"warm (on-disk cache): {best['total_s']:.2f} s (import {best['import_s']:.2f} s)", flush=True)
    return {"cold": cold, "warm": warm, "warm_best": best,
            "what": "fresh python process: import nrmlc + tracker.init + one update (600 particles), "
                    "NUMBA_CACHE_DIR = an empty temp dir (cold), then the same dir (warm)"}


# ---------------------------------------------------------------------------
# thread policy
# ---------------------------------------------------------------------------

_THREADS_CHILD = r"""
import json, sys, time
from nrmlc.config import set_threads
from threadpoolctl import threadpool_limits
import numba
n_numba, n_blas, n_frames = (int(v) for v in sys.argv[1:4])
set_threads(n_numba)
threadpool_limits(limits=n_blas, user_api="blas")
from nrmlc.data import synthetic_suite
from nrmlc.tracker.run import track_sequence
sequence = synthetic_suite(n_frames=n_frames)[0]
track_sequence(sequence, n_frames=6)
cpu = time.process_time()
result = track_sequence(sequence, n_frames=n_frames)
print(json.dumps({"fps": result.fps_tracking, "cpu_ms_per_frame": 1e3 * (time.process_time() - cpu) / (n_frames - 1),
                  "numba_layer": numba.threading_layer()}))
"""


def thread_configurations(n_threads: int) -> dict:
    """name -> (extra environment, numba threads, BLAS threads)."""
    n = n_threads
    return {
        "serial (numba 1, BLAS 1)": ({}, 1, 1),
        f"numba {n} spin-wait + BLAS {n} (libgomp default)": ({"GOMP_SPINCOUNT": "300000"}, n, n),
        f"numba {n} + BLAS {n}": ({}, n, n),
        f"numba {n} + BLAS 1": ({}, n, 1),
    }


def bench_threads(n_threads: int, rounds: int = 2, n_frames: int = 60) -> list[dict]:
    """Tracker fps and CPU per frame under several thread set-ups, each in a fresh process.

    The set-ups run interleaved, ``rounds`` times, so that a change of machine
    load hits them all alike; the median is reported.
    """
    configurations = thread_configurations(n_threads)
    samples = {name: [] for name in configurations}
    for _ in range(rounds):
        for name, (extra_env, n_numba, n_blas) in configurations.items():
            env = dict(os.environ, **extra_env)
            output = subprocess.run([sys.executable, "-c", _THREADS_CHILD, str(n_numba), str(n_blas), str(n_frames)],
                                    env=env, cwd=str(REPO_ROOT), capture_output=True, text=True, check=True)
            samples[name].append(json.loads(output.stdout.strip().splitlines()[-1]))
    rows = []
    for name, runs in samples.items():
        row = {"setup": name, "runs": len(runs), "frames": n_frames,
               "fps": float(np.median([r["fps"] for r in runs])),
               "cpu_ms_per_frame": float(np.median([r["cpu_ms_per_frame"] for r in runs])),
               "fps_all": [round(r["fps"], 1) for r in runs]}
        rows.append(row)
        print(f"  {name:48s} {row['fps']:7.1f} fps  {row['cpu_ms_per_frame']:6.1f} ms CPU/frame  "
              f"(runs: {row['fps_all']})", flush=True)
    return rows


# ---------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------

def _markdown(result: dict) -> str:
    m = result["machine"]
    lines = ["# NRMLC timings", "",
             f"Machine: {m['cpu']}, {m['logical_cores']} logical cores; threads used: numba {m['numba_threads']} "
             f"({m['numba_threading_layer']}), BLAS {', '.join(str(b['num_threads']) for b in m['blas'])}, "
             f"OpenCV {m['opencv_threads']}. numpy {m['numpy']}, numba {m['numba']}, OpenCV {m['opencv']}, "
             f"Python {m['python']}.",
             f"Load average before / after: {result['load_before']} / {result['load_after']} "
             "(other processes share the machine when it is above 0; medians are over repeats after a warm-up).",
             "", "## Kernels vs particles", "",
             "| kernel | N | ms (median) | reference ms | speed-up | reference |",
             "|---|---:|---:|---:|---:|---|"]
    for row in result["kernels"]:
        reference = f"{row['reference_ms']:.1f}" if "reference_ms" in row else ""
        speedup = f"{row['speedup']:.0f}x" if "speedup" in row else ""
        what = row.get("reference", "")
        if row.get("reference_on", row["n_particles"]) != row["n_particles"]:
            what += f", timed on {row['reference_on']} candidates, scaled"
        lines.append(f"| {row['kernel']} | {row['n_particles']} | {row['ms']:.3f} | {reference} | {speedup} | {what} |")
    lines += ["", "## End to end", "",
              "| sequence | tracker | frames | fps (decoding excluded) | fps (decoding included) |",
              "|---|---|---:|---:|---:|"]
    for row in result["end_to_end"]:
        total = f"{row['fps_total']:.1f}" if "fps_total" in row else "n/a (frames preloaded)"
        lines.append(f"| {row['sequence']} | {row['tracker']} | {row['frames']} | {row['fps_tracking']:.1f} | {total} |")
    if result.get("threads"):
        lines += ["", "## Thread set-ups (synthetic sequence, fresh process each, median of runs)", "",
                  "| set-up | fps | CPU ms / frame | runs (fps) |", "|---|---:|---:|---|"]
        for row in result["threads"]:
            lines.append(f"| {row['setup']} | {row['fps']:.1f} | {row['cpu_ms_per_frame']:.1f} | {row['fps_all']} |")
    summary = result.get("summary", {})
    if summary:
        lines += ["", "## Summary", ""]
        lines += [f"- {key}: {value}" for key, value in summary.items()]
    if result.get("startup"):
        s = result["startup"]
        lines += ["", "## Start-up", "",
                  f"- cold (empty numba cache): {s['cold']['total_s']:.2f} s "
                  f"(import {s['cold']['import_s']:.2f} s, first frame incl. compilation {s['cold']['first_frame_s']:.2f} s)",
                  f"- warm (on-disk cache): {s['warm_best']['total_s']:.2f} s "
                  f"(import {s['warm_best']['import_s']:.2f} s, first frame {s['warm_best']['first_frame_s']:.2f} s)",
                  f"- measured as: {s['what']}"]
    lines += ["", f"Bench wall time: {result['bench_seconds']:.0f} s.", ""]
    return "\n".join(lines)


def _summary(result: dict) -> dict:
    summary = {}
    by_name = {}
    for row in result["end_to_end"]:
        by_name[(row["sequence"], row["tracker"])] = row
    for (sequence, tracker), row in by_name.items():
        if tracker != "NRMLC regularized":
            continue
        mil = by_name.get((sequence, "OpenCV TrackerMIL"))
        constrained = by_name.get((sequence, "NRMLC constrained"))
        summary[f"{sequence}: regularized fps"] = f"{row['fps_tracking']:.1f}"
        if mil:
            summary[f"{sequence}: regularized / TrackerMIL fps"] = f"{row['fps_tracking'] / mil['fps_tracking']:.2f}x"
        if constrained:
            summary[f"{sequence}: constrained slower than regularized by"] = (
                f"{row['fps_tracking'] / constrained['fps_tracking']:.2f}x")
    speedups = [r for r in result["kernels"]
                if "speedup" in r and r["n_particles"] == 600 and "numpy BLAS" not in r["kernel"]]
    if speedups:
        speedup, kernel = min((r["speedup"], r["kernel"]) for r in speedups)
        summary["smallest kernel speed-up vs its test-oracle reference at N=600"] = f"{speedup:.0f}x ({kernel})"
    return summary


def run(data: Path | None, out_dir: Path, n_threads: int | None, counts=PARTICLE_COUNTS, repeats: int = 15,
        reference_repeats: int = 2, synthetic_frames: int = 120, real_frames: int | None = 300,
        e2e_repeats: int = 3, startup: bool = True, reference_subset: dict | None = None,
        thread_study: bool = True, blas_threads: int | None = None) -> dict:
    from nrmlc.config import set_threads
    from nrmlc.data import open_sequence, synthetic_suite

    began = time.perf_counter()
    threads = set_threads(n_threads)
    if blas_threads is not None:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=blas_threads, user_api="blas")
    result = {"load_before": _load_average()}
    synthetic = synthetic_suite(n_frames=synthetic_frames)[0]
    print(f"kernels ({synthetic.name}, {threads} threads):", flush=True)
    result["kernels"] = bench_kernels(synthetic, counts, repeats, reference_repeats,
                                      warm_frames=min(25, synthetic_frames - 1),
                                      reference_subset=reference_subset or REFERENCE_SUBSET)
    print("end to end:", flush=True)
    result["end_to_end"] = bench_end_to_end(synthetic, None, e2e_repeats)
    if data is not None:
        car4 = Path(data) / "Car4"
        if car4.is_dir():
            result["end_to_end"] += bench_end_to_end(open_sequence(car4), real_frames, 1)
        else:
            print(f"  (no Car4 under {data}; skipped)", flush=True)
    result["threads"] = None
    if thread_study:
        print("thread set-ups:", flush=True)
        result["threads"] = bench_threads(threads)
    result["startup"] = None
    if startup:
        print("start-up:", flush=True)
        result["startup"] = bench_startup(threads)
    result["machine"] = machine_info(threads)
    result["load_after"] = _load_average()
    result["summary"] = _summary(result)
    result["bench_seconds"] = time.perf_counter() - began
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "bench.json").write_text(json.dumps(result, indent=1, default=str))
    markdown = _markdown(result)
    (out_dir / "bench.md").write_text(markdown)
    print(markdown)
    return result


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", type=Path, default=None, help="folder of real sequences (uses <data>/Car4)")
    parser.add_argument("--out", type=Path, default=REPO_ROOT / "figures", help="where bench.json/bench.md go")
    parser.add_argument("--threads", type=int, default=None, help="threads for numba, BLAS and OpenCV (default: all cores)")
    parser.add_argument("--blas-threads", type=int, default=None,
                        help="override the BLAS thread count set by set_threads (to compare policies)")
    parser.add_argument("--quick", action="store_true",
                        help="tiny settings (for tests): N=50, few repeats, no start-up or thread study")
    args = parser.parse_args(argv)
    if args.quick:
        return run(args.data, args.out, args.threads, counts=(50,), repeats=2, reference_repeats=1,
                   synthetic_frames=12, real_frames=12, e2e_repeats=1, startup=False,
                   reference_subset={"regularized": 10, "plain": 10, "constrained": 4}, thread_study=False,
                   blas_threads=args.blas_threads)
    return run(args.data, args.out, args.threads, blas_threads=args.blas_threads)


if __name__ == "__main__":
    main()
