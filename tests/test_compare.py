"""``nrmlc evaluate`` compares like with like: what a benchmark folder ran (sequences, frame cap,
seeds), missing sequences shown as missing, the frames behind each single-file number, outputs that
are never inputs, per-attribute scores and the speed plot. No tracking: result files are written here.
"""
from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from nrmlc.workbench.attributes import ATTRIBUTES, read_attribute_file, read_attributes
from nrmlc.cli import main
from nrmlc.workbench.report import plot_comparison
from nrmlc.workbench.score import Comparison, TrackerScores, compare
from nrmlc.workbench.speed import plot_speed
from nrmlc.data import open_sequence
from nrmlc.errors import DataError
from nrmlc.workbench.metrics import evaluate


def run_main(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def write_boxes(path: Path, boxes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(",".join(f"{v:g}" for v in row) for row in boxes) + "\n")


def shifted(data_root, name, dx, n=None):
    boxes = open_sequence(data_root / name).groundtruth[:n]
    boxes[1:, 0] += dx
    return boxes


@pytest.fixture()
def benchmark_folder(data_root, names, tmp_path) -> Path:
    """What 'nrmlc benchmark --max-frames 6 --seeds 0,1 --sequences A,B' leaves (its manifest's format)."""
    out = tmp_path / "NRMLC"
    runs = {}
    for name in names[:2]:
        write_boxes(out / f"{name}.txt", shifted(data_root, name, 1.0, 6))
        write_boxes(out / "seeds" / "1" / f"{name}.txt", shifted(data_root, name, 2.0, 6))
        runs[name] = {str(seed): {"frames": 6, "fps": 100.0 if name == names[0] else 50.0, "scores": None,
                                  "code_version": "test"} for seed in (0, 1)}
    manifest = {"settings": {"params": {}, "max_frames": 6, "data": str(data_root.resolve())},
                "primary_seed": 0, "runs": runs}
    (out / "benchmark.json").write_text(json.dumps(manifest))
    return out


@pytest.fixture()
def peer(data_root, names, tmp_path) -> Path:
    """Another tracker's folder: every sequence, every frame."""
    folder = tmp_path / "Peer"
    for name in names:
        write_boxes(folder / f"{name}.txt", shifted(data_root, name, 4.0))
    return folder


# ------------------------------------------------------------------ like with like
def test_a_benchmark_folder_sets_what_every_tracker_is_scored_on(data_root, names, benchmark_folder, peer, capsys):
    comparison = compare([benchmark_folder, peer], data_root)
    assert comparison.sequences == names[:2] and comparison.max_frames == 6
    mine, theirs = comparison.trackers
    assert mine.summary()["missing_frames"] == 0 and theirs.summary()["missing_frames"] == 0
    expected = np.mean([evaluate(shifted(data_root, n, 4.0)[:6], open_sequence(data_root / n).groundtruth[:6])
                        .success_auc for n in names[:2]])
    assert theirs.summary()["success_auc"] == pytest.approx(expected)

    code, out, err = run_main(["evaluate", "--results", benchmark_folder, peer, "--data", data_root], capsys)
    assert code == 0, err
    first = out.splitlines()[0]
    assert first.startswith("scored: 2 sequences (those run in the benchmark.json of NRMLC), the first 6 frames "
                            "(the --max-frames of NRMLC); NRMLC seed 0 of 0,1"), first
    assert "other trackers their one result per sequence" in first
    assert names[2] not in out
    # fps from the manifest: 6 frames at 100 fps and 6 at 50 fps are 12 frames in 0.18 s.
    assert mine.fps == pytest.approx(12 / (6 / 100 + 6 / 50)) and theirs.fps is None

    # --all-seeds: both seeds said; explicit --sequences and --max-frames win over the manifest.
    code, out, _ = run_main(["evaluate", "--results", benchmark_folder, "--data", data_root, "--all-seeds"], capsys)
    assert code == 0 and "NRMLC seeds 0,1;" in out.splitlines()[0] + ";"
    everything = compare([benchmark_folder, peer], data_root, sequences=names, max_frames=10)
    assert everything.sequences == names and everything.max_frames == 10
    assert everything.trackers[0].files[names[2]] is None


def test_different_frame_caps_score_everyone_on_the_smallest(data_root, names, benchmark_folder, tmp_path):
    other = tmp_path / "Other"
    shutil.copytree(benchmark_folder, other)
    manifest = json.loads((other / "benchmark.json").read_text())
    manifest["settings"]["max_frames"] = None
    (other / "benchmark.json").write_text(json.dumps(manifest))
    comparison = compare([other, benchmark_folder], data_root)
    assert comparison.max_frames == 6
    assert any("different frame caps" in n and "first 6 frames" in n for n in comparison.notes)


def test_a_missing_sequence_is_shown_missing_and_the_means_say_over_what(data_root, names, peer, tmp_path, capsys):
    partial = tmp_path / "Partial"
    write_boxes(partial / f"{names[0]}.txt", shifted(data_root, names[0], 1.0))
    table_csv = tmp_path / "out" / "c.csv"
    code, out, err = run_main(["evaluate", "--results", peer, partial, "--data", data_root, "--csv", table_csv],
                              capsys)
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0] == "scored: 3 sequences, all frames; one result per tracker and sequence"
    row = next(line for line in lines if line.startswith(names[1]))
    assert row.split()[-1] == "-"
    assert any(line.startswith("Partial ") and " 1/3 " in line for line in lines)
    assert "means over the 3 scored" in out and "counts as every frame failed" in out
    rows = list(csv.DictReader(table_csv.open()))
    missing = next(r for r in rows if r["tracker"] == "Partial" and r["sequence"] == names[1])
    assert missing["file"] == "" and missing["success_auc"] == "" and missing["missing_frames"] == "9"
    total = next(r for r in rows if r["tracker"] == "Partial" and r["sequence"] == "ALL")
    assert total["sequences"] == "3"


def test_names_differing_only_by_case_are_refused(data_root, names, tmp_path, capsys):
    folder = tmp_path / "Twice"
    write_boxes(folder / f"{names[0]}.txt", shifted(data_root, names[0], 1.0))
    write_boxes(folder / f"{names[0].upper()}.txt", shifted(data_root, names[0], 2.0))
    if len({p.name for p in folder.iterdir()}) < 2:
        pytest.skip("this file system does not tell names apart by case")
    code, _, err = run_main(["evaluate", "--results", folder, "--data", data_root], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"{names[0].upper()}.txt and " in err and f"{names[0]}.txt both name sequence" in err


def test_a_folder_without_result_files_is_refused_in_one_line(data_root, names, peer, tmp_path, capsys):
    """A sequence folder, the data root or a folder of misnamed files is no tracker's results: an
    all-zero table would read as a tracker that failed everywhere."""
    misnamed = tmp_path / "misnamed"
    for name in names:
        write_boxes(misnamed / f"{name}_boxes.txt", shifted(data_root, name, 1.0))
    for folder in (data_root / names[0], data_root, misnamed):
        code, out, err = run_main(["evaluate", "--results", peer, folder, "--data", data_root], capsys)
        assert code == 2 and out == "", err
        assert err.count("\n") == 1 and err.startswith(f"error: {folder}: no result files (<Seq>.txt or "
                                                        f"<Seq>_<Tracker>.mat) for any of the 3 sequences")
    with pytest.raises(DataError, match="no result files"):
        compare([misnamed], data_root)
    code, _, err = run_main(["evaluate", "--results", peer, "--data", data_root], capsys)
    assert code == 0, err


# ------------------------------------------------------------------ one file
def test_single_file_numbers_say_which_frames_they_are_over(data_root, names, tmp_path, capsys):
    short = tmp_path / "short.txt"
    write_boxes(short, shifted(data_root, names[0], 1.0, 4))  # 4 of 10 frames
    truth = data_root / names[0] / "groundtruth_rect.txt"
    with pytest.warns(UserWarning, match="4 result boxes for 10 ground-truth boxes"):
        code, out, err = run_main(["evaluate", "--results", short, "--groundtruth", truth], capsys)
    assert code == 0, err
    text = dict(line.split(" : ", 1) for line in out.splitlines())
    assert text["frames evaluated"].startswith("9 (the annotated frames after frame 1): 3 with a prediction, "
                                               "6 missing")
    assert text["mean CLE        "].endswith("(the 3 frames with a prediction)")
    assert "(all 9 frames, missing = failed; " in text["mean overlap    "]
    assert "over the 3 with a prediction" in text["mean overlap    "]
    assert text["success AUC     "].endswith("(all 9 frames, missing = failed)")
    with pytest.warns(UserWarning):
        code, out, _ = run_main(["evaluate", "--results", short, "--groundtruth", truth, "--json"], capsys)
    summary = json.loads(out)
    assert summary["n_predicted"] == 3 and summary["n_frames"] == 9 and "n_predicted" in summary["frames"]
    with pytest.warns(UserWarning):
        code, _, err = run_main(["evaluate", "--results", short, "--groundtruth", truth,
                                 "--csv", tmp_path / "one.csv", "--plot", tmp_path / "one.png"], capsys)
    assert code == 0, err
    assert (tmp_path / "one.csv").read_text().count("\n") == 3  # header, the sequence, ALL
    assert (tmp_path / "one.png").read_bytes()[:4] == b"\x89PNG"


# ------------------------------------------------------------------ outputs are never inputs
@pytest.mark.parametrize("case", ["groundtruth", "result-file", "in-data", "in-results", "twice", "plot-as-csv"])
def test_outputs_that_are_inputs_are_refused(case, data_root, names, peer, tmp_path, capsys):
    truth = data_root / names[0] / "groundtruth_rect.txt"
    result = peer / f"{names[0]}.txt"
    before = {p: p.read_bytes() for p in (truth, result)}
    folders = ["--results", peer, "--data", data_root]
    argv, expected = {
        "groundtruth": (["--results", result, "--groundtruth", truth, "--csv", truth],
                        rf"--csv {truth}: is an input of this run"),
        "result-file": (["--results", result, "--groundtruth", truth, "--plot", result],
                        rf"--plot {result}: is an input of this run"),
        "in-data": ([*folders, "--csv", data_root / "scores.csv"], rf"--csv {data_root}/scores\.csv: is inside"),
        "in-results": ([*folders, "--plot", peer / "sub" / "p.png"], r"p\.png: is inside .*Peer, which this evaluation"),
        "twice": ([*folders, "--plot", tmp_path / "x.png", "--speed-plot", tmp_path / "x.png"],
                  r"--speed-plot \S+x\.png: the same file as --plot"),
        "plot-as-csv": ([*folders, "--plot", tmp_path / "x.png", "--csv", tmp_path / "x.png"],
                        r"--csv \S+x\.png: the same file as --plot"),
    }[case]
    code, out, err = run_main(["evaluate", *argv], capsys)
    assert code == 2 and out == "", err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    import re

    assert re.search(expected, lines[0]), lines[0]
    assert {p: p.read_bytes() for p in before} == before
    assert not (data_root / "scores.csv").exists() and not (tmp_path / "x.png").exists()


# ------------------------------------------------------------------ attributes and speed
def test_attribute_files_use_the_toolkits_order(tmp_path):
    path = tmp_path / "Car4.txt"
    path.write_text("1,0,1,0,0,0,0,0,0,0,0\n")  # the benchmark's Car4: illumination and scale variation
    assert read_attribute_file(path) == {"IV", "SV"}
    assert [code for code, _ in ATTRIBUTES] == ["IV", "OPR", "SV", "OCC", "DEF", "MB", "FM", "IPR", "OV", "BC", "LR"]
    for bad in ("1,0,1\n", "1,0,1,0,0,0,0,0,0,0,2\n", "yes\n"):
        path.write_text(bad)
        with pytest.raises(DataError, match=r"Car4\.txt: expected 11 flags"):
            read_attribute_file(path)


def test_two_target_sequences_take_their_own_file_or_their_folders(tmp_path):
    (tmp_path / "Skating2.1.txt").write_text("0 0 1 0 0 0 0 0 0 0 0")
    (tmp_path / "Jogging.txt").write_text("0,0,0,1,0,0,0,0,0,0,0")
    found, notes = read_attributes(tmp_path, ["Skating2-1", "Jogging-2", "Toy"])
    assert found == {"Skating2-1": {"SV"}, "Jogging-2": {"OCC"}}
    assert len(notes) == 1 and "Toy" in notes[0]


def test_scores_per_attribute_table_csv_and_plots(data_root, names, benchmark_folder, peer, tmp_path, capsys):
    attributes = tmp_path / "att"
    attributes.mkdir()
    (attributes / f"{names[0]}.txt").write_text("0,0,1,0,0,0,0,0,0,0,0\n")  # SV
    (attributes / f"{names[1]}.txt").write_text("1,0,1,0,0,0,0,0,0,0,0\n")  # IV, SV
    out_csv, heatmap, speed = tmp_path / "o" / "c.csv", tmp_path / "o" / "a.png", tmp_path / "o" / "s.png"
    code, out, err = run_main(["evaluate", "--results", benchmark_folder, peer, "--data", data_root,
                               "--attributes", attributes, "--csv", out_csv, "--attribute-plot", heatmap,
                               "--speed-plot", speed], capsys)
    assert code == 0, err
    assert "IV(1)" in out and "SV(2)" in out and "OCC(0)" in out
    comparison = compare([benchmark_folder, peer], data_root)
    nrmlc = comparison.trackers[0]
    iv = nrmlc.evaluations[names[1]].success_auc
    row = next(line for line in out.splitlines() if line.startswith("NRMLC ") and "-" in line)
    assert f"{iv:.3f}" in row
    rows = [r for r in csv.DictReader(out_csv.open()) if r["attribute"]]
    assert {(r["tracker"], r["attribute"], r["sequences"]) for r in rows} == {
        (t, a, n) for t in ("NRMLC", "Peer") for a, n in (("IV", "1"), ("SV", "2"))}
    sv = next(r for r in rows if r["tracker"] == "NRMLC" and r["attribute"] == "SV")
    assert float(sv["success_auc"]) == pytest.approx(nrmlc.summary()["success_auc"])
    for plot in (heatmap, speed):
        assert plot.read_bytes()[:4] == b"\x89PNG" and plot.stat().st_size > 5_000
    assert "--speed-plot: left out Peer (no fps recorded)" in err


def test_speed_and_attribute_plot_errors(tmp_path, capsys, peer, data_root):
    code, _, err = run_main(["evaluate", "--results", peer, "--data", data_root, "--speed-plot", tmp_path / "s.png"],
                            capsys)
    assert code == 2 and "no tracker's results record their speed" in err
    code, _, err = run_main(["evaluate", "--results", peer, "--data", data_root, "--attribute-plot",
                             tmp_path / "a.png"], capsys)
    assert code == 2 and "--attribute-plot needs --attributes" in err
    code, _, err = run_main(["evaluate", "--results", peer, "--data", data_root, "--speed-plot", tmp_path / "s.xyz"],
                            capsys)
    assert code == 2 and "--speed-plot" in err and "'xyz'" in err


def kept_figures(monkeypatch) -> list:
    """The figures the plots draw, kept open (``plt.close`` is called on each after it is saved)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kept = []
    monkeypatch.setattr(plt, "close", kept.append)
    return kept


def synthetic_comparison(data_root, names, fps=()) -> Comparison:
    """Trackers from 1 px to 24 px off on one sequence (MIL the worst), with the given fps."""
    sequence = open_sequence(data_root / names[0])
    trackers = []
    for k, name in enumerate(["NRMLC", "CSRT", "KCF", "TLD", "MIL"]):
        boxes = shifted(data_root, names[0], 1.0 + 6.0 * k)
        trackers.append(TrackerScores(name, data_root, files={sequence.name: data_root / f"{name}.txt"},
                                      evaluations={sequence.name: evaluate(boxes, sequence.groundtruth)},
                                      speeds={sequence.name: (fps[k], len(boxes))} if fps else {}))
    return Comparison([sequence.name], trackers)


def test_the_comparison_legends_cover_no_curve(data_root, names, tmp_path, monkeypatch):
    figures = kept_figures(monkeypatch)
    plot_comparison(synthetic_comparison(data_root, names), tmp_path / "p.png")
    figure = figures[0]
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    for axis in figure.axes:
        legend = axis.get_legend().get_window_extent(renderer)
        assert not legend.overlaps(axis.get_window_extent(renderer)), axis.get_title()


@pytest.mark.parametrize("fps", [(2.0, 5.0, 9.0, 30.0, 80.0), (0.2, 0.5, 1.0, 3.0, 8.0), (20.0, 25.0, 30.0, 35.0, 45.0),
                                 (0.3, 2.5, 40.0, 900.0, 3000.0)])
def test_the_speed_plot_fps_labels_do_not_overlap(fps, data_root, names, tmp_path, monkeypatch):
    """Over about 1.5 decades matplotlib's own log labels name minor ticks (3x10^1, 4x10^1) into each other."""
    figures = kept_figures(monkeypatch)
    plot_speed(synthetic_comparison(data_root, names, fps), tmp_path / "s.png")
    axis = figures[0].axes[0]
    figures[0].canvas.draw()
    renderer = figures[0].canvas.get_renderer()
    low, high = axis.get_xlim()
    labels = sorted((label.get_window_extent(renderer) for label in axis.get_xticklabels(which="both")
                     if label.get_visible() and label.get_text() and low <= label.get_position()[0] <= high),
                    key=lambda box: box.x0)
    assert len(labels) >= 2
    assert all(left.x1 + 2 < right.x0 for left, right in zip(labels, labels[1:]))
