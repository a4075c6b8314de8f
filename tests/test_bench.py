"""``make bench`` (quick settings) and the thread-count determinism of the tracker."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent

_TRACK_CHILD = r"""
import sys
import numpy as np
from nrmlc.config import set_threads
n_threads = set_threads(int(sys.argv[1]))
from nrmlc.data import synthetic_suite
from nrmlc.tracker.params import TrackerParams
from nrmlc.tracker.loop import track_sequence
sequence = synthetic_suite(n_frames=21)[0]
lines = [str(n_threads)]
for coding in ("regularized", "constrained"):
    result = track_sequence(sequence, TrackerParams(coding=coding), seed=3, n_frames=21)
    lines.append(result.boxes.tobytes().hex())
    lines.append(result.diagnostics["confidence"].tobytes().hex())
print("\n".join(lines))
"""


def _track_in_subprocess(n_threads: int) -> list[str]:
    # Every pool is sized by the environment too, as a user would do it.
    env = dict(os.environ, NUMBA_NUM_THREADS=str(n_threads), OPENBLAS_NUM_THREADS=str(n_threads),
               OMP_NUM_THREADS=str(n_threads))
    output = subprocess.run([sys.executable, "-c", _TRACK_CHILD, str(n_threads)], env=env, cwd=str(REPO_ROOT),
                            capture_output=True, text=True, check=True, timeout=600)
    return output.stdout.strip().splitlines()


def test_same_seed_same_boxes_with_one_or_two_threads():
    # 20 tracked frames (template updates included) in fresh processes whose numba,
    # OpenBLAS and OpenCV pools have 1 and 2 threads: boxes and confidences must be
    # the same bits.
    one = _track_in_subprocess(1)
    two = _track_in_subprocess(2)
    assert one[0] == "1" and two[0] == "2"
    assert len(one) == len(two) == 5
    assert one[1:] == two[1:]


def test_quick_bench_writes_json_and_markdown(tmp_path):
    from experiments import bench

    bench.main(["--quick", "--out", str(tmp_path)])
    data = json.loads((tmp_path / "bench.json").read_text())
    kernels = {row["kernel"] for row in data["kernels"]}
    expected = {"warp", "distances+knn"} | {f"{name} {mode}" for name in ("coding", "weights+confidence")
                                            for mode in bench.MODES}
    assert expected <= kernels
    assert all(row["ms"] > 0 and row["reference_ms"] > 0 and row["speedup"] > 0 for row in data["kernels"])
    stages = {row["stage"]: row for row in data["stages"]}
    assert {"warp (particles)", "product (sgemm)", bench.OTHER_STAGE, "whole frame"} <= set(stages)
    # Everything after the product: the four kernels, or the one pass that fuses them.
    four = {"nearest templates", "coding", "weights + confidence"}
    assert four <= set(stages) or bench.ONE_PASS_STAGE in stages
    for name, row in stages.items():
        if name != bench.OTHER_STAGE:
            assert row["floor_ms"] > 0
        if not row.get("part") and name != bench.OTHER_STAGE:
            assert row["ms"] > 0
    if bench.ONE_PASS_STAGE in stages:  # its parts, each timed alone, are listed under it
        assert sum(1 for row in data["stages"] if row.get("part")) == 4
    # The stages and what lies between them add up to the frame.
    frame = stages["whole frame"]["ms"]
    parts = [row["ms"] for name, row in stages.items() if name != "whole frame" and not row.get("part")]
    assert abs(sum(parts) - frame) < 1e-6 * frame + 1e-9
    trackers = {row["tracker"] for row in data["end_to_end"]}
    assert {"NRMLC regularized", "NRMLC constrained", "NRMLC plain", "OpenCV TrackerMIL"} <= trackers
    assert any(name.startswith("NRMLC generative_weight=") for name in trackers)  # the switch's cost
    assert any(name.startswith("NRMLC second_expert=") for name in trackers)  # the second expert's cost
    assert all(row["fps_tracking"] > 0 for row in data["end_to_end"])
    assert data["machine"]["numba_threads"] >= 1 and data["machine"]["numpy"]
    assert data["threads_option"] is None  # the API's own configuration, untouched
    markdown = (tmp_path / "bench.md").read_text()
    assert "| warp |" in markdown and "TrackerMIL" in markdown and "## Stages of a frame" in markdown
    summary = "\n".join(data["summary"])
    assert "constrained is" in summary and "(default parameters" in summary
    assert "second_expert=off is" in summary  # one tracker against the default's pair
    assert bench.PARTNER_ALONE in trackers and "the partner adds" in summary  # the pair against its experts alone
    assert "slower by" not in markdown and "faster by" not in markdown


def test_ratios_are_in_plain_words():
    from experiments.bench import compare

    assert compare("constrained", 90.0, "regularized", 117.0) == "constrained is 1.30x slower than regularized"
    assert compare("constrained", 117.0, "regularized", 90.0) == "constrained is 1.30x faster than regularized"
    assert compare("NRMLC", 180.0, "TrackerMIL", 18.0) == "NRMLC is 10.00x faster than TrackerMIL"
    assert "as fast as" in compare("a", 100.0, "b", 100.2)


def test_bench_writes_out_figures_by_default_not_the_committed_report():
    from experiments import bench

    assert bench.DEFAULT_OUT == REPO_ROOT / "out" / "figures"
    assert "out/" in (REPO_ROOT / ".gitignore").read_text().splitlines(), "out/ must be git-ignored"


def test_bench_sets_the_lineage_beside_the_papers_matlab_fps():
    from experiments import bench

    rows = [{"sequence": "Car4", "tracker": f"IVT {bench.LINEAGE_SUFFIX}", "fps_tracking": 32.82},
            {"sequence": "synth-01", "tracker": f"L1 {bench.LINEAGE_SUFFIX}", "fps_tracking": 50.0},
            {"sequence": "Car4", "tracker": "OpenCV TrackerMIL", "fps_tracking": 20.0}]
    (line,) = [text for text in bench._reported_matlab_lines({"end_to_end": rows}) if text]
    # Table II's IVT column is 16.41 fps; L1 ran on another sequence only, so it has no live run on Car4
    assert "IVT 16.41 fps (live here: 32.8, 2x)" in line
    assert "LSK 6.57 fps (no live run)" in line and "L1 0.28 fps (no live run)" in line
    assert "MIL" not in line and "KCF" not in line
    assert bench._reported_matlab_lines({"end_to_end": rows[1:]}) == []


def test_the_pair_s_cost_is_set_against_its_experts_run_alone():
    from experiments.bench import PARTNER_ALONE, _pair_cost_line

    rows = {("Car4", "NRMLC second_expert=off"): {"fps_tracking": 100.0},
            ("Car4", PARTNER_ALONE): {"fps_tracking": 200.0}}
    line = _pair_cost_line(rows, "Car4", 80.0)[0]
    assert "takes 12.5 ms" in line and "10.0 (the first" in line and "+ 5.0 (the partner) = 15.0 ms" in line
    assert "adds 2.5 ms to the first expert, against 5.0 ms alone" in line
    assert _pair_cost_line({}, "Car4", 80.0) == []
