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
from nrmlc.tracker.run import track_sequence
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
    expected = {"warp", "distances+knn", "tracker frame regularized"}
    expected |= {f"{name} {mode}" for name in ("coding", "weights+confidence") for mode in bench.MODES}
    assert expected <= kernels
    for row in data["kernels"]:
        assert row["ms"] > 0
        if row["kernel"] != "tracker frame regularized" and row["kernel"].startswith("tracker frame"):
            continue
        assert row["reference_ms"] > 0 and row["speedup"] > 0
    trackers = {row["tracker"] for row in data["end_to_end"]}
    assert {"NRMLC regularized", "NRMLC constrained", "NRMLC plain", "OpenCV TrackerMIL"} <= trackers
    assert all(row["fps_tracking"] > 0 for row in data["end_to_end"])
    assert data["machine"]["threads"] >= 1 and data["machine"]["numpy"]
    markdown = (tmp_path / "bench.md").read_text()
    assert "| warp |" in markdown and "TrackerMIL" in markdown
