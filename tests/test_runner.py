"""nrmlc.workbench.run_cache and the jobs, pool and versions behind it: cached, resumable grids of runs.
Work is never lost.

- a grid killed with SIGKILL part-way resumes without recomputing finished
  runs and leaves no corrupt file;
- a changed parameter recomputes exactly the runs that use it; a changed
  code version recomputes everything;
- a run that fails in a process pool does not throw away the runs that finished.
"""
from __future__ import annotations

import concurrent.futures as futures
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import nrmlc.workbench.jobs as jobs
import nrmlc.workbench.pool as pool
import nrmlc.workbench.run_cache as run_cache
import nrmlc.workbench.version as version
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.errors import ParameterError
from nrmlc.tracker.loop import TrackResult
from nrmlc.tracker.params import TrackerParams
from nrmlc.workbench.jobs import RunSpec, sequence_identity
from nrmlc.workbench.progress import Progress
from nrmlc.workbench.run_cache import RunCache
from nrmlc.workbench.version import code_version

REPO_ROOT = Path(__file__).resolve().parent.parent


def tiny_sequence(k: int, n_frames: int = 6) -> SyntheticSequence:
    return SyntheticSequence(SyntheticSpec(
        name=f"tiny-{k}", seed=k, n_frames=n_frames, frame_height=48, frame_width=64, target_width=16,
        target_height=12, translation_amplitude_x=8, translation_amplitude_y=6, n_distractors=1))


def fake_arrays(spec: RunSpec) -> dict:
    n = spec.n_frames or len(spec.sequence)
    return TrackResult(np.full((n, 4), float(spec.seed)), np.zeros((n, 6)), {}, 0.1, 0.2).to_arrays()


@pytest.fixture
def counted(monkeypatch) -> list:
    """Replace the tracking with a fake that records which runs were computed."""
    computed = []

    def fake_execute(spec, threads):
        computed.append(spec.label)
        return fake_arrays(spec)

    monkeypatch.setattr(pool, "execute_job", fake_execute)
    return computed


def grid(params: TrackerParams | None = None) -> list[RunSpec]:
    params = params or TrackerParams()
    return [RunSpec(tiny_sequence(k), params, seed=s, label=f"{k}/{s}") for k in range(2) for s in range(2)]


# ------------------------------------------------------------- invalidation
def test_rerun_computes_nothing(tmp_path, counted):
    cache = RunCache(tmp_path)
    results = cache.run(grid(), jobs=1, progress=False)
    assert sorted(counted) == ["0/0", "0/1", "1/0", "1/1"]
    assert [r.boxes[0, 0] for r in results] == [0, 1, 0, 1]
    counted.clear()
    RunCache(tmp_path).run(grid(), jobs=1, progress=False)
    assert counted == []


def test_changed_parameter_recomputes_exactly_its_runs(tmp_path, counted):
    specs = grid()
    cache = RunCache(tmp_path)
    cache.run(specs, jobs=1, progress=False)
    before = {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("*.npz")}
    changed = list(specs)
    changed[2] = RunSpec(specs[2].sequence, specs[2].params.replace(lam=0.5), seed=specs[2].seed, label="changed")
    keys = [s.key(cache.version) for s in specs]
    new_keys = [s.key(cache.version) for s in changed]
    assert [a != b for a, b in zip(keys, new_keys)] == [False, False, True, False]
    counted.clear()
    cache.run(changed, jobs=1, progress=False)
    assert counted == ["changed"]
    after = {p.name: p.stat().st_mtime_ns for p in tmp_path.glob("*.npz")}
    assert {k: v for k, v in after.items() if k in before} == before  # old files untouched
    assert set(after) - set(before) == {f"{new_keys[2]}.npz"}
    description = json.loads((tmp_path / f"{new_keys[2]}.json").read_text())
    assert description["params"]["lam"] == 0.5 and description["code_version"] == cache.version


def test_changed_code_version_recomputes_everything(tmp_path, counted, monkeypatch):
    RunCache(tmp_path).run(grid(), jobs=1, progress=False)
    counted.clear()
    monkeypatch.setattr(version, "code_version", lambda: "0123456789abcdef")
    cache = RunCache(tmp_path)
    assert cache.version == "0123456789abcdef"
    cache.run(grid(), jobs=1, progress=False)
    assert sorted(counted) == ["0/0", "0/1", "1/0", "1/1"]
    assert len(list(tmp_path.glob("*.npz"))) == 8


def test_runs_read_from_another_numba_target_are_named_and_kept(tmp_path, counted, monkeypatch):
    RunCache(tmp_path).run(grid(), jobs=1, progress=False)
    sidecars = sorted(tmp_path.glob("*.json"))
    assert {json.loads(p.read_text())["computed_for"] for p in sidecars} == {version.numba_target()}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the same target: no warning
        RunCache(tmp_path).run(grid(), jobs=1, progress=False)
    monkeypatch.setattr(version, "numba_target", lambda: "othercpu (host features)")
    counted.clear()
    with pytest.warns(UserWarning, match=r"4 of the cached runs read were computed for another numba target"):
        RunCache(tmp_path).run(grid(), jobs=1, progress=False)
    assert counted == []  # read, not recomputed: the key does not hold the target


def test_library_settings_are_recorded_beside_each_run(tmp_path, monkeypatch):
    monkeypatch.delenv("NPY_DISABLE_CPU_FEATURES", raising=False)
    monkeypatch.delenv("OPENCV_IPP", raising=False)
    monkeypatch.setenv("OPENBLAS_CORETYPE", "Haswell")
    RunCache(tmp_path).run(grid(), jobs=1, progress=False)
    recorded = [json.loads(p.read_text())["library_settings"] for p in tmp_path.glob("*.json")]
    assert len(recorded) == 4 and all(r == {"OPENBLAS_CORETYPE": "Haswell"} for r in recorded)


def _target(monkeypatch, name, features=None):
    """This process as if numba had been told to compile for ``name`` with ``features``; the
    child's outcome is mocked (a real one compiles every kernel, a minute)."""
    import numba
    from llvmlite import binding

    monkeypatch.setattr(numba.config, "CPU_NAME", name)
    monkeypatch.setattr(numba.config, "CPU_FEATURES", features)
    monkeypatch.setattr(binding, "get_host_cpu_name", lambda: "hostcpu")
    monkeypatch.setattr(pool, "_target_problem", None)
    children = []

    def child(returncode, stderr=""):
        def run(argv, **kwargs):
            children.append((argv, kwargs["env"]))
            return subprocess.CompletedProcess(argv, returncode, "", stderr)
        monkeypatch.setattr(pool.subprocess, "run", run)
    return children, child


def test_a_numba_target_this_cpu_cannot_run_is_refused_in_one_line(monkeypatch):
    children, child = _target(monkeypatch, "znver4", "")
    child(-signal.SIGILL)
    with pytest.raises(ParameterError, match=r"NUMBA_CPU_NAME=znver4.*this CPU \(hostcpu\) cannot run.*"
                                                   r"died with SIGILL") as caught:
        pool.check_numba_target()
    assert "\n" not in str(caught.value) and len(children) == 1
    argv, env = children[0]
    assert "warm_up()" in argv[-1] and env["PYTHONPATH"].split(os.pathsep)[0] == str(Path(pool.__file__).parents[2])
    with pytest.raises(ParameterError):  # remembered: not probed twice
        pool.check_numba_target()
    assert len(children) == 1
    children, child = _target(monkeypatch, "znver4", "")
    child(1, "Traceback ...\nImportError: no numba here\n")
    with pytest.raises(ParameterError, match=r"failed \(ImportError: no numba here\)"):
        pool.check_numba_target()


def test_a_numba_target_this_cpu_runs_passes_and_the_own_target_is_not_probed(monkeypatch):
    children, child = _target(monkeypatch, "znver4", "")
    child(0)
    pool.check_numba_target()
    pool.check_numba_target()
    assert len(children) == 1
    for name, features in ((None, None), ("hostcpu", None), ("hostcpu", "")):
        children, child = _target(monkeypatch, name, features)
        child(-signal.SIGILL)
        pool.check_numba_target()  # the host's own code: nothing to probe
        assert children == []
    children, child = _target(monkeypatch, None, "+avx512f")  # features beyond the host's are probed
    child(-signal.SIGILL)
    with pytest.raises(ParameterError, match="SIGILL"):
        pool.check_numba_target()


def test_code_version_follows_the_sources_that_decide_the_boxes(monkeypatch):
    version = code_version()
    assert version == code_version() and len(version) == 16
    original = Path.read_bytes
    for name in ("coding.py", "algorithm.py", "sequence.py", "synthetic.py", "geometry.py"):
        for addition, changes in ((b"\n# a comment", False), (b'\n"""a docstring"""\n\n', False),
                                  (b"\nedited = 1", True), (b'\nedited = "# not a comment"', True)):
            def edited(self, name=name, addition=addition):
                return original(self) + (addition if self.name == name else b"")

            monkeypatch.setattr(Path, "read_bytes", edited)
            assert (code_version() != version) == changes, (name, addition)


def test_executable_text_leaves_out_comments_docstrings_and_blank_lines():
    source = ('"""The module."""\nimport math  # why\n\n\ndef f(x):\n    """Doc, \u00e9."""  # both\n'
              '    # a whole line\n    y = "a # b"; "c"\n    return x + 1   \n')
    assert version.executable_text(source) == 'import math\ndef f(x):\n    y = "a # b";\n    return x + 1'
    assert version.executable_text(source.replace("x + 1", "x + 2")) != version.executable_text(source)


def test_run_keys_are_pinned():
    """The key of a tracking run must not move with refactors: a real-data grid is ~40 min."""
    spec = RunSpec(tiny_sequence(0), TrackerParams(), seed=3, n_frames=5, label="not part of the key")
    description = spec.description("0123456789abcdef")
    assert description == {"sequence": sequence_identity(spec.sequence), "sequence_name": "tiny-0",
                           "params": TrackerParams().as_dict(), "seed": 3, "n_frames": 5,
                           "code_version": "0123456789abcdef", "epoch": jobs.CACHE_EPOCH}
    text = json.dumps(description, sort_keys=True, default=str)
    assert spec.key("0123456789abcdef") == hashlib.sha256(text.encode()).hexdigest()[:24]
    # The hash of a fixed description, pinned literally.
    fixed = {"sequence": "folder:/data/Car4:Car4:659", "sequence_name": "Car4", "params": {"lam": 1.0},
             "seed": 0, "n_frames": None, "code_version": "0123456789abcdef"}
    assert jobs.description_key(fixed) == "c11d3c395e02361a13af561a"
    from experiments.instrumented import DiagnosticRun

    assert DiagnosticRun(tiny_sequence(0), recentre_every=10).description("v")["recentre_every"] == 10
    assert "recentre_every" not in DiagnosticRun(tiny_sequence(0)).description("v")
    assert DiagnosticRun(tiny_sequence(0)).key("v") == RunSpec(tiny_sequence(0)).key("v")


def test_every_parameter_and_the_epoch_are_in_the_key(monkeypatch):
    """A run's key holds every parameter and the cache epoch: changing either gives another key."""
    before = RunSpec(tiny_sequence(0), TrackerParams(), seed=0).key("v")
    assert jobs.params_for_key(TrackerParams()) == TrackerParams().as_dict()
    assert RunSpec(tiny_sequence(0), TrackerParams(redetect_count=0), seed=0).key("v") != before
    monkeypatch.setattr(jobs, "CACHE_EPOCH", jobs.CACHE_EPOCH + 1)
    assert RunSpec(tiny_sequence(0), TrackerParams(), seed=0).key("v") != before


def test_frames_tracked_is_one_rule():
    sequence = tiny_sequence(0, n_frames=6)
    assert [jobs.frames_tracked(sequence, n) for n in (None, 0, 3, 6, 100)] == [6, 1, 3, 6, 6]
    assert RunSpec(sequence, n_frames=4).frames() == 4


def test_initial_box_override_is_part_of_the_key():
    sequence = tiny_sequence(0)
    plain = RunSpec(sequence)
    moved = RunSpec(sequence.with_init_box(sequence.init_box + [1, 0, 0, 0]))
    assert plain.key("v") != moved.key("v")
    assert "init_box" not in sequence_identity(sequence)  # ordinary runs keep their keys
    assert RunSpec(sequence.with_init_box(sequence.init_box + [1, 0, 0, 0])).key("v") == moved.key("v")


def test_failed_store_leaves_the_run_missing(tmp_path, counted, monkeypatch):
    spec = grid()[0]
    cache = RunCache(tmp_path)

    def broken(handle, **arrays):
        handle.write(b"PK partial")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(run_cache.io.np, "savez_compressed", broken)
    # run() hands the computed run back all the same (its caller keeps it), with one warning ...
    with pytest.warns(UserWarning, match=r"cannot store runs in the run cache \(.*No space left on device"):
        [result] = cache.run([spec], jobs=1, progress=False)
    assert result.boxes.shape == (6, 4) and counted == [spec.label]
    assert not cache.has(spec) and list(tmp_path.iterdir()) == []
    # ... ensure(), which returns no results, stops with the error.
    with pytest.raises(OSError):
        cache.ensure([spec], jobs=1, progress=False)
    monkeypatch.undo()
    assert not cache.has(spec) and list(tmp_path.iterdir()) == []
    monkeypatch.setattr(pool, "execute_job", lambda spec, threads: fake_arrays(spec))
    assert cache.run([spec], jobs=1, progress=False)[0].boxes.shape == (6, 4)


def test_pool_failure_keeps_the_finished_runs(tmp_path, monkeypatch):
    """One run raises: the others that finish are still stored, and the error is raised."""
    def execute(spec, threads):
        if spec.label == "0/1":
            time.sleep(0.02)  # let every worker thread pick up its run before the failure arrives
            raise RuntimeError("boom")
        time.sleep(0.05)
        return fake_arrays(spec)

    monkeypatch.setattr(pool, "execute_job", execute)
    specs = grid()
    cache = RunCache(tmp_path)
    with futures.ThreadPoolExecutor(max_workers=4) as executor:  # all four start at once
        with pytest.raises(RuntimeError, match="boom"):
            cache.run(specs, executor=executor, progress=False)
    assert [cache.has(s) for s in specs] == [True, False, True, True]


def test_each_run_is_handed_over_as_soon_as_it_is_there(tmp_path, counted):
    """on_result sees the runs read from the cache first, then each computed one; one that the
    caller fails to keep ends the batch like a failed run, and the runs computed are still stored."""
    specs = grid()
    cache = RunCache(tmp_path)
    cache.run(specs[:1], jobs=1, progress=False)
    seen = []
    cache.run(specs, jobs=1, progress=False, on_result=lambda job, result: seen.append((job.label, result.boxes[0, 0])))
    assert seen == [("0/0", 0), ("0/1", 1), ("1/0", 0), ("1/1", 1)]

    def refuse(job, result):
        if job.label == "1/1":
            raise OSError(28, "No space left on device")

    other = RunCache(tmp_path / "other")
    with futures.ThreadPoolExecutor(max_workers=2) as executor:
        with pytest.raises(OSError, match="No space left"):
            other.run(specs, executor=executor, progress=False, on_result=refuse)
    assert other.has(specs[3])  # stored before it was handed over


# ------------------------------------------------------ killed and resumed
GRID_SCRIPT = """
import sys, time
import nrmlc.workbench.jobs as jobs
import nrmlc.workbench.pool as pool
import nrmlc.workbench.run_cache as run_cache
import nrmlc.workbench.version as version
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.tracker.params import TrackerParams

computed = []
real_execute = pool.execute_job
def execute(spec, threads):
    computed.append(spec.label)
    time.sleep(float(sys.argv[2]))  # long enough to be killed part-way
    return real_execute(spec, threads)
pool.execute_job = execute
version.code_version = lambda: "fixed"  # what is tested here is resumption, not source edits

params = TrackerParams(n_particles=30, n_positive=10, n_negative=20, max_positive=20)
specs = [jobs.RunSpec(SyntheticSequence(SyntheticSpec(
             name=f"tiny-{k}", seed=k, n_frames=6, frame_height=48, frame_width=64, target_width=16,
             target_height=12, translation_amplitude_x=8, translation_amplitude_y=6, n_distractors=1)),
             params, seed=0, label=f"tiny-{k}") for k in range(4)]
results = run_cache.RunCache(sys.argv[1]).run(specs, jobs=1, progress=False)
assert len(results) == 4
print("computed", len(computed), *computed)
"""


def run_grid(cache: Path, delay: float, **kwargs):
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), PYTHONHASHSEED="0")
    return subprocess.Popen([sys.executable, "-c", GRID_SCRIPT, str(cache), str(delay)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)


def test_killed_grid_resumes_without_recomputing(tmp_path):
    cache = tmp_path / "cache"
    process = run_grid(cache, 0.5)
    deadline = time.monotonic() + 120
    try:
        while not list(cache.glob("*.npz")):
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline, "no result file after 120 s"
            time.sleep(0.01)
    finally:
        process.send_signal(signal.SIGKILL)
        process.communicate(timeout=30)
    assert process.returncode == -signal.SIGKILL

    done = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in cache.glob("*.npz")}
    assert 1 <= len(done) < 4  # killed part-way
    for name in done:  # nothing corrupt under a final name
        with np.load(cache / name) as arrays:
            assert np.isfinite(TrackResult.from_arrays(dict(arrays)).boxes).all()

    process = run_grid(cache, 0.0)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 0, err
    computed = out.split()
    assert computed[:2] == ["computed", str(4 - len(done))]
    assert len(set(computed[2:])) == len(computed[2:])
    after = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in cache.glob("*.npz")}
    assert len(after) == 4
    assert {name: after[name] for name in done} == done  # finished runs were neither recomputed nor rewritten
    for name in after:
        with np.load(cache / name) as arrays:
            result = TrackResult.from_arrays(dict(arrays))
        assert result.boxes.shape == (6, 4) and np.isfinite(result.boxes).all()
        assert (cache / name).with_suffix(".json").is_file() or name in done  # killed between .npz and .json


# ------------------------------------------------------ damaged cache files
@pytest.mark.parametrize("damage", ["truncated", "garbled", "empty"])
def test_damaged_cache_file_counts_as_missing(tmp_path, counted, damage):
    cache = RunCache(tmp_path)
    specs = grid()
    cache.run(specs, jobs=1, progress=False)
    path = cache.path(specs[1])
    data = path.read_bytes()
    if damage == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "garbled":  # a whole zip whose member data is corrupt (CRC fails on reading)
        middle = len(data) // 3
        path.write_bytes(data[:middle] + bytes(b ^ 0xFF for b in data[middle:middle + 64]) + data[middle + 64:])
    else:
        path.write_bytes(b"")
    counted.clear()
    with pytest.warns(UserWarning, match=str(path.name)):
        results = RunCache(tmp_path).run(specs, jobs=1, progress=False)
    assert counted == [specs[1].label]
    assert [r.boxes[0, 0] for r in results] == [0, 1, 0, 1]
    with np.load(path) as arrays:  # rewritten whole
        assert TrackResult.from_arrays(dict(arrays)).boxes.shape == (6, 4)
    counted.clear()
    RunCache(tmp_path).run(specs, jobs=1, progress=False)
    assert counted == []


def test_ensure_recomputes_a_truncated_file(tmp_path, counted):
    cache = RunCache(tmp_path)
    specs = grid()
    cache.ensure(specs, jobs=1, progress=False)
    path = cache.path(specs[0])
    path.write_bytes(path.read_bytes()[:100])
    counted.clear()
    with pytest.warns(UserWarning, match=path.name):
        computed = cache.ensure(specs, jobs=1, progress=False)
    assert computed == [specs[0]] and counted == [specs[0].label]


# -------------------------------------------- process pools and OpenMP
FORK_SCRIPT = """
import sys
import nrmlc.workbench.jobs as jobs
import nrmlc.workbench.pool as pool
import nrmlc.workbench.run_cache as run_cache
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.tracker.params import TrackerParams

if __name__ == "__main__":
    params = TrackerParams(n_particles=30, n_positive=10, n_negative=20, max_positive=20)
    specs = [jobs.RunSpec(SyntheticSequence(SyntheticSpec(
                 name=f"tiny-{k}", seed=k, n_frames=6, frame_height=48, frame_width=64, target_width=16,
                 target_height=12, translation_amplitude_x=8, translation_amplitude_y=6, n_distractors=1)),
                 params, seed=0, label=f"tiny-{k}") for k in range(3)]
    cache = run_cache.RunCache(sys.argv[1])
    # A lone missing run is computed here, in this process: numba's OpenMP threads start.
    cache.run(specs[:1], jobs=2, progress=False)
    pool.execute_job(specs[0], 2)
    # Then a script needs two more runs: a process pool starts after OpenMP was used.
    results = cache.run(specs, jobs=2, progress=False)
    print("ok", len(results))
"""


def test_a_pool_after_openmp_in_this_process_does_not_crash(tmp_path):
    """GNU OpenMP aborts a process that forks after using it; pools must not fork this one."""
    script = tmp_path / "grid.py"
    script.write_text(FORK_SCRIPT)
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), PYTHONHASHSEED="0")
    done = subprocess.run([sys.executable, str(script), str(tmp_path / "cache")], env=env, capture_output=True,
                          text=True, timeout=300)
    assert "fork() called from a process already using GNU OpenMP" not in done.stderr
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["ok", "3"]


def test_default_pool_starts_fresh_processes():
    workers = pool.process_pool(1)
    try:
        assert workers._mp_context.get_start_method() in ("forkserver", "spawn")
    finally:
        workers.shutdown()


# ------------------------------------------------------------- progress
def test_progress_lines_when_not_a_terminal():
    import io

    stream = io.StringIO()
    progress = Progress(300, 3, stream=stream, interval=0.0)
    for _ in range(3):
        progress.update(100, "x")
    progress.close()
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("[runs] started: 0/3 runs, 0/300 frames")
    assert "2/3 runs, 200/300 frames" in lines[2] and "ETA" in lines[2]
    assert lines[-1].startswith("[runs] done: 3/3 runs, 300/300 frames")
    silent = io.StringIO()
    Progress(10, 1, enabled=False, stream=silent).close()
    assert silent.getvalue() == ""


def test_compile_notice_is_given_once_and_only_when_compiling(monkeypatch):
    import io

    monkeypatch.setattr(pool, "warm_up", lambda: None)
    for cached, expected in ((True, ""), (False, "compiling the numba kernels")):
        monkeypatch.setattr(pool, "_kernels_ready", False)
        monkeypatch.setattr(pool, "kernels_cached", lambda cached=cached: cached)
        stream = io.StringIO()
        pool.prepare_kernels(stream)
        pool.prepare_kernels(stream)  # once per process
        text = stream.getvalue()
        assert (expected in text) if expected else text == ""
        if expected:
            assert text.count("compiling") == 1 and "not counted as tracking time" in text
            assert "kernels compiled in" in text


def test_kernels_cached_follows_numba_index_files(tmp_path, monkeypatch):
    package = tmp_path / "nrmlc"
    (package / "__pycache__").mkdir(parents=True)
    source = package / "kern.py"
    source.write_text("from numba import njit\n\n@njit(cache=True)\ndef f(x):\n    return x\n")
    (package / "plain.py").write_text('"""Mentions @njit and cache=True in prose only."""\n')
    monkeypatch.setattr(pool, "__file__", str(package / "pool.py"))
    assert not pool.kernels_cached()
    index = package / "__pycache__" / "kern.f-3.py311.nbi"
    index.write_bytes(b"")
    os.utime(index, (source.stat().st_mtime + 10,) * 2)
    assert pool.kernels_cached()
    os.utime(source, (source.stat().st_mtime + 20,) * 2)  # the source changed after compiling
    assert not pool.kernels_cached()


ORPHAN_SCRIPT = """
import os, sys, time
import nrmlc.workbench.run_cache as run_cache


class Sleeper:
    folder, uses_kernels, label = "", False, "sleeper"

    def __init__(self, k):
        self.k = k

    def key(self, version):
        return f"sleeper-{self.k}"

    def description(self, version):
        return {"k": self.k}

    def frames(self):
        return 1

    def execute(self):
        with open(os.path.join(sys.argv[2], f"{os.getpid()}.pid"), "w") as handle:
            handle.write("running")
        time.sleep(120)
        return {}

    def result(self, arrays):
        return arrays


if __name__ == "__main__":
    run_cache.RunCache(sys.argv[1]).run([Sleeper(0), Sleeper(1)], jobs=2, progress=False)
"""


def test_pool_workers_end_when_their_parent_is_killed(tmp_path):
    """SIGKILL runs no clean-up: the workers must notice on their own, not hold the cores for good."""
    script, pids = tmp_path / "grid.py", tmp_path / "pids"
    script.write_text(ORPHAN_SCRIPT)
    pids.mkdir()
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), PYTHONHASHSEED="0")
    process = subprocess.Popen([sys.executable, str(script), str(tmp_path / "cache"), str(pids)], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while len(list(pids.iterdir())) < 2:
            assert process.poll() is None and time.monotonic() < deadline, "the workers never started"
            time.sleep(0.1)
    finally:
        process.kill()
        process.wait(timeout=30)
    workers = [int(path.stem) for path in pids.iterdir()]

    def alive(pid):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True

    deadline = time.monotonic() + 20
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.2)
    left = [pid for pid in workers if alive(pid)]
    for pid in left:  # do not leave them behind when the test fails
        os.kill(pid, signal.SIGKILL)
    assert not left


def test_negative_shares_are_recorded_only_on_request_and_keyed_apart():
    from nrmlc.data import SyntheticSequence, SyntheticSpec

    sequence = SyntheticSequence(SyntheticSpec(name="shares", seed=0, n_frames=4))
    from experiments.instrumented import DiagnosticRun

    plain = RunSpec(sequence, TrackerParams(n_particles=20), n_frames=4)
    shares = DiagnosticRun(sequence, TrackerParams(n_particles=20), n_frames=4, negative_shares=True)
    assert "negative_shares" not in plain.description("v") and plain.key("v") != shares.key("v")
    without, with_shares = plain.result(plain.execute()), shares.result(shares.execute())
    assert "negative_share_c" not in without.diagnostics
    np.testing.assert_array_equal(without.boxes, with_shares.boxes)
    assert with_shares.diagnostics["negative_share_c"].shape == (4,)
    assert np.all(np.isfinite(with_shares.diagnostics["negative_share_w"][1:]))


def test_every_job_class_follows_the_one_job_contract():
    from experiments.paper.ablation_oracle_gate import OracleGateRun
    from experiments.internals import Collection
    from experiments.peers import LiveSpec
    from experiments.paper.scale_likelihood import ScaleProfile
    from nrmlc.workbench.jobs import CachedJob, Job

    for cls in (RunSpec, OracleGateRun, Collection, LiveSpec, ScaleProfile):
        assert issubclass(cls, CachedJob) and isinstance(cls.folder, str)
    sequence = SyntheticSequence(SyntheticSpec(name="job", seed=0, n_frames=6))
    job = ScaleProfile(sequence, TrackerParams(), 0, max_frames=4)
    assert isinstance(job, Job) and job.frames() == 4 and job.key("v") == jobs.description_key(job.description("v"))


def test_entry_a_job_cannot_read_is_computed_again(tmp_path, monkeypatch):
    """A job with no problem() of its own (a peer run, recorded internals): an entry its result()
    cannot read (a missing array, text where a number is) is damage, not a traceback."""

    class Timed(jobs.CachedJob):
        uses_kernels = False
        n_frames = None
        label = "timed"

        def __init__(self, sequence):
            self.sequence = sequence

        def description(self, version):
            return {"timed": self.sequence.identity}

        def execute(self):
            return {"seconds": np.float64(2.0)}

        def result(self, arrays):
            return float(arrays["seconds"])

    job = Timed(tiny_sequence(0))
    cache = RunCache(tmp_path)
    for stored, said in (({"other": np.zeros(2)}, "KeyError"), ({"seconds": np.array("two")}, "ValueError")):
        cache.path(job).parent.mkdir(parents=True, exist_ok=True)
        np.savez(cache.path(job), **stored)
        with pytest.warns(UserWarning, match=rf"incomplete cache entry \(unreadable: {said}"):
            assert cache.run([job], jobs=1, progress=False) == [2.0]
