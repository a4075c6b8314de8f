"""experiments.devset: the development evaluation command."""
import json

import numpy as np
import pytest

from experiments import devset
from nrmlc.errors import NrmlcError


def test_seed_ranges():
    assert devset.parse_seeds("0-4") == (0, 1, 2, 3, 4)
    assert devset.parse_seeds("0,2,5") == (0, 2, 5)
    for bad in ("", "a-b", "-1"):
        with pytest.raises(NrmlcError, match="--seeds"):
            devset.parse_seeds(bad)


def test_configuration_beside_its_baseline_on_the_synthetic_suite(tmp_path, capsys):
    out = tmp_path / "dev.json"
    argv = ["--sequences", "", "--synthetic", "1", "--seeds", "0", "--max-frames", "8", "--no-peers",
            "--jobs", "1", "--cache", str(tmp_path / "cache"), "--param", "n_particles=60",
            "--baseline-param", "n_particles=60", "--baseline-param", "alpha=2.5", "--json", str(out)]
    assert devset.main(argv) == 0
    table = capsys.readouterr().out
    assert "| synth-01 |" in table and "baseline" in table and "**mean**" in table
    numbers = json.loads(out.read_text())
    assert numbers["config"]["alpha"] == 25.0 and numbers["baseline"]["alpha"] == 2.5
    assert set(numbers["columns"]) == {"config", "baseline"}
    # The paired difference, for the synthetic suite only (no real sequence was asked for).
    assert "config - baseline on the synthetic suite:" in table and "development sequences:" not in table
    assert "the runs that changed most: synth-01 seed 0" in table
    assert set(numbers["differences"]) == {"synthetic suite"}
    difference = numbers["differences"]["synthetic suite"]
    assert difference["mean"] == pytest.approx(numbers["columns"]["config"]["synth-01"]
                                               - numbers["columns"]["baseline"]["synth-01"])
    # A rerun computes nothing: every run is in the cache.
    files = sorted(p.name for p in (tmp_path / "cache").iterdir())
    assert devset.main(argv) == 0
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == files


def test_paired_difference_by_hand():
    config = {"a": [0.5, 0.7, 0.6], "b": [0.2, 0.2, 0.2]}
    baseline = {"a": [0.4, 0.4, 0.4], "b": [0.3, 0.2, 0.2]}
    d = devset.paired_difference(config, baseline, ["a", "b"])
    # Per seed: mean(0.1, -0.1) = 0, mean(0.3, 0) = 0.15, mean(0.2, 0) = 0.1.
    assert d["per_seed"] == pytest.approx([0.0, 0.15, 0.1])
    assert d["mean"] == pytest.approx(0.25 / 3)
    assert d["standard_error"] == pytest.approx(np.std([0.0, 0.15, 0.1], ddof=1) / np.sqrt(3))
    # a rose (0.6 against 0.4); b fell (0.2 against 0.2333).
    assert (d["up"], d["down"], d["n"]) == (1, 1, 2)
    # The single runs that moved most: a at seed 1 (+0.3), then a at seed 2 (+0.2).
    largest = devset.largest_run_changes(config, baseline, ["a", "b"], seeds=(0, 1, 2), count=2)
    assert [(name, seed) for name, seed, _ in largest] == [("a", 1), ("a", 2)]
    assert [change for _, _, change in largest] == pytest.approx([0.3, 0.2])
    assert devset.largest_run_changes(config, baseline, ["b"], seeds=(0, 1, 2), count=1)[0][:2] == ("b", 0)
    assert np.isnan(devset.paired_difference({"a": [0.5]}, {"a": [0.4]}, ["a"])["standard_error"])


def test_a_paper_sequence_is_refused_as_a_development_sequence(capsys):
    assert devset.main(["--sequences", "Car4", "--no-peers"]) == 2
    assert "not development sequences: Car4" in capsys.readouterr().err
