"""The lineage's experiments: the fidelity table against the benchmark's files, and NRMLC against its
lineage, on a few synthetic frames."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from experiments.lineage import fidelity, versus
from nrmlc.errors import NrmlcError
from nrmlc.data import open_sequence, synthetic_suite, write_otb_sequence
from nrmlc.testing.otb_files import _save
from nrmlc.workbench.metrics import evaluate

FRAMES = 8


@pytest.fixture(scope="module")
def data_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("lineage-experiments")
    for name, sequence in zip(("Walker", "Runner"), synthetic_suite(n_frames=FRAMES, size=(120, 160), n_sequences=2,
                                                                        seed=5)):
        write_otb_sequence(sequence, root / name)
    return root


def test_compare_is_per_target_on_the_means_over_seeds():
    ours = {"a": [0.5, 0.7], "b": [0.2], "c": [0.4, 0.4, 0.4]}
    theirs = {"a": [0.1], "b": [0.3, 0.3], "c": [0.4]}
    got = versus.compare(ours, theirs, ["a", "b", "c"])
    differences = np.array([0.5, -0.1, 0.0])
    assert got["mean"] == pytest.approx(differences.mean())
    assert got["standard_error"] == pytest.approx(differences.std(ddof=1) / math.sqrt(3))
    assert (got["won"], got["lost"], got["n"]) == (1, 1, 3)


@pytest.mark.parametrize("mean, error, expected", [
    (0.05, 0.02, "beats it"), (0.05, 0.03, "level (within two standard errors)"), (-0.05, 0.02, "is beaten"),
    (0.0, float("nan"), "one target: no verdict")])
def test_verdict_needs_two_standard_errors(mean, error, expected):
    assert versus.verdict({"mean": mean, "standard_error": error}) == expected


def test_versus_runs_every_tracker_and_writes_the_table(data_root, tmp_path):
    groups = {"A": ("Walker",), "B": ("Runner",), "both": ("Walker", "Runner")}
    result = versus.run([data_root], tmp_path / "out", seeds=(0, 1), groups=groups, cache=tmp_path / "cache",
                        jobs=1, max_frames=6)
    columns = result["columns"]
    assert list(columns) == ["NRMLC", "NRMLC (paper preset)", "IVT", "ASLA", "L1", "L1APG"]
    for column in columns.values():
        assert set(column) == {"Walker", "Runner"} and all(len(v) == 2 for v in column.values())
        assert all(0 <= x <= 1 for v in column.values() for x in v)
    both = result["groups"]["both"]
    for tracker, mean in both["means"].items():
        assert mean == pytest.approx(np.mean([np.mean(columns[tracker][n]) for n in ("Walker", "Runner")]))
    assert set(both["differences"]) == {f"{a} - {b}" for a in versus.NRMLC_CONFIGURATIONS for b in versus.LINEAGE}
    assert result["groups"]["A"]["differences"]["NRMLC - IVT"]["verdict"] == "one target: no verdict"
    with open(tmp_path / "out" / "lineage_versus.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["target"], r["group"]) for r in rows] == [("Walker", "both"), ("Runner", "both")]
    assert float(rows[0]["IVT"]) == pytest.approx(np.mean(columns["IVT"]["Walker"]))
    stored = json.loads((tmp_path / "out" / "lineage_versus.json").read_text())
    assert stored["seeds"] == [0, 1] and stored["per_seed"]["ASLA"] == columns["ASLA"]
    assert (tmp_path / "out" / "lineage_versus.png").stat().st_size > 0


def test_versus_takes_the_lineage_from_an_earlier_table(data_root, tmp_path):
    """--lineage-from: the lineage's columns as an earlier run stored them, NRMLC's run again; a
    table at other seeds or without a target is refused in one line."""
    groups = {"A": ("Walker",), "B": ("Runner",)}
    first = versus.run([data_root], tmp_path / "first", seeds=(0,), groups=groups, cache=tmp_path / "cache", jobs=1,
                       max_frames=6)
    stored = tmp_path / "first" / "lineage_versus.json"
    again = versus.run([data_root], tmp_path / "again", seeds=(0,), groups=groups, cache=tmp_path / "empty", jobs=1,
                       max_frames=6, lineage_from=stored)
    assert again["columns"] == first["columns"]
    assert not list((tmp_path / "empty").rglob("imported/*"))  # no lineage run was made
    with pytest.raises(NrmlcError, match="seeds"):
        versus.run([data_root], tmp_path / "x", seeds=(1,), groups=groups, cache=tmp_path / "cache", jobs=1,
                   max_frames=6, lineage_from=stored)
    with pytest.raises(NrmlcError, match="no runs of IVT on Jumper"):
        versus.lineage_columns_from(stored, ["Walker", "Jumper"], (0,), 6)


def test_versus_names_a_missing_target_in_one_line(data_root, tmp_path, capsys):
    code = versus.main(["--data", str(data_root), "--out", str(tmp_path), "--seeds", "0"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "development sequence(s) not found" in err


def test_fidelity_scores_the_live_runs_against_the_file(data_root, tmp_path):
    otb = tmp_path / "otb"
    otb.mkdir()
    walker = open_sequence(data_root / "Walker")
    # A file that is the ground truth itself: overlap 1 on every frame, so the live runs are below it.
    _save(otb / "Walker_IVT.mat", res=np.asarray(walker.groundtruth, dtype=np.float64), type="rect", startFrame=1.0,
          len=float(FRAMES), fps=10.0)
    result = fidelity.run([data_root], otb, tmp_path / "out", trackers=("ivt", "asla"), seeds=(0, 1),
                          cache=tmp_path / "cache", jobs=1)
    (row,) = result["rows"]
    assert (row["tracker"], row["sequence"], row["frames"]) == ("IVT", "Walker", FRAMES)
    perfect = evaluate(walker.groundtruth, walker.groundtruth)
    assert row["file_overlap"] == pytest.approx(1.0) and row["file_auc"] == pytest.approx(perfect.success_auc)
    assert row["live_overlap_min"] <= row["live_overlap_mean"] <= row["live_overlap_max"] < 1.0
    assert row["within_seed_range"] is False
    summary = result["summary"]["IVT"]
    assert summary["sequences"] == 1 and summary["live_overlap"] == pytest.approx(row["live_overlap_mean"])
    assert (tmp_path / "out" / "lineage_fidelity.csv").read_text().count("\n") == 2
