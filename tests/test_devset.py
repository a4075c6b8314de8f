"""experiments.development.devset: the development evaluation command."""
import json
import math

import numpy as np
import pytest

from experiments.development import devset
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
    assert "| synth-01 |" in table and "baseline" in table and "**mean, synthetic suite (1)**" in table
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


def _difference(mean, error, n_seeds=5):
    return {"mean": mean, "standard_error": error, "per_seed": [mean] * n_seeds}


def test_the_adoption_rule_reads_both_halves_and_the_synthetic_suite():
    gain = _difference(0.02, 0.005)
    assert devset.adopted({"A": gain, "B": _difference(0.001, 0.01)})[0]
    assert devset.adopted({"A": gain, "B": gain, "synthetic suite": _difference(-0.004, 0.005)})[0]
    assert devset.adopted({"A": _difference(0.01, 0.005), "B": gain})[0]  # the floor itself passes
    refusals = {
        "A: +0.012 is not beyond": {"A": _difference(0.012, 0.013), "B": gain},
        "A: +0.009 is under the least gain worth a change, 0.01": {"A": _difference(0.009, 0.001), "B": gain},
        "B: -0.001 is not a gain": {"A": gain, "B": _difference(-0.001, 0.001)},
        "synthetic suite: -0.010": {"A": gain, "B": gain, "synthetic suite": _difference(-0.01, 0.005)},
        "needs at least 5 seeds": {"A": _difference(0.02, 0.005, 4), "B": gain},
        "needs both halves": {"A": gain},
    }
    for why, differences in refusals.items():
        verdict = devset.adopted(differences)
        assert not verdict[0] and why in verdict[1], (why, verdict)


def test_table_marks_missing_values_and_compares_like_with_like():
    groups = {"A": ["a1", "a2"], "B": ["b1"]}
    columns = {"config": {"a1": 0.5, "a2": 0.7, "b1": 0.4}, "ASLA": {"a1": 0.3, "b1": 0.2}}
    text = devset.format_table(groups, columns)
    assert "| a2 | 0.700 | - |" in text
    # ASLA has one of half A's two targets: its mean there, and config's on the same target.
    assert "| **mean, half A (2)** | **0.600** | **0.300** (1; config 0.500) |" in text
    assert "| **mean, all real (3)** | **0.533** | **0.250** (2; config 0.450) |" in text


def test_sequences_come_from_several_roots(tmp_path):
    from nrmlc.data import synthetic_suite, write_otb_sequence

    first, second = tmp_path / "one", tmp_path / "two"
    suite = synthetic_suite(n_frames=4, n_sequences=2)
    write_otb_sequence(suite[0], first / "synth-01")
    for sequence in suite:
        write_otb_sequence(sequence, second / sequence.name)
    roots = devset.parse_roots(f"{first}:{second}")
    found = devset.development_sequences(roots, ["synth-01", "synth-02"], 0)
    # synth-01 from the first root that has it, synth-02 from the second.
    assert [s.path.parent for s in found] == [first, second]
    with pytest.raises(NrmlcError, match="not found: synth-09"):
        devset.development_sequences(roots, ["synth-09"], 0)
    with pytest.raises(NrmlcError, match="--data: .*nowhere is not a folder"):
        devset.parse_roots(str(tmp_path / "nowhere"))


def test_no_default_data_root_is_said_in_one_warning_line(tmp_path, monkeypatch, capsys):
    from experiments.development import devset

    monkeypatch.delenv("NRMLC_DATA", raising=False)
    monkeypatch.delenv(devset.MORE_DATA_ENV, raising=False)
    monkeypatch.setattr(devset, "DEFAULT_DATA", tmp_path / "no-shared")
    monkeypatch.setattr(devset, "DEFAULT_MORE_DATA", tmp_path / "no-devdata")
    assert devset.parse_roots(None) == []
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "no development data" in lines[0] and "no-devdata" in lines[0]


def test_screen_gives_each_variant_its_paired_differences_and_verdict(tmp_path, capsys):
    from experiments.development import screen

    out = tmp_path / "screen.json"
    argv = ["--data", str(tmp_path), "--seeds", "0", "--synthetic", "1", "--jobs", "1",
            "--cache", str(tmp_path / "cache"), "--baseline", "n_particles=60,generative_weight=0",
            "--variant", "low_alpha", "n_particles=60,generative_weight=0,alpha=2.5",
            "--variant", "same", "n_particles=60,generative_weight=0", "--json", str(out)]
    # Every development target is asked for by default: none is in an empty root.
    assert screen.main(argv) == 2
    assert "no sequences" in capsys.readouterr().err
    # --cached-only computes nothing but the baseline... which is not cached either: only it runs.
    small = ["--sequences", "", "--max-frames", "8"]
    assert screen.main(argv + small + ["--cached-only"]) == 0
    captured = capsys.readouterr()
    assert "skipped: low_alpha, same" not in captured.err and "skipped: low_alpha" in captured.err
    assert "| low_alpha |" not in captured.out
    assert screen.main(argv + small) == 0
    text = capsys.readouterr().out
    assert "| low_alpha |" in text and "| same | - | - | +0.000 ± nan (0↑ 0↓) | - | 0, 0 |" in text
    numbers = json.loads(out.read_text())
    low = numbers["variants"][0]
    assert low["params"]["alpha"] == 2.5 and not low["adopted"] and low["why"] == "needs both halves"
    assert low["differences"]["synthetic suite"]["mean"] == pytest.approx(
        low["per_seed"]["synth-01"][0] - numbers["baseline_per_seed"]["synth-01"][0])


def test_screen_variant_syntax():
    from experiments.development import screen

    params = screen.parse_variant("v", "motion_sigmas=[4,4,0.01,0,0.005,0],alpha=3", "default")
    assert params.motion_sigmas == (4.0, 4.0, 0.01, 0.0, 0.005, 0.0) and params.alpha == 3.0
    assert screen.parse_variant("p", "preset:paper", "default") == devset.TrackerParams.paper()
    with pytest.raises(NrmlcError, match="unknown parameter"):
        screen.parse_variant("v", "alhpa=3", "default")


def test_the_committed_split_keeps_videos_together_and_halves_balanced():
    from experiments.development import development_split
    from experiments.sequence_sets import (DEVELOPMENT_A, DEVELOPMENT_B, DEVELOPMENT_SEQUENCES,
                                           FIRST_DEVELOPMENT)

    assert sorted(DEVELOPMENT_A + DEVELOPMENT_B) == sorted(DEVELOPMENT_SEQUENCES)
    assert len(DEVELOPMENT_A) == len(DEVELOPMENT_B) == 18 and len(set(DEVELOPMENT_SEQUENCES)) == 36
    assert len(set(FIRST_DEVELOPMENT) & set(DEVELOPMENT_A)) == 6
    for pair in development_split.SAME_VIDEO:
        assert set(pair) <= set(DEVELOPMENT_A) or set(pair) <= set(DEVELOPMENT_B)


def test_balanced_split_by_hand():
    from experiments.development import development_split

    targets = list(development_split.FIRST_TARGETS) + [f"t{i}" for i in range(6)]
    difficulty = np.arange(len(targets), dtype=float)
    flags = np.zeros((len(targets), 11))
    half_a, half_b = development_split.balanced_split(targets, difficulty, flags, draws=300, seed=1)
    assert len(half_a) == len(half_b) == 9
    assert {"Jogging-1", "Jogging-2"} <= set(half_a) or {"Jogging-1", "Jogging-2"} <= set(half_b)
    in_a = np.isin(targets, half_a)
    # 300 draws find halves whose mean difficulty is within a tenth of a spread.
    assert development_split.split_cost(in_a, difficulty, flags) < 0.1


def _still_target(box, n_frames):
    """A target that stays at ``box`` for ``n_frames``: just what score(), tracked_scale() and
    scale_ratios() read of a sequence."""
    class Truth:
        name = "t"
        groundtruth = np.tile(np.asarray(box, dtype=np.float64), (n_frames, 1))

        def __len__(self):
            return n_frames

    return Truth()


def test_tracked_scale_is_the_median_over_the_last_quarter():
    truth = _still_target([10.0, 10.0, 20.0, 20.0], 9)
    boxes = np.tile([10.0, 10.0, 20.0, 20.0], (9, 1))
    boxes[7:] = [10.0, 10.0, 10.0, 10.0]  # the last two of the 8 scored frames at half the size
    assert devset.tracked_scale(boxes, truth) == pytest.approx(0.5)
    assert devset.tracked_scale(boxes, truth, share=1.0) == pytest.approx(1.0)
    assert devset.collapsed({"t": [0.5, 0.6, 0.9], "u": [0.8, 0.9, 0.5]}, ["t", "u"]) == ["t"]


def test_a_collapse_is_told_apart_from_a_box_that_shrank_after_the_loss():
    truth = _still_target([100.0, 100.0, 40.0, 40.0], 41)
    held = np.tile([100.0, 100.0, 40.0, 40.0], (41, 1))
    shrank_on_target = held.copy()
    shrank_on_target[10:] = [110.0, 110.0, 20.0, 20.0]  # half the size, inside the target: IoU 0.25
    lost_then_shrank = held.copy()
    lost_then_shrank[10:] = [300.0, 300.0, 40.0, 40.0]  # off the target at its size ...
    lost_then_shrank[25:] = [300.0, 300.0, 20.0, 20.0]  # ... then smaller
    specs = [type("Spec", (), {"sequence": truth})() for _ in range(3)]
    results = [type("Result", (), {"boxes": b})() for b in (shrank_on_target, lost_then_shrank, held)]
    measures = devset.run_measures(results, specs)["t"]
    assert measures["lost_at"] == [None, 10 / 41, None]
    assert measures["shrunk_at"] == [10 / 41, 25 / 41, None]
    assert measures["scale"] == [pytest.approx(0.5), pytest.approx(0.5), pytest.approx(1.0)]
    # Collapsed (median scale 0.5): one run shrank while it held the target, one after it lost it.
    assert devset.collapse_after_loss({"t": measures}, ["t"]) == {"t": (1, 2)}
    measures["shrunk_at"][1] = 5 / 41  # had it shrunk first, neither counts as shrunk after the loss
    assert devset.collapse_after_loss({"t": measures}, ["t"]) == {"t": (0, 2)}


def test_a_baseline_is_carried_from_another_code_version_only_when_bit_identical(tmp_path):
    from experiments.development import screen
    from experiments.grid import specs_for
    from nrmlc.data import synthetic_suite
    from nrmlc.workbench.run_cache import RunCache
    from nrmlc.tracker.params import TrackerParams

    cache = RunCache(tmp_path / "cache")
    specs = specs_for(synthetic_suite(n_frames=6, n_sequences=1), TrackerParams(n_particles=40), (0,), n_frames=6)
    here = cache.run(specs, jobs=1, progress=False)
    with pytest.raises(NrmlcError, match="1 baseline runs are not in"):
        screen.baseline_at_version(cache, specs, "0" * 16, jobs=1)
    # The same runs stored under another version: read from there.
    other = RunCache(tmp_path / "cache")
    other.version = "0" * 16
    arrays = dict(np.load(cache.path(specs[0])))
    other.store(specs[0], arrays)
    carried = screen.baseline_at_version(cache, specs, "0" * 16, jobs=1)
    assert np.array_equal(carried[0].boxes, here[0].boxes)
    # Other boxes under that version: refused by name.
    arrays["boxes"] = arrays["boxes"] + 1.0
    other.store(specs[0], arrays)
    with pytest.raises(NrmlcError, match="synth-01 seed 0 gives other boxes"):
        screen.baseline_at_version(cache, specs, "0" * 16, jobs=1)


def test_attribute_means_and_early_losses_by_hand():
    columns = {"config": {"a": 0.2, "b": 0.6, "c": 0.9}, "ASLA": {"a": 0.4, "c": 0.5}}
    table = devset.attribute_means(columns, ["a", "b", "c"], {"a": {"IV", "SV"}, "b": {"IV"}, "c": {"SV"}})
    assert table["IV"] == {"n": 2, "config": pytest.approx(0.4), "ASLA": pytest.approx(0.4)}
    assert table["SV"]["n"] == 2 and table["SV"]["config"] == pytest.approx(0.55) and "OCC" not in table
    assert "| IV (2) | 0.400 | 0.400 |" in devset.format_attribute_means(table, list(columns))
    measures = {"a": {"lost_at": [0.01, 0.03, None]}, "b": {"lost_at": [0.01, None, 0.5]}}
    # Lost within the first 5% in most seeds: a (2 of 3), not b (1 of 3).
    assert devset.early_losses(measures, ["a", "b"]) == ["a"]


def test_fewer_seeds_than_the_rule_needs_are_warned_in_one_line(capsys):
    # "--seeds 3" is seed 3 alone, easily meant as three seeds.
    devset.warn_few_seeds("3", (3,))
    line = capsys.readouterr().err.strip()
    assert line.count("\n") == 0 and "--seeds 3 is 1 seed(s) (3)" in line and "at least 5" in line
    devset.warn_few_seeds("0-4", (0, 1, 2, 3, 4))
    assert capsys.readouterr().err == ""


def test_screen_pool_joins_disjoint_seeds_and_rejudges(tmp_path, capsys):
    from experiments.development import screen

    groups = {"A": ["a1", "a2"], "B": ["b1"], "synthetic suite": ["s1"]}

    def document(seeds, shift):
        base = {n: [0.5 + 0.01 * s for s in seeds] for n in ["a1", "a2", "b1", "s1"]}
        variant = {n: [x + shift for x in runs] for n, runs in base.items()}
        scales = {n: [1.0] * len(seeds) for n in base}
        return {"baseline": {"alpha": 25.0}, "baseline_per_seed": base, "baseline_scales": scales,
                "seeds": seeds, "groups": groups,
                "variants": [{"name": "v", "params": {"alpha": 3.0}, "per_seed": variant,
                              "scales": {n: [0.5] * len(seeds) for n in base}}]}

    first, second = tmp_path / "first.json", tmp_path / "second.json"
    first.write_text(json.dumps(document([0, 1], 0.02)))
    second.write_text(json.dumps(document([2, 3], -0.01)))
    out = tmp_path / "pooled.json"
    assert screen.main(["--pool", f"{first},{second}", "--json", str(out)]) == 0
    pooled = json.loads(out.read_text())
    assert pooled["seeds"] == [0, 1, 2, 3]
    a = pooled["variants"][0]["differences"]["A"]
    assert a["per_seed"] == pytest.approx([0.02, 0.02, -0.01, -0.01]) and a["mean"] == pytest.approx(0.005)
    assert a["standard_error"] == pytest.approx(np.std([0.02, 0.02, -0.01, -0.01], ddof=1) / 2)
    assert pooled["variants"][0]["collapsed"] == {"A": ["a1", "a2"], "B": ["b1"]}
    assert pooled["baseline_collapsed"] == {"A": [], "B": []}
    assert "| v |" in capsys.readouterr().out
    # a seed in both screens is refused, naming both files
    assert screen.main(["--pool", f"{first},{first}"]) == 2
    message = capsys.readouterr().err.strip()
    assert message.count("\n") == 0 and "seed 0" in message and "first.json" in message
    assert screen.main(["--pool", f"{first},{tmp_path / 'missing.json'}"]) == 2
    assert "missing.json" in capsys.readouterr().err
    # only the variants every screen has are pooled; none shared is an error
    wider = document([4], 0.0)
    wider["variants"].append(dict(wider["variants"][0], name="w"))
    (tmp_path / "wider.json").write_text(json.dumps(wider))
    assert screen.main(["--pool", f"{tmp_path / 'wider.json'},{first}", "--json", str(out)]) == 0
    assert [v["name"] for v in json.loads(out.read_text())["variants"]] == ["v"]
    other = document([5], 0.0)
    other["variants"][0]["name"] = "u"
    (tmp_path / "other.json").write_text(json.dumps(other))
    capsys.readouterr()
    assert screen.main(["--pool", f"{first},{tmp_path / 'other.json'}"]) == 2
    assert "no variant" in capsys.readouterr().err


def test_the_peers_collapse_is_nrmlc_s_measure_on_their_boxes(tmp_path):
    from nrmlc.testing.otb_files import truth, write_otb_result_files

    class Standin:
        def __init__(self, name, groundtruth, frame_size=(100, 200)):
            self.name, self.groundtruth, self.frame_size = name, groundtruth, frame_size

        def __len__(self):
            return len(self.groundtruth)

    folder = write_otb_result_files(tmp_path)
    grown = truth()
    grown[5:, 2:] *= 2  # the target doubles in width and height; the file's boxes keep the first size
    overlaps, scales, edges, notes = devset.lineage_measures(folder, [Standin("Walker-2", grown)],
                                                             trackers=("RectTracker",))
    assert scales["RectTracker"]["Walker-2"] == pytest.approx(0.5)  # the last quarter: frames 8-9
    assert 0 < overlaps["RectTracker"]["Walker-2"] < 1
    assert edges["RectTracker"]["Walker-2"] == 0
    found = devset.peer_collapses({"RectTracker (OTB results)": scales["RectTracker"],
                                   "lost": {"Walker-2": float("nan")}}, ["Walker-2", "Other"])
    assert found == {"RectTracker (OTB results)": {"scored": ["Walker-2"], "collapsed": ["Walker-2"],
                                                   "at_frame_edge": []},
                     "lost": {"scored": [], "collapsed": [], "at_frame_edge": []}}
    # A frame 47 px wide: the boxes of frames 8-9 (x = 27, 29; w = 20) reach its right border.
    _, scales, edges, _ = devset.lineage_measures(folder, [Standin("Walker-2", grown, (100, 47))],
                                                  trackers=("RectTracker",))
    assert edges["RectTracker"]["Walker-2"] == 1
    found = devset.peer_collapses({"Rect": scales["RectTracker"]}, ["Walker-2"], {"Rect": edges["RectTracker"]})
    assert found["Rect"]["at_frame_edge"] == ["Walker-2"]


def test_frame_edge_share_counts_the_last_quarter_s_boxes_at_the_border():
    class Standin:
        frame_size = (50, 80)  # height, width

    boxes = np.array([[10, 10, 20, 20]] * 6 + [[1, 10, 5, 20], [70, 10, 11, 20], [10, 31, 20, 20],
                                                [np.nan] * 4], dtype=np.float64)
    # the last quarter of frames 1-9: frames 7-9; frame 9 has no box; 7 touches the right border
    # (70 + 11 >= 80), 8 the bottom (31 + 20 >= 50)
    assert devset.frame_edge_share(boxes, Standin(), np.arange(1, 10)) == 1.0
    assert devset.frame_edge_share(boxes, Standin(), np.arange(1, 7)) == 0.5  # frames 5-6: 6 is at the left
    assert devset.frame_edge_share(boxes, Standin(), np.arange(1, 6)) == 0.0
    assert math.isnan(devset.frame_edge_share(boxes, Standin(), np.array([9])))
