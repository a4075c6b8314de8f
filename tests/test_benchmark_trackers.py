"""``nrmlc benchmark --tracker package.module:factory``: the benchmark knows trackers only through
``init(frame, box)`` / ``update(frame) -> box`` (nrmlc.workbench.trackers), and a user's tracker is
run, resumed, scored and refused as NRMLC is. NRMLC's runs keep their run-cache keys.

The user's trackers are a module written to a temporary folder put on ``sys.path`` (in this
process) or ``PYTHONPATH`` (for the command in a subprocess).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from nrmlc.cli import main
from nrmlc.data import read_box_file, synthetic_suite, write_otb_sequence
from nrmlc.errors import DataError, ParameterError
from nrmlc.tracker.params import TrackerParams
from nrmlc.workbench.benchmark import run_benchmark
from nrmlc.workbench.jobs import RunSpec
from nrmlc.workbench.metrics import evaluate
from nrmlc.workbench.run_cache import RunCache
from nrmlc.workbench.trackers import ImportedTracker, InitUpdateJob, NRMLCEntry, TrackerFailed

MODULE = "nrmlc_test_user_trackers"
SOURCE = textwrap.dedent('''
    """Trackers of a user: init(frame, box) / update(frame) -> box, nothing of nrmlc."""
    import math

    import numpy as np


    class Still:
        """Says the initial box on every frame; checks it is given BGR uint8 frames."""

        def init(self, frame, box):
            if not (isinstance(frame, np.ndarray) and frame.dtype == np.uint8 and frame.ndim == 3
                    and frame.shape[2] == 3):
                raise TypeError(f"not a BGR frame: {type(frame).__name__} {getattr(frame, 'shape', '')}")
            self.box = [float(v) for v in box]

        def update(self, frame):
            return tuple(self.box)


    def still():
        return Still()


    class Drift(Still):
        """Moves the box ``seed`` px right per frame."""

        def __init__(self, seed):
            self.seed = seed

        def update(self, frame):
            self.box[0] += self.seed
            return list(self.box)


    def drifting(seed=0):
        return Drift(seed)


    class NaNBox(Still):
        def update(self, frame):
            return [math.nan, 1.0, 2.0, 3.0]


    class Three(Still):
        def update(self, frame):
            return (1.0, 2.0, 3.0)


    def nan_box():
        return NaNBox()


    def three():
        return Three()


    class OnlyInit:
        def init(self, frame, box):
            pass


    def no_update():
        return OnlyInit()


    def broken():
        raise RuntimeError("no GPU here")


    not_callable = 5
''')


@pytest.fixture(scope="module")
def user_folder(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("user")
    (folder / f"{MODULE}.py").write_text(SOURCE)
    return folder


@pytest.fixture
def user(user_folder, monkeypatch) -> Path:
    monkeypatch.syspath_prepend(str(user_folder))
    yield user_folder
    sys.modules.pop(MODULE, None)


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("data")
    for sequence in synthetic_suite(n_frames=6, size=(48, 64), n_sequences=2):
        write_otb_sequence(sequence, root / sequence.name)
    return root


def _bench(data, out, cache, tracker, **options) -> tuple[dict, list[str]]:
    lines: list[str] = []
    summary = run_benchmark(data, out, cache=RunCache(cache), progress=False, log=lines.append,
                            tracker=tracker, **options)
    return summary, lines


def _subprocess(args, user_folder, cwd) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(user_folder),
                                                                    os.environ.get("PYTHONPATH", "")])))
    return subprocess.run([sys.executable, "-m", "nrmlc", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)


# ------------------------------------------------------------------ a user's tracker, benchmarked
def test_a_user_tracker_is_benchmarked_resumed_and_scored_as_evaluate_scores_it(user, data, tmp_path, capsys):
    out, cache = tmp_path / "Still", tmp_path / "cache"
    entry = ImportedTracker(f"{MODULE}:still")
    # Two worker processes: they find the module through the parent's sys.path.
    summary, lines = _bench(data, out, cache, entry, seeds=(0, 1), jobs=2)
    assert "0 finished, 4 to run" in lines[0]
    names = ["synth-01", "synth-02"]
    for name in names:
        truth = read_box_file(data / name / "groundtruth_rect.txt")
        for path in (out / f"{name}.txt", out / "seeds" / "1" / f"{name}.txt"):
            boxes = read_box_file(path)
            assert boxes.shape == (6, 4) and np.allclose(boxes, truth[0])  # the initial box, every frame
    manifest = json.loads((out / "benchmark.json").read_text())
    assert manifest["settings"] == {"tracker": f"{MODULE}:still", "max_frames": None, "data": str(data.resolve())}
    assert summary["settings"] == manifest["settings"]
    assert sorted(p.parent.name for p in cache.rglob("*.npz")) == ["imported"] * 4
    rows = {(r["sequence"], r["seed"]): r for r in summary["runs"]}
    assert set(rows) == {(n, s) for n in names for s in (0, 1)}
    for (name, seed), row in rows.items():
        truth = read_box_file(data / name / "groundtruth_rect.txt")
        scores = evaluate(read_box_file(out / ("" if seed == 0 else "seeds/1") / f"{name}.txt"), truth)
        assert row["success_auc"] == pytest.approx(scores.success_auc) and row["fps"] > 0
    assert len((out / "summary.csv").read_text().splitlines()) == 1 + 4

    # nrmlc evaluate on the folder gives the summary's scores.
    assert main(["evaluate", "--results", str(out), "--data", str(data), "--all-seeds", "--json"]) == 0
    scored = json.loads(capsys.readouterr().out)["trackers"][0]
    for name in names:
        for key in ("success_auc", "precision_20", "mean_overlap", "mean_center_error"):
            assert scored["per_sequence"][name][key] == pytest.approx(summary["per_sequence"][name][key])
    assert scored["success_auc"] == pytest.approx(summary["mean_over_sequences"]["success_auc"])

    # A rerun says all is finished and computes nothing, even from an empty cache.
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("*.txt")}
    again, lines = _bench(data, out, tmp_path / "empty", ImportedTracker(f"{MODULE}:still"), seeds=(0, 1), jobs=1)
    assert "4 finished, 0 to run" in lines[0]
    assert not (tmp_path / "empty").exists() or not any((tmp_path / "empty").rglob("*.npz"))
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.txt")} == stamps
    assert again["runs"] == summary["runs"]
    # Another folder on the same cache: every run comes from it.
    _, lines = _bench(data, tmp_path / "Again", cache, ImportedTracker(f"{MODULE}:still"), seeds=(0, 1), jobs=1)
    assert "0 finished, 4 to run (4 of them from the run cache" in lines[0]


def test_a_factory_with_a_seed_is_called_with_each_seed(user, data, tmp_path):
    out = tmp_path / "Drift"
    _bench(data, out, tmp_path / "cache", ImportedTracker(f"{MODULE}:drifting"), seeds=(0, 2), jobs=1,
           max_frames=4)
    for seed, folder in ((0, out), (2, out / "seeds" / "2")):
        boxes = read_box_file(folder / "synth-01.txt")
        assert len(boxes) == 4 and np.allclose(np.diff(boxes[:, 0]), seed)
    settings = json.loads((out / "benchmark.json").read_text())["settings"]
    assert settings["tracker"] == f"{MODULE}:drifting" and settings["max_frames"] == 4


def test_imported_run_keys(user, data, user_folder):
    from nrmlc.data import open_sequence

    sequence = open_sequence(data / "synth-01")
    entry = ImportedTracker(f"{MODULE}:still")
    job = entry.job(sequence, 0, None)
    assert isinstance(job, InitUpdateJob) and job.folder == "imported" and not job.uses_kernels
    key = job.key("v")
    assert job.key("another code version") == key  # our code does not decide a user's boxes
    assert entry.job(sequence, 1, None).key("v") != key
    assert entry.job(sequence, 0, 5).key("v") != key
    assert ImportedTracker(f"{MODULE}:drifting").job(sequence, 0, None).key("v") != key
    assert entry.job(open_sequence(data / "synth-02"), 0, None).key("v") != key
    # Editing the factory's module recomputes its runs.
    path = user_folder / f"{MODULE}.py"
    path.write_text(SOURCE + "\n# edited\n")
    try:
        assert ImportedTracker(f"{MODULE}:still").job(sequence, 0, None).key("v") != key
    finally:
        path.write_text(SOURCE)


# ------------------------------------------------------------------ refusals
@pytest.mark.parametrize("spec, says", [
    ("nocolon", "expected package.module:factory"),
    (":still", "expected package.module:factory"),
    ("nrmlc_no_such_module_here:make", "no module named 'nrmlc_no_such_module_here'"),
    (f"{MODULE}:absent", f"module {MODULE} has no attribute 'absent'"),
    (f"{MODULE}:not_callable", "not_callable is a int, not a callable"),
    (f"{MODULE}:no_update", "returned a OnlyInit, which has no update() method"),
    (f"{MODULE}:broken", "broken() raised RuntimeError: no GPU here"),
])
def test_a_bad_tracker_is_one_error_line(spec, says, user, data, tmp_path, capsys):
    code = main(["benchmark", str(data), "--out", str(tmp_path / "R"), "--cache", str(tmp_path / "c"),
                 "--tracker", spec])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith(f"error: --tracker {spec!r}: "), err
    assert says in err, err
    assert not (tmp_path / "R").exists()


def test_a_bad_tracker_in_a_subprocess_is_one_line_and_exit_2(user_folder, data, tmp_path):
    done = _subprocess(["benchmark", data, "--out", tmp_path / "R", "--tracker", f"{MODULE}:no_update"],
                       user_folder, tmp_path)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr
    assert "has no update() method" in done.stderr


def test_tracker_and_nrmlc_parameters_are_refused_together(user, data, tmp_path, capsys):
    for extra in (["--param", "n_particles=50"], ["--preset", "paper"]):
        code = main(["benchmark", str(data), "--out", str(tmp_path / "R"), "--tracker", f"{MODULE}:still", *extra])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and extra[0] in err and "--tracker" in err, err
    with pytest.raises(ParameterError, match="not both"):
        run_benchmark(data, tmp_path / "R", TrackerParams(), tracker=ImportedTracker(f"{MODULE}:still"))


@pytest.mark.parametrize("factory, shown", [("nan_box", "[nan, 1.0, 2.0, 3.0]"), ("three", "(1.0, 2.0, 3.0)")])
def test_a_tracker_returning_no_box_is_refused_by_name(factory, shown, user, data, tmp_path):
    out = tmp_path / "R"
    with pytest.raises(TrackerFailed) as refused:
        _bench(data, out, tmp_path / "cache", ImportedTracker(f"{MODULE}:{factory}"), jobs=1, sequences=["synth-01"])
    message = str(refused.value)
    assert message == (f"--tracker {MODULE}:{factory}: update() on frame 2 of synth-01 returned {shown}, "
                       f"not a box (4 finite numbers x, y, w, h)")
    assert not list(out.glob("*.txt")) and not list((tmp_path / "cache").rglob("*.npz"))


def test_a_folder_of_another_tracker_is_refused(user, data, tmp_path):
    out = tmp_path / "R"
    _bench(data, out, tmp_path / "cache", ImportedTracker(f"{MODULE}:still"), jobs=1, max_frames=3)
    before = (out / "synth-01.txt").read_bytes()
    with pytest.raises(DataError, match=rf"tracker '{MODULE}:still' there, '{MODULE}:drifting' now.*another --out"):
        _bench(data, out, tmp_path / "cache", ImportedTracker(f"{MODULE}:drifting"), jobs=1, max_frames=3)
    with pytest.raises(DataError, match=rf"tracker '{MODULE}:still' there, NRMLC now"):
        _bench(data, out, tmp_path / "cache", NRMLCEntry(), jobs=1, max_frames=3)
    assert (out / "synth-01.txt").read_bytes() == before


# ------------------------------------------------------------------ NRMLC: as before
def test_nrmlc_entry_keeps_the_settings_and_the_run_keys(data):
    from nrmlc.data import open_sequence

    params = TrackerParams(n_particles=50)
    entry = NRMLCEntry(params)
    assert entry.settings() == {"params": params.as_dict()}  # what benchmark.json held before entries
    sequence = open_sequence(data / "synth-01")
    for seed, n_frames in ((0, None), (3, 5)):
        job = entry.job(sequence, seed, n_frames)
        assert type(job) is RunSpec and job.folder == "" and job.label == "synth-01"
        assert job.key("0123456789abcdef") == RunSpec(sequence, params, seed, n_frames).key("0123456789abcdef")
        assert job.description("v") == RunSpec(sequence, params, seed, n_frames).description("v")
    with pytest.raises(ParameterError, match="params must be a TrackerParams"):
        NRMLCEntry({"n_particles": 50})


def test_the_command_runs_a_user_tracker(user_folder, data, tmp_path):
    args = ["benchmark", data, "--out", tmp_path / "R", "--cache", tmp_path / "cache", "--jobs", "1",
            "--max-frames", "4", "--tracker", f"{MODULE}:still"]
    done = _subprocess(args, user_folder, tmp_path)
    assert done.returncode == 0, done.stderr
    assert "0 finished, 2 to run" in done.stderr and "mean of 2" in done.stdout
    done = _subprocess(args, user_folder, tmp_path)
    assert done.returncode == 0 and "2 finished, 0 to run" in done.stderr, done.stderr


def test_a_manifest_whose_tracker_is_not_text_is_refused_by_name(user, data, tmp_path):
    out = tmp_path / "R"
    _bench(data, out, tmp_path / "cache", ImportedTracker(f"{MODULE}:still"), jobs=1, max_frames=3)
    manifest = json.loads((out / "benchmark.json").read_text())
    manifest["settings"]["tracker"] = 5
    (out / "benchmark.json").write_text(json.dumps(manifest))
    with pytest.raises(DataError, match=r"benchmark.json: not a benchmark manifest \('settings.tracker' must be"):
        _bench(data, out, tmp_path / "cache", ImportedTracker(f"{MODULE}:still"), jobs=1, max_frames=3)
