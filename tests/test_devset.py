"""experiments.devset: the development evaluation command."""
import json

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
    # A rerun computes nothing: every run is in the cache.
    files = sorted(p.name for p in (tmp_path / "cache").iterdir())
    assert devset.main(argv) == 0
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == files


def test_a_paper_sequence_is_refused_as_a_development_sequence(capsys):
    assert devset.main(["--sequences", "Car4", "--no-peers"]) == 2
    assert "not development sequences: Car4" in capsys.readouterr().err
