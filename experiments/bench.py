"""Timings: ``make bench`` = ``python -m experiments.bench [--data DIR] [--out DIR]``.

Writes ``bench.md`` (printed too) and ``bench.json`` (every number) to
``out/figures/`` (git-ignored) unless ``--out`` says otherwise: ``--out figures``
(``make bench OUT=figures``) replaces the committed report. Sections:

* **Stages of a frame** at 100, 600 and 1200 particles (Car4 when ``--data`` is
  given, else the synthetic sequence): the time each stage takes inside real
  ``update`` calls (warp, product, norms, nearest templates, coding, weights and
  confidence, the generative term's local coding, template updates, and the Python
  and numpy between them) against
  its *floor*, the same call on the same inputs timed alone (median after a
  warm-up). A stage well above its floor loses time to its neighbours (caches,
  waking threads); the row "between the kernels" has no floor.
* **Kernels against their numpy references** (``nrmlc.testing.reference``, the
  test oracles; for distances also a numpy version with the same sgemm, the fair
  comparison for the selection part). Per-candidate references cost the same for
  every candidate, so they are timed on a subset and scaled (column "reference on").
* **End to end**: the tracker (every coding mode, and the generative term flipped) and OpenCV's TrackerMIL on the
  same frames, decoding excluded, in this process, in alternating rounds so
  that a change of machine load hits both alike; ratios in words.
* **Thread set-ups**, each in a fresh process: the API as a user runs it (nothing
  called), ``set_threads()`` before or after importing the tracker (the CLI's
  order), one thread, and numba's pool spin-waiting
  (libgomp's default, which ``nrmlc`` turns off; see
  :func:`nrmlc.config.set_threads`).
* **Grid throughput**: a small grid through the run cache in one process (one
  thread) and in the local process pool (one single-threaded worker per core), as
  ``make figures`` runs it, and on a Dask cluster with ``--dask ADDRESS``.
* **Start-up** (fresh processes: empty numba cache, then warm) and the machine.

The bench times exactly the configuration the API and the CLI use: it calls
nothing that changes threads unless ``--threads`` is given. The machine may be
shared: before each measured section it waits (up to ``--wait-quiet`` seconds)
for an idle machine, and it records the waits, the idle share, the load average
and the parallel speed-up at hand; compare ratios measured in one run, not
numbers across runs.
"""
from __future__ import annotations

import argparse
import copy
import functools
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parent.parent
#: Default output folder (git-ignored); ``--out figures`` writes the committed report.
DEFAULT_OUT = REPO_ROOT / "out" / "figures"

#: Particle counts of the stage and kernel tables.
PARTICLE_COUNTS = (100, 600, 1200)
#: Candidates the per-candidate references are timed on (then scaled to N).
REFERENCE_SUBSET = {"regularized": 120, "plain": 60, "constrained": 12}
MODES = ("regularized", "constrained", "plain")
#: Switches whose cost the end-to-end bench measures by flipping them (bench_end_to_end).
FLIPPED_SWITCHES = ("generative_weight", "second_expert", "partner_eyes")
#: The end-to-end row of the default's second expert run alone (its :meth:`partner_params`).
PARTNER_ALONE = "NRMLC partner alone"
#: Frames of Car4 for the end-to-end and thread rows; the project's speed target there.
REAL_FRAMES = 300
TARGET_FPS = 150.0
TARGET_MIL_RATIO = 6.0


# ---------------------------------------------------------------------------
# timing and words
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


def compare(name: str, fps: float, other: str, other_fps: float) -> str:
    """``"<name> is 1.31x slower than <other>"`` (or faster, or as fast as), from two rates."""
    ratio = fps / other_fps
    if abs(ratio - 1.0) < 0.005:
        return f"{name} is as fast as {other} (within 0.5%)"
    if ratio > 1.0:
        return f"{name} is {ratio:.2f}x faster than {other}"
    return f"{name} is {1.0 / ratio:.2f}x slower than {other}"


@functools.lru_cache(maxsize=None)
def _spin_kernel():
    """A compute-bound parallel loop (compiled once per process; a closure, so not cached on disk)."""
    import numba

    from nrmlc.config import PARALLEL_FLAGS

    @numba.njit(**dict(PARALLEL_FLAGS, cache=False))
    def spin(out):
        for i in numba.prange(out.shape[0]):
            value = 0.0
            for k in range(20000):
                value += math.sin(value + k)
            out[i] = value

    return spin


def _parallel_speedup(repeats: int = 5) -> float | None:
    """How much faster a compute-bound numba loop runs on all threads than on one, right now.

    About the core count on an idle machine, about 1 when other processes hold the other
    cores: it says how many cores the bench's parallel numbers actually had.
    """
    import numba

    spin = _spin_kernel()
    threads = numba.get_num_threads()
    if threads < 2:
        return None
    out = np.empty(8 * threads)
    spin(out)
    times = {}
    try:
        for n in (1, threads):
            numba.set_num_threads(n)
            times[n] = measure(lambda: spin(out), repeats)["ms"]
    finally:
        numba.set_num_threads(threads)
    return times[1] / times[threads]


#: Before each measured section the bench waits, up to this many seconds, for the machine to
#: be at least QUIET_SHARE idle (over one second); 0 disables it (``--wait-quiet``).
WAIT_QUIET_S = 30.0
QUIET_SHARE = 0.8
_quiet_log: list[dict] = []


def _idle_share(seconds: float) -> float | None:
    """Share of CPU time idle over the next ``seconds`` (all cores), or None off Linux."""
    def ticks():
        fields = [float(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
        return fields[3] + fields[4], sum(fields)

    try:
        idle_0, total_0 = ticks()
        time.sleep(seconds)
        idle_1, total_1 = ticks()
    except OSError:  # pragma: no cover - not Linux
        return None
    return (idle_1 - idle_0) / max(total_1 - total_0, 1.0)


def wait_quiet(section: str) -> None:
    """Wait up to WAIT_QUIET_S for an idle machine, and log how long and how idle it was."""
    start = time.perf_counter()
    idle = _idle_share(1.0) if WAIT_QUIET_S > 0 else None
    while idle is not None and idle < QUIET_SHARE and time.perf_counter() - start < WAIT_QUIET_S:
        idle = _idle_share(1.0)
    _quiet_log.append({"section": section, "waited_s": round(time.perf_counter() - start, 1),
                       "idle_share": None if idle is None else round(idle, 2)})


def _load(probe_cores: bool = True) -> dict:
    """Load averages, the share of CPU time idle over 0.5 s (all cores), the parallel speed-up at hand."""
    idle = _idle_share(0.5)
    try:
        load_average = [round(v, 2) for v in os.getloadavg()]
    except OSError:  # pragma: no cover - not Linux
        load_average = None
    return {"load_average": load_average, "idle_share": None if idle is None else round(idle, 3),
            "parallel_speedup": _parallel_speedup() if probe_cores else None}


# ---------------------------------------------------------------------------
# machine
# ---------------------------------------------------------------------------

def machine_info() -> dict:
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
        "cpu": cpu, "logical_cores": os.cpu_count(),
        "numba_threads": numba.get_num_threads(), "numba_threading_layer": layer,
        "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY"),
        "blas": blas, "opencv_threads": cv2.getNumThreads(),
        "python": platform.python_version(), "numpy": np.__version__, "numba": numba.__version__,
        "llvmlite": llvmlite.__version__, "scipy": scipy.__version__, "opencv": cv2.__version__,
        "platform": platform.platform(),
    }


# ---------------------------------------------------------------------------
# stages of a frame
# ---------------------------------------------------------------------------

#: Function name (as the tracker modules call it) -> stage label. Calls made while the
#: templates are updated count as the template update.
STAGES = {
    "warp_patches": "warp (particles)",
    "gradient_cells": "gradient cells (a gradient expert's eyes)",
    "candidate_template_dots": "product (sgemm)",
    "squared_norms": "squared norms",
    "nearest_templates": "nearest templates",
    "encode_dictionaries": "coding",
    "combine_dictionaries": "weights + confidence",
    "code_candidates": "norms, nearest, coding, weights (one pass)",
    "template_gram": "template Gram",
    "match_local_histogram": "generative term (local coding, histogram match)",
}
ONE_PASS_STAGE = STAGES["code_candidates"]
TEMPLATE_STAGE = "template update (amortised)"
OTHER_STAGE = "between the kernels (Python, numpy)"


class StageTimer:
    """Times the stages of a tracker while it runs, by wrapping the functions its modules call.

    Every function named in :data:`STAGES` that an ``nrmlc.tracker`` module
    holds is replaced by a wrapper that adds its wall time to its stage (or, during
    the tracker's ``update_templates``, to the template update's parts), and keeps
    its last arguments so that its floor can be timed alone on the same inputs.
    """

    def __init__(self, tracker_class) -> None:
        import types

        self.seconds: dict[tuple, float] = {}
        self.calls: dict[tuple, int] = {}
        self.last_call: dict[tuple, tuple] = {}
        self._updating = False
        self._patched: list[tuple[object, str, object]] = []
        for module_name, module in list(sys.modules.items()):
            if not module_name.startswith("nrmlc.tracker") or module is None:
                continue
            for name, label in STAGES.items():
                value = vars(module).get(name)
                if isinstance(value, types.FunctionType):
                    self._wrap(module, name, value, label)
        if hasattr(tracker_class, "update_templates"):
            original = tracker_class.update_templates
            timer = self

            def update_templates(self_, *args, **kwargs):
                timer._updating = True
                start = time.perf_counter()
                try:
                    return original(self_, *args, **kwargs)
                finally:
                    timer._add((TEMPLATE_STAGE, False), time.perf_counter() - start)
                    timer._updating = False

            self._patched.append((tracker_class, "update_templates", original))
            tracker_class.update_templates = update_templates

    def _add(self, key: tuple, seconds: float) -> None:
        self.seconds[key] = self.seconds.get(key, 0.0) + seconds
        self.calls[key] = self.calls.get(key, 0) + 1

    def _wrap(self, module, name: str, function, label: str) -> None:
        timer = self

        def wrapper(*args, **kwargs):
            key = (label, timer._updating)
            start = time.perf_counter()
            result = function(*args, **kwargs)
            timer._add(key, time.perf_counter() - start)
            timer.last_call[key] = (function, args, kwargs)
            return result

        self._patched.append((module, name, function))
        setattr(module, name, wrapper)

    def reset(self) -> None:
        self.seconds.clear()
        self.calls.clear()

    def floor(self, key: tuple, repeats: int) -> float:
        """Median ms of the stage's last call, repeated alone."""
        function, args, kwargs = self.last_call[key]
        return measure(lambda: function(*args, **kwargs), repeats)["ms"]

    def restore(self) -> None:
        for owner, name, original in reversed(self._patched):
            setattr(owner, name, original)
        self._patched.clear()


def _frames(sequence, n_frames: int, color: bool = False) -> list:
    read = sequence.color_frame if color else sequence.frame
    return [read(i) for i in range(min(n_frames, len(sequence)))]


def _one_pass_parts(args: tuple, repeats: int) -> dict:
    """Floors (ms per call) of the four kernels that ``code_candidates`` fuses, on its inputs."""
    from nrmlc.kernels.coding import combine_dictionaries, encode_dictionaries
    from nrmlc.kernels.distance import nearest_templates, squared_norms

    candidates, dots, gram, t_norms, sizes, n_positive, ridge_c, ridge_w, constrained, n_iterations = args
    k_max = int(np.max(sizes))
    sq = squared_norms(candidates)
    neighbours, _ = nearest_templates(dots, sq, t_norms, k_max)
    coefficients = encode_dictionaries(gram, dots, sq, neighbours, sizes, ridge_c, constrained)
    return {
        "squared norms": measure(lambda: squared_norms(candidates), repeats)["ms"],
        "nearest templates": measure(lambda: nearest_templates(dots, sq, t_norms, k_max), repeats)["ms"],
        "coding": measure(lambda: encode_dictionaries(gram, dots, sq, neighbours, sizes, ridge_c, constrained),
                          repeats)["ms"],
        "weights + confidence": measure(lambda: combine_dictionaries(gram, dots, sq, neighbours, coefficients, sizes,
                                                                     n_positive, ridge_w, constrained, n_iterations),
                                        repeats)["ms"],
    }


def bench_stages(sequence, counts, warm_frames: int = 20, timed_frames: int = 60, floor_repeats: int = 15) -> list:
    """Per-stage ms per frame inside real ``update`` calls, and each stage's floor (ms per frame)."""
    from nrmlc.tracker.algorithm import NRMLCTracker
    from nrmlc.tracker.experts import make_tracker
    from nrmlc.tracker.params import TrackerParams

    frames = _frames(sequence, warm_frames + timed_frames + 1)
    timed_frames = len(frames) - warm_frames - 1
    rows = []
    for n in counts:
        wait_quiet(f"stages N={n}")
        timer = StageTimer(NRMLCTracker)
        try:
            tracker = make_tracker(TrackerParams(n_particles=n), seed=0)
            tracker.init(frames[0], sequence.init_box)
            for frame in frames[1:warm_frames + 1]:
                tracker.update(frame)
            timer.reset()
            start = time.perf_counter()
            for frame in frames[warm_frames + 1:]:
                tracker.update(frame)
            frame_ms = 1e3 * (time.perf_counter() - start) / timed_frames
            per_frame = {key: 1e3 * seconds / timed_frames for key, seconds in timer.seconds.items()}
            calls = {key: count / timed_frames for key, count in timer.calls.items()}
            floors = {key: timer.floor(key, floor_repeats) * calls[key] for key in calls if key in timer.last_call}
            one_pass = timer.last_call.get((ONE_PASS_STAGE, False))
        finally:
            timer.restore()
        top = [(label, False) for label in STAGES.values() if (label, False) in per_frame]
        for key in top:
            rows.append({"n_particles": n, "stage": key[0], "ms": per_frame[key], "calls_per_frame": calls[key],
                         "floor_ms": floors[key]})
            if key[0] == ONE_PASS_STAGE and one_pass is not None:
                rows += [{"n_particles": n, "stage": f"  of which, alone: {label}", "ms": None, "part": True,
                          "calls_per_frame": calls[key], "floor_ms": ms * calls[key]}
                         for label, ms in _one_pass_parts(one_pass[1], floor_repeats).items()]
        update_key = (TEMPLATE_STAGE, False)
        if update_key in per_frame:
            parts = [key for key in floors if key[1]]
            rows.append({"n_particles": n, "stage": TEMPLATE_STAGE, "ms": per_frame[update_key],
                         "calls_per_frame": calls[update_key], "floor_ms": sum(floors[key] for key in parts),
                         "floor_of": [key[0] for key in parts]})
            top.append(update_key)
        kernel_floor = sum(row["floor_ms"] for row in rows if row["n_particles"] == n and not row.get("part"))
        rows.append({"n_particles": n, "stage": OTHER_STAGE, "ms": frame_ms - sum(per_frame[key] for key in top),
                     "calls_per_frame": None, "floor_ms": None})
        rows.append({"n_particles": n, "stage": "whole frame", "ms": frame_ms, "calls_per_frame": 1.0,
                     "floor_ms": kernel_floor, "fps": 1e3 / frame_ms})
        print(f"  N={n:5d}: frame {frame_ms:6.2f} ms ({1e3 / frame_ms:6.1f} fps), sum of stage floors "
              f"{kernel_floor:6.2f} ms", flush=True)
    return rows


# ---------------------------------------------------------------------------
# kernels against their references
# ---------------------------------------------------------------------------

def _warmed_tracker(sequence, n_frames: int):
    """One expert run over the first frames, so that its templates, the kernels' inputs, include updates."""
    from nrmlc.tracker.algorithm import NRMLCTracker

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

    def add(kernel, n, timing, reference, reference_name, subset=None):
        scale = n / subset if subset else 1.0
        row = {"kernel": kernel, "n_particles": n, "n_templates": len(templates), **timing,
               "reference": reference_name, "reference_ms": reference["ms"] * scale, "reference_on": subset or n}
        row["speedup"] = row["reference_ms"] / timing["ms"]
        rows.append(row)
        print(f"  {kernel:28s} N={n:5d} {timing['ms']:9.3f} ms   reference {row['reference_ms']:10.1f} ms  "
              f"({row['speedup']:.0f}x faster)", flush=True)
        return row

    for n in counts:
        tracker = copy.deepcopy(base)
        tracker.params = params.replace(n_particles=n)
        tracker.particles = None  # draw around the estimate, as in the first frame
        states = tracker.sample_particles()
        affines = np.ascontiguousarray(state_to_affine(states))
        candidates = warp_patches(frame, affines)

        add("warp", n, measure(lambda: warp_patches(frame, affines), repeats),
            measure(lambda: warp_patches_reference(frame, affines), reference_repeats, 0),
            "nrmlc/testing/reference.py (oracle)")

        def knn():
            dots = candidate_template_dots(candidates, templates)
            return nearest_templates(dots, squared_norms(candidates), t_norms, k_max)

        def knn_reference():
            dots = reference_dots(candidates, templates)
            sq = np.einsum("ij,ij->i", candidates, candidates, dtype=np.float64)
            return reference_nearest(sq[:, None] + t_norms[None, :] - 2.0 * dots, k_max)

        timing = measure(knn, repeats)
        add("distances+knn", n, timing, measure(knn_reference, reference_repeats, 0),
            "nrmlc/testing/reference.py einsum + stable argsort (oracle)")
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
            add(f"coding {mode}", n, measure(encode, repeats),
                measure(lambda: reference_encode(candidates[:subset], templates, neighbours[:subset], sizes,
                                                 ridge_c, constrained), reference_repeats, 0),
                "nrmlc/testing/reference.py reference_encode (oracle)", subset)

            def combine(ridge_w=ridge_w, constrained=constrained, coefficients=coefficients):
                return combine_dictionaries(gram, dots, sq_norms, neighbours, coefficients, sizes, n_positive,
                                            ridge_w, constrained, params.n_iterations)

            add(f"weights+confidence {mode}", n, measure(combine, repeats),
                measure(lambda: reference_combine(candidates[:subset], templates, neighbours[:subset],
                                                  coefficients[:subset], sizes, n_positive, ridge_w,
                                                  constrained, params.n_iterations), reference_repeats, 0),
                "nrmlc/testing/reference.py reference_combine (oracle)", subset)
    return rows


# ---------------------------------------------------------------------------
# end to end
# ---------------------------------------------------------------------------

def _nrmlc_fps(sequence, frames, params) -> float:
    """Tracker fps over preloaded frames (decoding excluded), init included, as track_sequence counts."""
    from nrmlc.tracker.experts import make_tracker

    tracker = make_tracker(params, seed=0)
    start = time.perf_counter()
    tracker.init(frames[0], sequence.init_box)
    for frame in frames[1:]:
        tracker.update(frame)
    return (len(frames) - 1) / (time.perf_counter() - start)


#: How the end-to-end rows name the lineage's trackers ("IVT (lineage, live)").
LINEAGE_SUFFIX = "(lineage, live)"
#: The paper's peers of NRMLC's lineage (Table II's names), built in :mod:`nrmlc.lineage` or not.
LINEAGE_PAPER_NAMES = ("LSK", "L1", "L1APG", "MTT", "IVT", "ASLA")


def _mil_fps(sequence, color_frames) -> float:
    """OpenCV TrackerMIL on the same frames (BGR, preloaded), init included."""
    import cv2

    x, y, w, h = (float(v) for v in sequence.init_box)
    box = (int(round(x - 1)), int(round(y - 1)), max(1, int(round(w))), max(1, int(round(h))))
    tracker = cv2.TrackerMIL.create()
    start = time.perf_counter()
    tracker.init(color_frames[0], box)
    for frame in color_frames[1:]:
        tracker.update(frame)
    return (len(color_frames) - 1) / (time.perf_counter() - start)


def _lineage_fps(sequence, color_frames, name: str) -> float:
    """A lineage tracker (:data:`nrmlc.lineage.TRACKERS`) on the same frames (BGR, preloaded), init included."""
    import importlib

    from nrmlc.lineage import TRACKERS

    module, _, factory = TRACKERS[name].partition(":")
    tracker = getattr(importlib.import_module(module), factory)(seed=0)
    start = time.perf_counter()
    tracker.init(color_frames[0], sequence.init_box)
    for frame in color_frames[1:]:
        tracker.update(frame)
    return (len(color_frames) - 1) / (time.perf_counter() - start)


def bench_end_to_end(sequence, n_frames: int | None, rounds: int) -> list[dict]:
    """NRMLC (each coding mode) and TrackerMIL on the same preloaded frames, in alternating rounds.

    Also times one run with decoding included (``track_sequence`` reading the frames).
    """
    from experiments.shared import TRIAL_VALUES
    from nrmlc.tracker.params import TrackerParams
    from nrmlc.tracker.loop import track_sequence

    total = len(sequence) if n_frames is None else min(n_frames, len(sequence))
    frames = _frames(sequence, total)
    color_frames = _frames(sequence, total, color=True)
    default = TrackerParams()
    _nrmlc_fps(sequence, frames[:8], default)  # loads the compiled kernels
    # The default parameters exactly, and the other coding modes changed from them.
    variants = {f"NRMLC {mode}": default if mode == default.coding else default.replace(coding=mode) for mode in MODES}
    # The generative term's cost: the default with the switch flipped (to its ablation value when off).
    flipped = 0.0 if default.generative_weight > 0 else TRIAL_VALUES["generative_weight"]
    variants[f"NRMLC generative_weight={flipped:g}"] = default.replace(generative_weight=flipped)
    # The second expert's cost: the default with one tracker, or with the pair when the default has one.
    expert = "off" if default.second_expert != "off" else "every_frame"
    variants[f"NRMLC second_expert={expert}"] = default.replace(second_expert=expert)
    # What the partner's other eyes cost: the pair with the partner's eyes flipped (gray <-> gradient).
    if default.second_expert != "off":
        eyes = "gradient" if default.partner_eyes == "gray" else "gray"
        variants[f"NRMLC partner_eyes={eyes}"] = default.replace(partner_eyes=eyes)
        # The pair against its experts run one after the other: the partner alone.
        variants[PARTNER_ALONE] = default.partner_params()
    samples = {name: [] for name in variants}
    samples["OpenCV TrackerMIL"] = []
    from nrmlc.lineage import TRACKERS

    for name in TRACKERS:
        samples[f"{name.upper()} {LINEAGE_SUFFIX}"] = []
        _lineage_fps(sequence, color_frames[:3], name)  # loads its compiled kernels
    for index in range(rounds):
        wait_quiet(f"end to end {sequence.name} round {index + 1}")
        for name, params in variants.items():
            samples[name].append(_nrmlc_fps(sequence, frames, params))
        samples["OpenCV TrackerMIL"].append(_mil_fps(sequence, color_frames))
        for name in TRACKERS:
            samples[f"{name.upper()} {LINEAGE_SUFFIX}"].append(_lineage_fps(sequence, color_frames, name))
    decoded = track_sequence(sequence, default, seed=0, n_frames=total)
    rows = []
    for tracker, runs in samples.items():
        row = {"sequence": sequence.name, "tracker": tracker, "frames": total, "rounds": len(runs),
               "fps_tracking": float(np.median(runs)), "fps_runs": [round(v, 1) for v in runs],
               "default": variants.get(tracker) is default}
        if row["default"]:
            row["fps_total"] = decoded.fps_total
        rows.append(row)
        print(f"  {sequence.name}: {tracker:22s} {row['fps_tracking']:7.1f} fps (decoding excluded; "
              f"rounds {row['fps_runs']})", flush=True)
    return rows


# ---------------------------------------------------------------------------
# thread set-ups
# ---------------------------------------------------------------------------

_THREADS_CHILD = r"""
import json, sys, time
setup, data, n_frames = sys.argv[1], sys.argv[2], int(sys.argv[3])
if setup in ("set_threads first", "serial", "spin-wait"):
    from nrmlc.config import set_threads
    set_threads(1 if setup == "serial" else None)
from nrmlc.tracker.experts import make_tracker
if setup == "set_threads after import":
    from nrmlc.config import set_threads
    set_threads(None)
import numba
from nrmlc.data import open_sequence, synthetic_suite
sequence = open_sequence(data) if data else synthetic_suite(n_frames=n_frames)[0]
frames = [sequence.frame(i) for i in range(min(n_frames, len(sequence)))]
tracker = make_tracker(seed=0)
tracker.init(frames[0], sequence.init_box)
for frame in frames[1:6]:
    tracker.update(frame)
tracker = make_tracker(seed=0)
cpu, wall = time.process_time(), time.perf_counter()
tracker.init(frames[0], sequence.init_box)
for frame in frames[1:]:
    tracker.update(frame)
wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
print(json.dumps({"fps": (len(frames) - 1) / wall, "cpu_ms_per_frame": 1e3 * cpu / (len(frames) - 1),
                  "numba_threads": numba.get_num_threads(), "numba_layer": numba.threading_layer()}))
"""

#: name -> (child set-up, extra environment). The first is the reference of the ratios.
THREAD_SETUPS = {
    "API default (nothing called)": ("default", {}),
    "set_threads() before importing the tracker (as the CLI)": ("set_threads first", {}),
    "set_threads() after importing the tracker": ("set_threads after import", {}),
    "one thread: set_threads(1)": ("serial", {}),
    "numba pool spin-waiting (libgomp default; the bug it fixed)": ("spin-wait", {"GOMP_SPINCOUNT": "300000"}),
}


def bench_threads(data_sequence: Path | None, rounds: int = 2, n_frames: int = 120) -> list[dict]:
    """Tracker fps and CPU per frame under each thread set-up, each in a fresh process, interleaved."""
    samples = {name: [] for name in THREAD_SETUPS}
    for index in range(rounds):
        wait_quiet(f"thread set-ups round {index + 1}")
        for name, (setup, extra_env) in THREAD_SETUPS.items():
            env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
            env.update(extra_env)
            output = subprocess.run([sys.executable, "-c", _THREADS_CHILD, setup,
                                     str(data_sequence) if data_sequence else "", str(n_frames)],
                                    env=env, cwd=str(REPO_ROOT), capture_output=True, text=True, check=True)
            samples[name].append(json.loads(output.stdout.strip().splitlines()[-1]))
    rows = []
    for name, runs in samples.items():
        row = {"setup": name, "runs": len(runs), "frames": n_frames,
               "sequence": data_sequence.name if data_sequence else "synthetic",
               "fps": float(np.median([r["fps"] for r in runs])),
               "cpu_ms_per_frame": float(np.median([r["cpu_ms_per_frame"] for r in runs])),
               "numba_threads": runs[0]["numba_threads"], "fps_all": [round(r["fps"], 1) for r in runs]}
        rows.append(row)
        print(f"  {name:62s} {row['fps']:7.1f} fps  {row['cpu_ms_per_frame']:6.1f} ms CPU/frame  "
              f"(runs: {row['fps_all']})", flush=True)
    return rows


# ---------------------------------------------------------------------------
# start-up
# ---------------------------------------------------------------------------

_STARTUP_CHILD = r"""
import json, time
start = time.perf_counter()
import numpy as np
from nrmlc.tracker.experts import make_tracker
imported = time.perf_counter()
rng = np.random.default_rng(0)
frame = rng.random((120, 160)).astype(np.float32)
tracker = make_tracker(seed=0)
tracker.init(frame, (40.0, 30.0, 40.0, 32.0))
for _ in range(5):
    tracker.update(frame)
done = time.perf_counter()
print(json.dumps({"import_s": imported - start, "first_frames_s": done - imported, "total_s": done - start}))
"""


def _startup_run(cache_dir: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    wall = time.perf_counter()
    output = subprocess.run([sys.executable, "-c", _STARTUP_CHILD], env=env, cwd=str(REPO_ROOT),
                            capture_output=True, text=True, check=True)
    result = json.loads(output.stdout.strip().splitlines()[-1])
    result["process_s"] = time.perf_counter() - wall
    return result


def bench_startup(warm_repeats: int = 2) -> dict:
    """Import + init + 5 updates (a template update included) in fresh processes: empty cache, then warm."""
    with tempfile.TemporaryDirectory(prefix="nrmlc-numba-cache-") as cache_dir:
        cold = _startup_run(cache_dir)
        warm = [_startup_run(cache_dir) for _ in range(warm_repeats)]
    best = min(warm, key=lambda r: r["total_s"])
    print(f"  cold (empty numba cache): {cold['total_s']:.2f} s (import {cold['import_s']:.2f} s); "
          f"warm (on-disk cache): {best['total_s']:.2f} s (import {best['import_s']:.2f} s)", flush=True)
    return {"cold": cold, "warm": warm, "warm_best": best,
            "what": "fresh python process: import the tracker, init and 5 updates (600 particles, one template "
                    "update), NUMBA_CACHE_DIR = an empty temp dir (cold), then the same dir (warm)"}


# ---------------------------------------------------------------------------
# grid throughput
# ---------------------------------------------------------------------------

_GRID_CHILD = r"""
import json, os, sys, tempfile, time
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.workbench.jobs import RunSpec
from nrmlc.workbench.pool import prepare_kernels, process_pool
from nrmlc.workbench.run_cache import RunCache
from nrmlc.tracker.params import TrackerParams
n_runs, n_frames, workers, dask = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
specs = [RunSpec(SyntheticSequence(SyntheticSpec(name=f"grid-{k}", seed=k, n_frames=n_frames)), TrackerParams(),
                 seed=0, label=str(k)) for k in range(n_runs)]
frames = sum(spec.frames() for spec in specs)
out = {"runs": n_runs, "frames": frames}
prepare_kernels()  # loaded before any timing, as the runner does
with tempfile.TemporaryDirectory() as folder:
    start = time.perf_counter()
    RunCache(os.path.join(folder, "serial")).run(specs, jobs=1, progress=False)  # here, one thread
    out["serial_fps"] = frames / (time.perf_counter() - start)
    start = time.perf_counter()
    pool = process_pool(workers)
    list(pool.map(time.sleep, [0.5] * workers))  # every worker started and warmed up
    out["pool_start_s"] = time.perf_counter() - start
    start = time.perf_counter()
    RunCache(os.path.join(folder, "pool")).run(specs, executor=pool, progress=False)
    out["pool_fps"] = frames / (time.perf_counter() - start)
    pool.shutdown()
    if dask:
        from distributed import Client
        with Client(dask) as client:
            out["dask_workers"] = len(client.scheduler_info()["workers"])
            start = time.perf_counter()
            RunCache(os.path.join(folder, "dask")).run(specs, executor=client.get_executor(), progress=False)
            out["dask_fps"] = frames / (time.perf_counter() - start)
print(json.dumps(out))
"""


def bench_grid(workers: int, dask: str | None = None, n_runs: int = 8, n_frames: int = 150) -> dict:
    """Frames per second of a small grid through the run cache: one process (one thread), the
    local process pool of ``workers`` single-threaded workers (started and warmed up first, timed
    apart), and optionally a Dask cluster; in a fresh process, so that this one keeps its threads."""
    output = subprocess.run([sys.executable, "-c", _GRID_CHILD, str(n_runs), str(n_frames), str(workers), dask or ""],
                            cwd=str(REPO_ROOT), capture_output=True, text=True)
    if output.returncode != 0:
        raise RuntimeError(f"grid throughput run failed:\n{output.stderr[-2000:]}")
    result = json.loads(output.stdout.strip().splitlines()[-1])
    result["workers"] = workers
    result["pool_start_s"] -= 0.5  # the tasks that started the workers each slept 0.5 s
    result["pool_efficiency"] = result["pool_fps"] / (workers * result["serial_fps"])
    print(f"  {result['runs']} runs, {result['frames']} frames: one process {result['serial_fps']:.1f} fps, "
          f"pool of {workers} {result['pool_fps']:.1f} fps ({result['pool_efficiency']:.2f} of {workers} x one "
          f"process; pool start {result['pool_start_s']:.1f} s)"
          + (f", Dask ({result['dask_workers']} workers) {result['dask_fps']:.1f} fps" if dask else ""), flush=True)
    return result


# ---------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------

def _summary(result: dict) -> list[str]:
    lines = []
    by_name = {(row["sequence"], row["tracker"]): row for row in result["end_to_end"]}
    for (sequence, tracker), row in by_name.items():
        if not row.get("default"):
            continue
        fps = row["fps_tracking"]
        default_mode = tracker.split()[-1]
        mil = by_name.get((sequence, "OpenCV TrackerMIL"))
        line = f"{sequence}: NRMLC (default parameters, {default_mode}) runs at {fps:.1f} fps, decoding excluded"
        if mil:
            line += (f"; OpenCV TrackerMIL at {mil['fps_tracking']:.1f} fps on the same frames: "
                     + compare("NRMLC", fps, "TrackerMIL", mil["fps_tracking"]))
        lines.append(line + ".")
        if sequence == "Car4":
            ratio = fps / mil["fps_tracking"] if mil else float("nan")
            met = fps >= TARGET_FPS and ratio >= TARGET_MIL_RATIO
            lines.append(f"Car4 speed target (>= {TARGET_FPS:.0f} fps and >= {TARGET_MIL_RATIO:.0f}x "
                         f"TrackerMIL, same run): {'met' if met else 'NOT met'} ({fps:.1f} fps, {ratio:.1f}x).")
        for (other_sequence, other_tracker), other in by_name.items():
            if other_sequence == sequence and other_tracker.endswith(LINEAGE_SUFFIX) and mil:
                lines.append(f"{sequence}: {other_tracker} runs at {other['fps_tracking']:.1f} fps: "
                             + compare(other_tracker.split()[0], other["fps_tracking"], "TrackerMIL",
                                       mil["fps_tracking"]) + ".")
        for mode in MODES:
            other = by_name.get((sequence, f"NRMLC {mode}"))
            if other and mode != default_mode:
                lines.append(f"{sequence}: " + compare(mode, other["fps_tracking"], default_mode, fps) + ".")
        for (other_sequence, other_tracker), other in by_name.items():
            if other_sequence == sequence and any(f"{switch}=" in other_tracker for switch in FLIPPED_SWITCHES):
                lines.append(f"{sequence}: " + compare(other_tracker.split()[-1], other["fps_tracking"],
                                                       "the default", fps) + ".")
        lines += _pair_cost_line(by_name, sequence, fps)
    threads = result.get("threads") or []
    if threads:
        reference = threads[0]
        for row in threads[1:]:
            lines.append(f"Threads ({row['sequence']}): {row['setup']}: {row['fps']:.1f} fps; "
                         + compare("it", row["fps"], "the API default", reference["fps"])
                         + f" ({reference['fps']:.1f} fps).")
    if result.get("grid"):
        g = result["grid"]
        lines.append(f"Grid: a pool of {g['workers']} single-threaded workers runs {g['pool_fps']:.1f} frames per "
                     f"second, {g['pool_efficiency']:.2f} of {g['workers']} x one process ({g['serial_fps']:.1f} fps).")
    kernels = [r for r in result.get("kernels", []) if r["n_particles"] == 600 and "numpy BLAS" not in r["kernel"]]
    if kernels:
        slowest = min(kernels, key=lambda r: r["speedup"])
        lines.append(f"Smallest kernel speed-up against its test oracle at N=600: {slowest['speedup']:.0f}x "
                     f"({slowest['kernel']}).")
    return lines


def _pair_cost_line(by_name: dict, sequence: str, fps: float) -> list[str]:
    """The default's pair against its two experts run one after the other, in ms per frame: what
    sharing the frame and the seeing kernels saves (empty without the rows)."""
    first = by_name.get((sequence, "NRMLC second_expert=off"))
    partner = by_name.get((sequence, PARTNER_ALONE))
    if not first or not partner:
        return []
    pair_ms, first_ms, partner_ms = 1e3 / fps, 1e3 / first["fps_tracking"], 1e3 / partner["fps_tracking"]
    return [f"{sequence}: the pair takes {pair_ms:.1f} ms per frame; its experts alone {first_ms:.1f} (the first, "
            f"second_expert=off) + {partner_ms:.1f} (the partner) = {first_ms + partner_ms:.1f} ms: the partner adds "
            f"{pair_ms - first_ms:.1f} ms to the first expert, against {partner_ms:.1f} ms alone."]


def _reported_matlab_lines(result: dict) -> list[str]:
    """The paper's Table II fps of each lineage tracker's MATLAB original (its machine, not this
    one), beside this run's live fps on Car4: a context ratio, not one measured side by side."""
    from experiments import paper_numbers

    live = {row["tracker"].split()[0]: row["fps_tracking"] for row in result["end_to_end"]
            if row["sequence"] == "Car4" and row["tracker"].endswith(LINEAGE_SUFFIX)}
    if not live:
        return []
    parts = [f"{name} {paper_numbers.FPS[name]:g} fps (live here: {fps:.1f}, {fps / paper_numbers.FPS[name]:.0f}x)"
             for name, fps in live.items() if name in paper_numbers.FPS]
    missing = [name for name in LINEAGE_PAPER_NAMES if name not in live]
    return ["", "The paper's Table II reports the MATLAB originals, over its nine sequences on an Intel Xeon E5506 "
            "(2.13 GHz), at " + ", ".join(parts)
            + "".join(f"; {name} {paper_numbers.FPS[name]:g} fps (no live run)" for name in missing)
            + ". Another machine and other frames: context, not a measured ratio."]


def _speedup_text(load: dict) -> str:
    speedup = load.get("parallel_speedup")
    return "n/a" if speedup is None else f"{speedup:.2f}x"


def _markdown(result: dict) -> str:
    m = result["machine"]
    blas = ", ".join(str(b["num_threads"]) for b in m["blas"])
    lines = ["# NRMLC timings", "",
             f"Machine: {m['cpu']}, {m['logical_cores']} logical cores. Threads as the API uses them: numba "
             f"{m['numba_threads']} ({m['numba_threading_layer']}, OMP_WAIT_POLICY={m['omp_wait_policy']}), "
             f"BLAS {blas} (products run with one, see nrmlc.config.set_threads), OpenCV {m['opencv_threads']}. "
             f"numpy {m['numpy']}, numba {m['numba']}, OpenCV {m['opencv']}, Python {m['python']}.",
             f"Machine load before / after: load average {result['load_before']['load_average']} / "
             f"{result['load_after']['load_average']}, idle share {result['load_before']['idle_share']} / "
             f"{result['load_after']['idle_share']} (other processes shared the machine when the idle share is "
             "well below 1); all threads against one on a compute-bound loop: "
             f"{_speedup_text(result['load_before'])} / {_speedup_text(result['load_after'])} faster (about the "
             "core count when the cores are free, about 1 when other processes hold them). "
             "Compare ratios within this run.", ""]
    quiet = result.get("quiet") or {}
    sections = [entry for entry in quiet.get("sections", []) if entry["idle_share"] is not None]
    if quiet.get("wait_limit_s") and sections:
        shares = [entry["idle_share"] for entry in sections]
        lines += [f"Before each measured section the bench waited up to {quiet['wait_limit_s']:.0f} s for the "
                  f"machine to be {quiet['quiet_share']:.0%} idle: {sum(e['waited_s'] for e in sections):.0f} s of "
                  f"waiting in all; the idle share when the sections started ranged {min(shares):.2f}-"
                  f"{max(shares):.2f} ({sum(share >= quiet['quiet_share'] for share in shares)} of "
                  f"{len(shares)} sections started on a quiet machine).", ""]
    lines += ["## Summary", ""]
    lines += [f"- {line}" for line in result["summary"]]
    stage_sequence = result.get("stage_sequence", "")
    lines += ["", f"## Stages of a frame ({stage_sequence}, ms per frame)", "",
              "In real `update` calls, against the floor of each stage: the same call on the same inputs timed "
              "alone (median), times its calls per frame. Template updates happen every few frames; their time is "
              "spread over all frames, and their floor is that of their parts (warps, Gram) timed alone. The whole "
              "frame's floor is the sum of the stage floors; the Python and numpy between the kernels have none. "
              "Rows \"of which, alone\" time the four kernels that the one pass fuses, each alone on the same "
              "inputs (the one pass does their work with one meeting of the threads instead of four).", "",
              "| N | stage | ms in the frame | floor ms | in frame / floor | calls per frame |",
              "|---:|---|---:|---:|---:|---:|"]
    for row in result["stages"]:
        floor = f"{row['floor_ms']:.3f}" if row.get("floor_ms") else ""
        ratio = f"{row['ms'] / row['floor_ms']:.2f}" if row.get("floor_ms") and row["ms"] is not None else ""
        calls = f"{row['calls_per_frame']:.2f}" if row.get("calls_per_frame") is not None else ""
        stage = f"**{row['stage']}** ({row['fps']:.1f} fps)" if row["stage"] == "whole frame" else row["stage"]
        in_frame = "" if row["ms"] is None else f"{row['ms']:.3f}"
        lines.append(f"| {row['n_particles']} | {stage} | {in_frame} | {floor} | {ratio} | {calls} |")
    lines += ["", "## End to end (decoding excluded; medians of alternating rounds)", "",
              "| sequence | tracker | frames | fps | rounds (fps) | fps with decoding |",
              "|---|---|---:|---:|---|---:|"]
    for row in result["end_to_end"]:
        total = f"{row['fps_total']:.1f}" if "fps_total" in row else ""
        tracker = f"{row['tracker']} (default parameters)" if row.get("default") else row["tracker"]
        lines.append(f"| {row['sequence']} | {tracker} | {row['frames']} | {row['fps_tracking']:.1f} | "
                     f"{row['fps_runs']} | {total} |")
    if result.get("matlab_fps"):
        lines += ["", "The OTB benchmark's files record the MATLAB originals on Car4 at "
                  + ", ".join(f"{fps:.1f} fps ({name})" for name, fps in result["matlab_fps"].items())
                  + ", on the benchmark's machine (2013), not this one."]
    lines += _reported_matlab_lines(result)
    if result.get("threads"):
        lines += ["", "## Thread set-ups (fresh process each, median of interleaved runs)", "",
                  "| set-up | numba threads | fps | CPU ms / frame | runs (fps) |", "|---|---:|---:|---:|---|"]
        for row in result["threads"]:
            lines.append(f"| {row['setup']} | {row['numba_threads']} | {row['fps']:.1f} | "
                         f"{row['cpu_ms_per_frame']:.1f} | {row['fps_all']} |")
    if result.get("grid"):
        g = result["grid"]
        lines += ["", "## Grid throughput (the run cache, as `make figures` uses it)", "",
                  f"{g['runs']} synthetic runs of the default tracker, {g['frames']} frames in all.", "",
                  "| where | fps (frames per second of wall time) |", "|---|---:|",
                  f"| one process, one thread | {g['serial_fps']:.1f} |",
                  f"| local process pool, {g['workers']} single-threaded workers (started beforehand: "
                  f"{g['pool_start_s']:.1f} s) | {g['pool_fps']:.1f} |"]
        if "dask_fps" in g:
            lines.append(f"| Dask cluster, {g['dask_workers']} workers | {g['dask_fps']:.1f} |")
        lines += ["", f"The pool reaches {g['pool_efficiency']:.2f} of {g['workers']} x the one-process rate."]
    lines += ["", "## Kernels against their numpy references", "",
              "| kernel | N | ms (median) | reference ms | speed-up | reference |",
              "|---|---:|---:|---:|---:|---|"]
    for row in result["kernels"]:
        what = row["reference"]
        if row["reference_on"] != row["n_particles"]:
            what += f", timed on {row['reference_on']} candidates, scaled"
        lines.append(f"| {row['kernel']} | {row['n_particles']} | {row['ms']:.3f} | {row['reference_ms']:.1f} | "
                     f"{row['speedup']:.0f}x | {what} |")
    if result.get("startup"):
        s = result["startup"]
        lines += ["", "## Start-up", "",
                  f"- cold (empty numba cache): {s['cold']['total_s']:.2f} s "
                  f"(import {s['cold']['import_s']:.2f} s, first frames incl. compilation "
                  f"{s['cold']['first_frames_s']:.2f} s)",
                  f"- warm (on-disk cache): {s['warm_best']['total_s']:.2f} s "
                  f"(import {s['warm_best']['import_s']:.2f} s, first frames {s['warm_best']['first_frames_s']:.2f} s)",
                  f"- measured as: {s['what']}"]
    lines += ["", f"Bench wall time: {result['bench_seconds']:.0f} s.", ""]
    return "\n".join(lines)


def run(data: Path | None, out_dir: Path, n_threads: int | None = None, counts=PARTICLE_COUNTS, repeats: int = 15,
        reference_repeats: int = 2, synthetic_frames: int = 120, real_frames: int | None = REAL_FRAMES,
        e2e_rounds: int = 3, startup: bool = True, reference_subset: dict | None = None,
        thread_study: bool = True, stage_frames: int = 60, grid: bool = True, dask: str | None = None,
        wait_quiet_s: float = WAIT_QUIET_S, probe_cores: bool = True, otb_results: Path | None = None) -> dict:
    from nrmlc import io
    from nrmlc.data import open_sequence, synthetic_suite

    global WAIT_QUIET_S
    WAIT_QUIET_S = wait_quiet_s
    _quiet_log.clear()
    began = time.perf_counter()
    if n_threads is not None:  # otherwise the API's own configuration, untouched
        from nrmlc.config import set_threads

        set_threads(n_threads)
    result = {"load_before": _load(probe_cores), "threads_option": n_threads}
    synthetic = synthetic_suite(n_frames=synthetic_frames)[0]
    car4 = None
    if data is not None:
        if (Path(data) / "Car4").is_dir():
            car4 = open_sequence(Path(data) / "Car4")
        else:
            print(f"  (no Car4 under {data}; the real-data rows are skipped)", flush=True)
    stage_sequence = car4 if car4 is not None else synthetic
    result["stage_sequence"] = stage_sequence.name
    print(f"stages of a frame ({stage_sequence.name}):", flush=True)
    result["stages"] = bench_stages(stage_sequence, counts, warm_frames=min(20, len(stage_sequence) // 3),
                                    timed_frames=stage_frames)
    print("end to end:", flush=True)
    result["end_to_end"] = bench_end_to_end(synthetic, None, e2e_rounds)
    if car4 is not None:
        result["end_to_end"] += bench_end_to_end(car4, real_frames, e2e_rounds)
    result["matlab_fps"] = matlab_fps(car4, otb_results) if car4 is not None else {}
    result["threads"] = None
    if thread_study:
        print("thread set-ups:", flush=True)
        result["threads"] = bench_threads(Path(car4.path) if car4 is not None else None)
    print(f"kernels against their references ({synthetic.name}):", flush=True)
    result["kernels"] = bench_kernels(synthetic, counts, repeats, reference_repeats,
                                      warm_frames=min(25, synthetic_frames - 1),
                                      reference_subset=reference_subset or REFERENCE_SUBSET)
    result["startup"] = None
    if startup:
        print("start-up:", flush=True)
        result["startup"] = bench_startup()
    result["grid"] = None
    if grid:
        print("grid throughput:", flush=True)
        result["grid"] = bench_grid(os.cpu_count() or 1, dask)
    result["machine"] = machine_info()
    result["load_after"] = _load(probe_cores)
    result["quiet"] = {"wait_limit_s": wait_quiet_s, "quiet_share": QUIET_SHARE, "sections": list(_quiet_log)}
    result["summary"] = _summary(result)
    result["bench_seconds"] = time.perf_counter() - began
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    io.write_text(out_dir / "bench.json", json.dumps(result, indent=1, default=str))
    markdown = _markdown(result)
    io.write_text(out_dir / "bench.md", markdown)
    print(markdown)
    print(f"wrote {out_dir / 'bench.md'} and bench.json", flush=True)
    return result


#: Where ``make more-sequences`` lays out the OTB benchmark's result files (their fps: the MATLAB originals').
DEFAULT_OTB_RESULTS = REPO_ROOT.parent / "devdata" / "otb_results"


def matlab_fps(sequence, otb_results: Path | None) -> dict:
    """The fps the OTB benchmark's files record for the lineage's MATLAB originals on ``sequence``
    (their 2013 machine, not this one: context, not a ratio); {} without the files."""
    from nrmlc.lineage import TRACKERS
    from nrmlc.workbench.otb_results import has_otb_results, otb_result_boxes

    folder = DEFAULT_OTB_RESULTS if otb_results is None else Path(otb_results)
    if not folder.is_dir() or not has_otb_results(folder):
        return {}
    found = {}
    for name in TRACKERS:
        boxes, fps, _ = otb_result_boxes(folder, name.upper(), sequence)
        if boxes is not None and fps is not None:
            found[name.upper()] = float(fps)
    return found


def default_bench_data() -> Path | None:
    """``$NRMLC_DATA`` or ``../shared/data/sequences``, where it holds Car4 (the README's headline)."""
    from nrmlc.config import data_root_from_env

    for root in (data_root_from_env(), REPO_ROOT.parent / "shared" / "data" / "sequences"):
        if root and (Path(root) / "Car4").is_dir():
            return Path(root)
    return None


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", type=Path, default=None,
                        help="folder of real sequences (uses <data>/Car4; default: $NRMLC_DATA, else "
                             "../shared/data/sequences where it holds Car4, else a synthetic sequence only)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT,
                        help="folder for bench.md and bench.json (default: out/figures, git-ignored; "
                             "'figures' replaces the committed report)")
    parser.add_argument("--threads", type=int, default=None,
                        help="call nrmlc.config.set_threads(THREADS) first (default: leave the API's configuration)")
    parser.add_argument("--dask", default=None, metavar="SCHEDULER_ADDRESS",
                        help="also run the grid-throughput runs on this Dask cluster (needs the cluster extra)")
    parser.add_argument("--wait-quiet", type=float, default=WAIT_QUIET_S, metavar="SECONDS",
                        help=f"before each measured section wait up to SECONDS for the machine to be "
                             f"{QUIET_SHARE * 100:.0f}%% idle (default {WAIT_QUIET_S:.0f}; 0: never wait); the waits and the "
                             "idle share are reported")
    parser.add_argument("--quick", action="store_true",
                        help="tiny settings (for tests): N=50, few repeats, no start-up or thread study")
    args = parser.parse_args(argv)
    if args.data is None and not args.quick:
        args.data = default_bench_data()
        if args.data is None:
            print("bench: no real data with Car4 (the README's headline is Car4: "
                  "make bench DATA=../shared/data/sequences); timing the synthetic sequence only", flush=True)
        else:
            print(f"bench: Car4 from {args.data}", flush=True)
    if args.quick:
        return run(args.data, args.out, args.threads, counts=(50,), repeats=2, reference_repeats=1,
                   synthetic_frames=12, real_frames=12, e2e_rounds=1, startup=False,
                   reference_subset={"regularized": 10, "plain": 10, "constrained": 4}, thread_study=False,
                   stage_frames=4, grid=False, wait_quiet_s=0.0, probe_cores=False)
    return run(args.data, args.out, args.threads, dask=args.dask, wait_quiet_s=args.wait_quiet)


if __name__ == "__main__":
    main()
