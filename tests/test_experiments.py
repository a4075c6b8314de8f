"""Tests for the experiment scripts (``make figures``): end to end on a tiny synthetic grid.

The grid is kept small so the whole file runs in well under a minute: one
synthetic sequence, its first 25 frames, one seed, 100 particles, one worker.
"""
from __future__ import annotations

import json
import re
import sys
import types

import numpy as np
import pytest

from experiments import paper_numbers, peers, run_all
from experiments.grid import context_from_args, run_script, score
from nrmlc.data import open_sequence

MY_SCRIPTS = ("table1_table2_accuracy", "fig3_qualitative", "fig4_lambda_sweep", "ablations",
              "ablation_per_sequence_motion", "ablation_oracle_recentring", "ablation_oracle_gate")
OUTPUTS = {"table1_table2_accuracy": (".png", ".csv", ".json"), "fig3_qualitative": (".png", ".json"),
           "fig4_lambda_sweep": (".png", ".csv", ".json"), "ablations": (".png", ".csv", ".json"),
           "ablation_oracle_recentring": (".png", ".csv", ".json"),
           "ablation_oracle_gate": (".png", ".csv", ".json")}


def tiny_args(tmp, figures="figures"):
    return ["--seeds", "1", "--sweep-seeds", "1", "--max-frames", "25", "--synthetic-sequences", "1",
            "--param", "n_particles=100", "--jobs", "1", "--out", str(tmp / figures), "--cache",
            str(tmp / "cache"), "--only", ",".join(MY_SCRIPTS)]


def cache_state(folder):
    return {p.name: p.stat().st_mtime_ns for p in folder.rglob("*.npz")}


@pytest.fixture(scope="module")
def grid(tmp_path_factory, monkeypatch_module):
    """run_all once on the tiny grid; returns (tmp folder, exit status, cache state after it)."""
    monkeypatch_module.delenv("NRMLC_DATA", raising=False)
    tmp = tmp_path_factory.mktemp("figures_run")
    status = run_all.main(tiny_args(tmp))
    return tmp, status, cache_state(tmp / "cache")


@pytest.fixture(scope="module")
def monkeypatch_module():
    patch = pytest.MonkeyPatch()
    yield patch
    patch.undo()


def test_run_all_writes_every_output(grid):
    tmp, status, state = grid
    assert status == 0
    figures = tmp / "figures"
    for stem, suffixes in OUTPUTS.items():
        for suffix in suffixes:
            path = figures / f"{stem}{suffix}"
            assert path.is_file() and path.stat().st_size > 0, path
            if suffix == ".json":
                json.loads(path.read_text())  # strict JSON (no NaN)
    report = (figures / "REPORT.md").read_text()
    for title in ("Tables I and II", "Fig. 3", "Fig. 4", "Ablations"):
        assert f"## {title}" in report
    for stem in OUTPUTS:
        assert f"]({stem}.png)" in report
    # The per-sequence motion script has nothing to compare on synthetic data: no placeholder.
    assert not (figures / "ablation_per_sequence_motion.png").exists()
    assert "Not drawn on this data: none of the given sequences" in report
    assert "Code version" in report and "synthetic suite" in report
    # Every distinct job of the grid ran once: shared runs (the table's default run is also
    # Fig. 3's, Fig. 4's lambda = 1 and every ablation family's first row) are one file.
    context = context_from_args(tiny_args(tmp)[:-2])
    failures = []
    jobs = run_all.collect_jobs(context, run_all.import_scripts(set(MY_SCRIPTS), failures), failures)
    paths = {context.cache.path(job) for script_jobs in jobs.values() for job in script_jobs}
    assert not failures and len(state) == len(paths) and len(paths) >= 30
    # One live run per OpenCV tracker on the one sequence (MIL; KCF and CSRT with opencv-contrib).
    assert len(list((tmp / "cache" / "peers").glob("*.npz"))) == len(peers.live_trackers())
    # One run per lineage tracker and seed (one seed here).
    assert len(list((tmp / "cache" / "imported").glob("*.npz"))) == len(peers.LINEAGE_LIVE)


def test_numbers_are_consistent(grid):
    tmp, _, _ = grid
    table = json.loads((tmp / "figures" / "table1_table2_accuracy.json").read_text())
    cell = table["cells"]["synth-01"]["Ours"]
    assert 0 <= cell["overlap"] <= 1 and cell["n_frames"] == 25
    assert "MIL (OpenCV)" in table["cells"]["synth-01"]
    for name in peers.LINEAGE_LIVE:
        live = table["cells"]["synth-01"][peers.lineage_label(name)]
        assert live["source"] == "live" and live["n_runs"] == 1 and 0 <= live["overlap"] <= 1
        assert live["n_frames"] == 25 and table["fps"][peers.lineage_label(name)] > 0
    sweep = json.loads((tmp / "figures" / "fig4_lambda_sweep.json").read_text())
    labels = [p["label"] for p in sweep["points"]]
    assert labels[:8] == [f"lambda={v:g}" for v in paper_numbers.FIG4_LAMBDAS] and labels[8] == "lambda=beta=0"
    # lambda = 1, beta = 0.1 is the default tracker: the same runs as the table's.
    at_one = next(p for p in sweep["points"] if p["label"] == "lambda=1")
    assert at_one["overlap"] == pytest.approx(cell["overlap"])
    ablations = json.loads((tmp / "figures" / "ablations.json").read_text())
    coding = {r["label"]: r for r in ablations["families"][0]["rows"]}
    assert coding["constrained"]["negative_share_c"] == 0.0  # the constraint forbids negative codes
    plain = next(p for p in sweep["points"] if p["label"] == "lambda=beta=0")
    assert coding["plain (λ = β = 0)"]["overlap"] == pytest.approx(plain["overlap"])


def test_rerun_recomputes_nothing(grid):
    tmp, _, before = grid
    assert run_all.main(tiny_args(tmp, figures="figures_again")) == 0
    assert cache_state(tmp / "cache") == before
    assert (tmp / "figures_again" / "REPORT.md").is_file()


def test_per_sequence_motion_conversion():
    """IVT's additive affsig -> nrmlc's relative sigmas, checked by hand for Car4 (lineage box 200x150)."""
    from experiments.paper.ablation_per_sequence_motion import converted_sigmas

    sigmas = converted_sigmas((4, 4, 0.02, 0.015, 0.005, 0.001), (200.0, 150.0), (70, 51, 107, 87), 32)
    assert sigmas == pytest.approx((4 * 107 / 200, 4 * 107 / 200, 0.02 / 6.25, 0.015, 0.005 / 0.75, 0.001))


def test_per_sequence_motion_runs_and_shares_the_table_runs(grid, monkeypatch):
    """With a classic entry for the synthetic sequence, the default column is Table II's own runs
    (from the cache) and the per-sequence column is a new run with the converted sigmas."""
    from experiments.paper import ablation_per_sequence_motion as script

    tmp, _, _ = grid
    monkeypatch.delenv("NRMLC_DATA", raising=False)
    monkeypatch.setitem(script.CLASSIC_MOTION, "synth-01", {"affsig": (2.0, 2.0, 0.004, 0.0, 0.0, 0.0),
                                                            "box": (64.0, 48.0)})
    context = context_from_args(tiny_args(tmp, figures="figures_motion")[:-2])
    result = run_script(script, context)
    data = json.loads((tmp / "figures_motion" / f"{script.STEM}.json").read_text())
    (row,) = data["rows"]
    table = json.loads((tmp / "figures" / "table1_table2_accuracy.json").read_text())
    assert row["overlap_default"] == pytest.approx(table["cells"]["synth-01"]["Ours"]["overlap"])
    width = context.sequence("synth-01").init_box[2]
    assert row["motion_sigmas_classic"] == pytest.approx([2.0 * width / 64, 2.0 * width / 64, 0.004 / 2, 0, 0, 0],
                                                         rel=1e-3)
    assert 0 <= row["overlap_classic"] <= 1 and row["overlap_classic"] != row["overlap_default"]
    assert "| synth-01 |" in result["markdown"]


def _one_row_and_table_overlap(tmp, stem: str):
    """A script's JSON, its one row, and Table II's overlap of the default on synth-01."""
    data = json.loads((tmp / "figures" / f"{stem}.json").read_text())
    (row,) = data["rows"]
    table = json.loads((tmp / "figures" / "table1_table2_accuracy.json").read_text())
    return data, row, table["cells"]["synth-01"]["Ours"]["overlap"]


def test_recentring_free_column_is_the_table_run(grid):
    """The free column reads Table II's own default run from the cache; the re-centred ones are new runs."""
    data, row, table_overlap = _one_row_and_table_overlap(grid[0], "ablation_oracle_recentring")
    assert row["free"] == pytest.approx(table_overlap)
    assert all(0 <= row[f"R = {period}"] <= 1 for period in (1, 10, 50))
    assert data["averages"]["other sequences"]["free"] == pytest.approx(row["free"])


def test_oracle_gate_rule_column_is_the_table_run(grid):
    """The rule column reads Table II's own default run from the cache; the gated ones are new runs."""
    data, row, table_overlap = _one_row_and_table_overlap(grid[0], "ablation_oracle_gate")
    assert row["rule"] == pytest.approx(table_overlap)
    assert all(0 <= row[gate] <= 1 and 0 <= row[f"{gate} updates"] <= 100 for gate in data["gates"])


def test_missing_and_failing_scripts(tmp_path, monkeypatch, capsys):
    """A script that does not import or fails is reported, the others still run, exit 1."""
    good = types.ModuleType("experiments._test_good")
    good.STEM = "good"
    good.runs = lambda context: []
    good.collect = lambda context: {}
    good.plot = lambda data, path: None
    good.report = lambda context, data: {"title": "Good", "figures": [], "markdown": "fine"}
    bad = types.ModuleType("experiments._test_bad")
    vars(bad).update(vars(good))
    bad.__name__ = "experiments._test_bad"

    def fail(context):
        raise RuntimeError("boom")

    bad.collect = fail
    monkeypatch.setitem(sys.modules, good.__name__, good)
    monkeypatch.setitem(sys.modules, bad.__name__, bad)
    monkeypatch.setattr(run_all, "SCRIPTS", ("experiments._test_absent", bad.__name__, good.__name__))
    status = run_all.main(["--out", str(tmp_path / "f"), "--cache", str(tmp_path / "c"), "--jobs", "1",
                           "--synthetic-sequences", "1", "--max-frames", "5"])
    assert status == 1
    closing = capsys.readouterr().err.strip().splitlines()[-1]
    assert closing.startswith("[run_all] wrote 0 figures, 0 tables (CSV), 0 JSON files and REPORT.md to ")
    assert closing.endswith(" s; 2 scripts failed: _test_absent, _test_bad")
    report = (tmp_path / "f" / "REPORT.md").read_text()
    assert "_test_absent: FAILED (import failed" in report
    assert "_test_bad: FAILED" in report and "boom" in report
    assert "## Good" in report
    for package in ("numpy", "numba", "OpenCV", "SciPy", "Python"):
        assert f"{package} " in report.split("## Notes")[0]


def test_outputs_go_to_the_ignored_folder_by_default(tmp_path, monkeypatch):
    from experiments.grid import DEFAULT_OUT, REPO_ROOT

    monkeypatch.delenv("NRMLC_DATA", raising=False)
    assert context_from_args([]).figures_dir == DEFAULT_OUT == REPO_ROOT / "out" / "figures"
    assert context_from_args(["--out", str(tmp_path)]).figures_dir == tmp_path
    ignored = (REPO_ROOT / ".gitignore").read_text().split()
    assert "out/" in ignored


def test_dry_run_prints_the_grid_and_tracks_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("NRMLC_DATA", raising=False)
    status = run_all.main(["--dry-run", "--cache", str(tmp_path / "c"), "--out", str(tmp_path / "f"),
                           "--synthetic-sequences", "1", "--max-frames", "10", "--only", "ablations"])
    err = capsys.readouterr().err
    assert status == 0 and "NRMLC runs" in err and " frames (0 cached, " in err and "Estimate" in err
    assert re.search(r"Estimate: ~\d+ min on \d+ worker\(s\) .* at \d+ frames/s per worker, measured just now", err)
    assert "ablations: " in err
    assert not (tmp_path / "c").exists() and not (tmp_path / "f").exists()
    assert "[run_all] wrote" not in err  # nothing written, no closing line


def _estimate_minutes(text: str) -> int:
    return int(re.search(r"Estimate: ~(\d+) min", text).group(1))


def test_the_estimate_follows_the_measured_speed(tmp_path, monkeypatch):
    monkeypatch.delenv("NRMLC_DATA", raising=False)
    context = context_from_args(["--cache", str(tmp_path / "c"), "--synthetic-sequences", "1", "--jobs", "1"])
    from experiments.paper import fig4_lambda_sweep as fig4

    jobs = {"fig4_lambda_sweep": fig4.runs(context)}
    cost = sum(run_all.job_cost(job) for job in jobs["fig4_lambda_sweep"])
    slow = run_all.grid_summary(context, jobs, measure=lambda: 10.0)[2]
    fast = run_all.grid_summary(context, jobs, measure=lambda: 100.0)[2]
    assert _estimate_minutes(slow) == round(cost / 10.0 / 60)
    assert _estimate_minutes(fast) == round(cost / 100.0 / 60)
    assert "at 10 frames/s per worker, measured just now on this machine" in slow
    assert "ESTIMATE_FPS_PER_WORKER" not in vars(run_all)  # no assumed speed left


def test_nothing_to_compute_measures_nothing(tmp_path, monkeypatch):
    monkeypatch.delenv("NRMLC_DATA", raising=False)
    context = context_from_args(["--cache", str(tmp_path / "c"), "--synthetic-sequences", "1"])

    def measure():
        raise AssertionError("measured although nothing is to be computed")

    assert "nothing to compute" in run_all.grid_summary(context, {"none": []}, measure=measure)[2]


def test_a_failed_measurement_leaves_the_run_going(tmp_path, monkeypatch):
    monkeypatch.delenv("NRMLC_DATA", raising=False)
    context = context_from_args(["--cache", str(tmp_path / "c"), "--synthetic-sequences", "1"])
    from experiments.paper import fig4_lambda_sweep as fig4

    def measure():
        raise RuntimeError("no kernels")

    text = run_all.grid_summary(context, {"fig4": fig4.runs(context)}, measure=measure)[2]
    assert "Estimate: none (the speed measurement failed: RuntimeError('no kernels'))" in text


def test_measure_speed_is_a_few_seconds_and_a_speed():
    import time

    start = time.perf_counter()
    fps = run_all.measure_speed(n_frames=8)
    assert 0 < fps < 10_000 and np.isfinite(fps)
    assert time.perf_counter() - start < 60  # kernels loaded by the tests before, or compiled once


def test_closing_line_says_what_was_written_where_and_how_long(tmp_path, monkeypatch):
    import os
    import time

    since = time.time() - 1.0
    for name in ("a.png", "b.png", "a.csv", "a.json", "b.json", "c.json", "notes.txt"):
        (tmp_path / name).write_text("x")
    old = tmp_path / "old.png"
    old.write_text("x")
    os.utime(old, (since - 100, since - 100))
    counts = run_all.written_since(tmp_path, since)
    assert counts == {".png": 2, ".csv": 1, ".json": 3}
    monkeypatch.chdir(tmp_path.parent)
    line = run_all.closing_line(tmp_path, counts, "REPORT.md", 186.0, [])
    assert line == f"[run_all] wrote 2 figures, 1 table (CSV), 3 JSON files and REPORT.md to {tmp_path.name}/ in 3.1 min"
    failed = run_all.closing_line(tmp_path, counts, "REPORT.md", 6.0, [("fig4", "boom"), ("fig3", "bang")])
    assert failed.endswith("in 6 s; 2 scripts failed: fig4, fig3")


def test_sequence_subset(tmp_path, monkeypatch):
    from nrmlc.errors import DataError

    monkeypatch.delenv("NRMLC_DATA", raising=False)
    context = context_from_args(["--synthetic-sequences", "3", "--sequences", "synth-02"])
    assert [s.name for s in context.sequences()] == ["synth-02"]
    with pytest.raises(DataError, match="Car4"):
        context_from_args(["--synthetic-sequences", "2", "--sequences", "Car4"]).sequences()


def test_capped_table_marks_the_full_sequence_paper_numbers():
    from experiments.paper import table1_table2_accuracy as table

    cells = {"Car4": {table.OURS: {"overlap": 0.5, "source": "measured"},
                      table.OURS_PAPER: {"overlap": 0.9, "source": "paper"}}}
    data = {"columns": [table.OURS, table.OURS_PAPER], "cells": cells, "paper_names": {"Car4": "Car4"},
            "blocks": [("paper", "the paper's sequences", ["Car4"])], "fps": {},
            "averages": {"paper": {}}, "max_frames": 50}
    text = table.markdown_table(data, "overlap", 2, "Table II", False)
    assert "first 50 frames" in text and "0.90† (full seq.)" in text
    data["max_frames"] = None
    assert "(full seq.)" not in table.markdown_table(data, "overlap", 2, "Table II", False)


def test_sequence_sets():
    from experiments.sequence_sets import DEVELOPMENT_SEQUENCES, PAPER_SEQUENCES, paper_name

    assert len(PAPER_SEQUENCES) == 9 and len(DEVELOPMENT_SEQUENCES) == 36
    assert not set(PAPER_SEQUENCES) & set(DEVELOPMENT_SEQUENCES)
    assert all(paper_name(name) in paper_numbers.SEQUENCES for name in PAPER_SEQUENCES)
    assert [paper_name(n) for n in PAPER_SEQUENCES] == [n for n in paper_numbers.SEQUENCES
                                                        if n in {paper_name(m) for m in PAPER_SEQUENCES}]


def test_paper_tables_are_complete():
    for table, average in ((paper_numbers.CLE, paper_numbers.CLE_AVERAGE),
                           (paper_numbers.OVERLAP, paper_numbers.OVERLAP_AVERAGE)):
        assert set(table) == set(paper_numbers.SEQUENCES) and len(table) == 12
        for row in table.values():
            assert tuple(row) == paper_numbers.TRACKERS and len(row) == 9
        assert tuple(average) == paper_numbers.TRACKERS
        for tracker in paper_numbers.TRACKERS:
            # The printed avg. row is the mean of the column (to its rounding).
            assert paper_numbers.average(table, paper_numbers.SEQUENCES, tracker) == pytest.approx(
                average[tracker], abs=0.051 if table is paper_numbers.CLE else 0.0051)
    assert tuple(paper_numbers.FPS) == paper_numbers.TRACKERS
    assert paper_numbers.FIG4_NO_REGULARISATION_OVERLAP == 0.3175


def test_frame_choice_and_rect_conversion():
    from experiments.paper.fig3_qualitative import frame_indices

    assert frame_indices(100) == [25, 50, 74, 99]
    assert frame_indices(1) == [0]
    assert peers._to_cv_rect([70, 51, 107, 87]) == (69, 50, 107, 87)


def test_shipped_kcf_car4_scores_like_the_paper(real_data_root):
    """The shipped KCF result on Car4, scored against our ground truth: ~0.48 overlap (paper: 0.47)."""
    peer_root = real_data_root.parent / "peer_results"
    if not (peer_root / "KCF").is_dir() or not (real_data_root / "Car4").is_dir():
        pytest.skip(f"no shipped KCF results or Car4 under {real_data_root.parent}")
    car4 = open_sequence(real_data_root / "Car4")
    shipped = peers.shipped_results(peer_root, car4, trackers=("KCF", "L1"))
    evaluation = score(shipped.results["KCF"].boxes, car4)
    assert evaluation.mean_overlap == pytest.approx(0.48, abs=0.01)
    # The sparse-pack Car4 has as many lines but is at twice the resolution: refused, with a note.
    assert "L1" not in shipped.results
    assert any("L1" in note and "not used" in note for note in shipped.notes)


def test_context_from_args_options(tmp_path):
    context = context_from_args(["--seeds", "2", "--max-frames", "7", "--param", "lam=0.5",
                                 "--cache", str(tmp_path / "c")])
    assert context.seeds == (0, 1) and context.max_frames == 7 and context.base_params.lam == 0.5
    spec = context.specs(context.sequences()[:1])[0]
    assert spec.n_frames == 7 and spec.params.lam == 0.5
    assert np.isfinite(context.sequences()[0].init_box).all()


def test_every_switch_has_ablation_rows(monkeypatch):
    """Each flag or named-choice field of TrackerParams is varied by some ablation family, each
    non-default row changing only what its family is about."""
    import dataclasses

    from experiments.paper.ablations import families
    from experiments.grid import Context
    from experiments.grid import params_differences
    from nrmlc.tracker.params import TrackerParams

    monkeypatch.delenv("NRMLC_DATA", raising=False)
    context = Context()
    base = context.base_params
    varied = set()
    for family, configs in families(context):
        assert configs[0][1] == base, family  # the first row is the default tracker
        for label, params in configs[1:]:
            changed = params_differences(params, base)
            assert changed, (family, label)
            if family != "preset":
                varied |= set(changed)
    switches = {f.name for f in dataclasses.fields(TrackerParams)
                if isinstance(getattr(TrackerParams(), f.name), (str, bool))}
    assert switches <= varied, switches - varied


def test_a_stated_value_the_default_departs_from_has_a_row_with_the_paper_value(monkeypatch):
    """n_negative (paper 150, default 100) gets an ablation family whose second row restores the
    paper's count and changes nothing else."""
    from experiments.paper.ablations import families
    from experiments.grid import Context, params_differences
    from nrmlc.tracker.params import TrackerParams

    monkeypatch.delenv("NRMLC_DATA", raising=False)
    context = Context()
    rows = dict(families(context))["n negative"]
    assert params_differences(rows[1][1], context.base_params) == {"n_negative": TrackerParams.paper().n_negative}
    assert TrackerParams.paper().n_negative == 150 != context.base_params.n_negative


def test_peers_option(tmp_path, monkeypatch):
    from nrmlc.errors import DataError

    monkeypatch.delenv("NRMLC_DATA", raising=False)
    assert context_from_args(["--peers", str(tmp_path)]).shipped_peer_root() == tmp_path
    with pytest.raises(DataError, match="--peers"):
        context_from_args(["--peers", str(tmp_path / "absent")])
    assert run_all.main(["--peers", str(tmp_path / "absent"), "--dry-run"]) == 2


def test_a_sequence_subset_opens_only_its_folders(tmp_path, recwarn):
    import warnings

    from experiments.grid import Context
    from nrmlc.data import synthetic_suite, write_otb_sequence

    for sequence in synthetic_suite(n_frames=5, n_sequences=2):
        write_otb_sequence(sequence, tmp_path / sequence.name)
    truth = tmp_path / "synth-02" / "groundtruth_rect.txt"
    truth.write_text("\n".join(truth.read_text().splitlines()[:3]) + "\n")  # 3 boxes for 5 frames: a warning
    warnings.simplefilter("always")
    assert [s.name for s in Context(data_root=tmp_path, only_sequences=("synth-01",)).sequences()] == ["synth-01"]
    assert not [w for w in recwarn if "synth-02" in str(w.message)]
    assert len(Context(data_root=tmp_path).sequences()) == 2
    assert [w for w in recwarn if "synth-02" in str(w.message)]


def test_make_figures_prints_warnings_as_one_line(tmp_path, capsys):
    import warnings

    def fake_main(argv):
        warnings.warn("a ground-truth file is short")
        return 0

    original = run_all._main
    run_all._main = fake_main
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            # What Python's own showwarning does (pytest replaces it with a recorder).
            warnings.showwarning = lambda message, category, filename, lineno, file=None, line=None: \
                sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))
            assert run_all.main([]) == 0
    finally:
        run_all._main = original
    assert capsys.readouterr().err == "warning: a ground-truth file is short\n"


def test_a_script_with_nothing_to_show_draws_no_placeholder(tmp_path):
    from experiments.paper import ablation_per_sequence_motion as motion
    from experiments.grid import Context, run_script

    context = Context(figures_dir=tmp_path, n_synthetic=1)
    section = run_script(motion, context)
    assert section["figures"] == [] and "Not drawn on this data" in section["markdown"]
    assert not (tmp_path / f"{motion.STEM}.png").exists()


def test_fig4_on_synthetic_data_leaves_out_the_papers_references(tmp_path, monkeypatch):
    from experiments.paper import fig4_lambda_sweep as fig4

    labels = {}
    monkeypatch.setattr(fig4, "save_figure", lambda fig, path, **kwargs: labels.__setitem__(
        path, [t.get_text() for t in fig.axes[0].get_legend().get_texts()]))
    points = [{"coding": "regularized", "lam": lam, "overlap": 0.8, "overlap_std": 0.01} for lam in (0.0, 1.0)]
    points.append({"coding": "plain", "lam": 0.0, "overlap": 0.7, "overlap_std": 0.01})
    for synthetic in (True, False):
        fig4.plot({"points": points, "sequences": ["s"], "seeds": [0], "synthetic": synthetic}, synthetic)
    assert not any(label.startswith("paper") for label in labels[True])
    assert sum(label.startswith("paper") for label in labels[False]) == 2


def _fig4_points(plain: float, green: float) -> list[dict]:
    points = [{"coding": "regularized", "lam": lam, "overlap": green if lam == 0 else 0.5, "overlap_std": 0.01}
              for lam in (0.0, 0.01, 0.1, 0.5, 0.8, 1.0, 5.0, 10.0)]
    return points + [{"coding": "plain", "lam": 0.0, "overlap": plain, "overlap_std": 0.01}]


def test_fig4_draws_the_unregularised_line_visibly_over_the_other(tmp_path, monkeypatch):
    """λ = β = 0 (red) and λ = 0, β = 0.1 (green) a hair apart: red on top, dashed, with markers."""
    from experiments.paper import fig4_lambda_sweep as fig4

    drawn = {}

    def keep(fig, path, **kwargs):
        fig.canvas.draw()
        drawn["fig"] = fig

    monkeypatch.setattr(fig4, "save_figure", keep)
    fig4.plot({"points": _fig4_points(0.549, 0.547), "sequences": ["s"], "seeds": [0, 1], "synthetic": True},
              tmp_path / "f.png")
    ax = drawn["fig"].axes[0]
    lines = {line.get_label(): line for line in ax.get_lines()}
    red = next(line for label, line in lines.items() if label.startswith("λ = β = 0"))
    green = next(line for label, line in lines.items() if label.startswith("λ = 0, β"))
    assert red.get_zorder() > green.get_zorder()
    assert red.get_marker() not in (None, "", "None") and red.get_linestyle() not in ("-", "solid")
    assert green.get_linewidth() > 2 * red.get_linewidth()  # the green shows around the red


def test_fig4_tick_labels_do_not_overlap(tmp_path, monkeypatch):
    from experiments.paper import fig4_lambda_sweep as fig4

    drawn = {}

    def keep(fig, path, **kwargs):
        fig.tight_layout()
        fig.canvas.draw()
        drawn["fig"] = fig

    monkeypatch.setattr(fig4, "save_figure", keep)
    fig4.plot({"points": _fig4_points(0.5, 0.5), "sequences": ["s"], "seeds": [0], "synthetic": True},
              tmp_path / "f.png")
    fig = drawn["fig"]
    renderer = fig.canvas.get_renderer()
    boxes = [label.get_window_extent(renderer) for label in fig.axes[0].get_xticklabels() if label.get_text()]
    boxes.sort(key=lambda box: box.x0)
    assert len(boxes) == 8
    space = fig.dpi * 3 / 72  # 3 points, more than a word space at the labels size: no two read as one
    for left, right in zip(boxes, boxes[1:]):
        assert right.x0 - left.x1 > space, "tick labels touch"


def test_fig3_row_labels_keep_clear_of_the_row_above(tmp_path, monkeypatch):
    """Rows of frames of other shapes (the real sequences'): every row's label is closer to its own
    frames than to the row above, with at least one and a half label heights of space above it."""
    from experiments.paper import fig3_qualitative as fig3

    class Frames:
        def __init__(self, name, shape):
            self.name, self.shape = name, shape

        def color_frame(self, index):
            return np.full(self.shape + (3,), 128, np.uint8)

    shapes = {"Car4": (240, 360), "CarScale": (272, 640), "Occlusion2": (480, 640), "ClifBar": (240, 320),
              "Occlusion1": (289, 352), "Portrait": (480, 360)}
    rows = [{"sequence": Frames(name, shape), "frames": [1, 2, 3, 4],
             "boxes": {"Ground truth": {f: np.array([10.0, 10.0, 50.0, 40.0]) for f in range(5)}}}
            for name, shape in shapes.items()]
    drawn = {}

    def keep(fig, path, rect=None, **kwargs):
        fig.tight_layout(rect=rect)  # what save_figure does
        fig.canvas.draw()
        drawn["fig"] = fig

    monkeypatch.setattr(fig3, "save_figure", keep)
    fig3.plot({"rows": rows}, tmp_path / "f.png")
    fig = drawn["fig"]
    renderer = fig.canvas.get_renderer()
    axes = np.array(fig.axes).reshape(len(rows), 4)
    for r in range(1, len(rows)):
        label = next(title for title in (axes[r, 0].title, axes[r, 0]._left_title) if title.get_text())
        box = label.get_window_extent(renderer)
        above = min(ax.get_images()[0].get_window_extent(renderer).y0 for ax in axes[r - 1]) - box.y1
        below = box.y0 - max(ax.get_images()[0].get_window_extent(renderer).y1 for ax in axes[r])
        assert above > max(below, 1.5 * box.height), f"{label.get_text()}: {above:.0f} px below the row above"
