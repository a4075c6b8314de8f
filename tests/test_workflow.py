"""A researcher's workflow: a video file tracked end to end, ``benchmark`` over a data root
(OTB result layout, summary, resume), and ``evaluate`` comparing several trackers' result
folders with plots. Everything runs on a few tiny synthetic frames with few particles.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from nrmlc.workbench.benchmark import parse_seeds
from nrmlc.cli import main
from nrmlc.workbench.score import compare
from nrmlc.data import open_sequence, read_box_file
from nrmlc.testing.scenes import write_small_suite
from nrmlc.data.video_file import VideoFileSequence
from nrmlc.errors import DataError, ParameterError
from nrmlc.workbench.metrics import evaluate, overlaps

FAST = ["--param", "n_particles=50", "--param", "n_positive=10", "--param", "n_negative=20",
        "--param", "max_positive=20"]
N_FRAMES = 12
SIZE = (72, 96)  # height, width


def run_main(argv, capsys) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ------------------------------------------------------------------ video files
def _target_frames(n_frames: int = N_FRAMES) -> tuple[list[np.ndarray], np.ndarray]:
    """A textured 20x16 target moving 2 px right and 1 px down per frame on a smooth background.

    Returns the BGR frames and the true 1-based boxes.
    """
    rng = np.random.default_rng(3)
    height, width = SIZE
    yy, xx = np.mgrid[0:height, 0:width]
    background = (60 + 40 * np.sin(xx / 9.0) * np.cos(yy / 7.0)).astype(np.float64)
    texture = rng.uniform(150, 255, (16, 20))
    frames, boxes = [], []
    for index in range(n_frames):
        x0, y0 = 20 + 2 * index, 20 + index
        image = background.copy()
        image[y0:y0 + 16, x0:x0 + 20] = texture
        frames.append(cv2.cvtColor(image.astype(np.uint8), cv2.COLOR_GRAY2BGR))
        boxes.append((x0 + 1, y0 + 1, 20, 16))
    return frames, np.array(boxes, dtype=np.float64)


def _write_video(path: Path, fourcc: str, frames) -> Path:
    height, width = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 25.0, (width, height))
    if not writer.isOpened():
        pytest.skip(f"this OpenCV cannot write {fourcc} to {path.suffix}")
    for frame in frames:
        writer.write(frame)
    writer.release()
    return path


@pytest.mark.parametrize("name, fourcc", [("clip.avi", "MJPG"), ("clip.mp4", "mp4v")])
def test_video_file_tracked_end_to_end(name, fourcc, tmp_path, capsys):
    frames, truth = _target_frames()
    video = _write_video(tmp_path / name, fourcc, frames)
    out = tmp_path / "boxes.txt"
    box = ",".join(f"{v:g}" for v in truth[0])
    code, _, err = run_main(["track", video, "--out", out, "--init-box", box, *FAST], capsys)
    assert code == 0, err
    boxes = read_box_file(out, predictions=True)
    assert boxes.shape == (N_FRAMES, 4)
    np.testing.assert_array_equal(boxes[0], truth[0])
    assert np.isfinite(boxes).all()
    # It follows the target (a lossy codec, 50 particles; measured 0.89 with MJPG, 0.91 with mp4v:
    # a loss of 0.1 fails it).
    assert overlaps(boxes, truth)[1:].mean() > 0.79, boxes
    assert "clip: 12 frames" in err


def test_video_frames_are_the_decoded_frames_in_any_order(tmp_path):
    frames, _ = _target_frames()
    video = _write_video(tmp_path / "clip.avi", "MJPG", frames)
    capture = cv2.VideoCapture(str(video))
    decoded = []
    while True:
        ok, image = capture.read()
        if not ok:
            break
        decoded.append(image)
    sequence = open_sequence(video, init_box=(21, 21, 20, 16))
    assert isinstance(sequence, VideoFileSequence)
    assert len(sequence) == len(decoded) == N_FRAMES
    assert sequence.frame_size == SIZE and sequence.name == "clip"
    assert not sequence.annotated.any()
    # Backward and forward jumps give the frame itself, not a neighbour or a key frame.
    for index in (9, 3, 4, 11, 0, 7):
        np.testing.assert_array_equal(sequence.raw_frame(index), decoded[index])
    np.testing.assert_array_equal(list(sequence)[5], sequence.frame(5))


def test_video_frame_count_does_not_trust_the_container(tmp_path, capsys):
    """A cut-off AVI still announces its full length in its header; only decodable frames count."""
    frames, truth = _target_frames(20)
    data = _write_video(tmp_path / "full.avi", "MJPG", frames).read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    announced = cv2.VideoCapture(str(cut)).get(cv2.CAP_PROP_FRAME_COUNT)
    sequence = open_sequence(cut, init_box=truth[0])
    assert 1 <= len(sequence) < 20
    if announced > 0:
        assert announced != len(sequence)  # the case this guards against
    out = tmp_path / "boxes.txt"
    code, _, err = run_main(["track", cut, "--out", out, "--init-box", ",".join(map(str, truth[0])), *FAST], capsys)
    assert code == 0, err
    assert len(read_box_file(out, predictions=True)) == len(sequence)


def test_video_without_box_names_the_cli_flag(tmp_path, capsys):
    frames, _ = _target_frames(3)
    video = _write_video(tmp_path / "clip.avi", "MJPG", frames)
    code, _, err = run_main(["track", video, "--out", tmp_path / "r.txt"], capsys)
    assert code == 2
    assert err.count("\n") == 1 and "--init-box X,Y,W,H" in err and "init_box=" in err
    assert not (tmp_path / "r.txt").exists()


def test_track_refuses_to_write_over_the_video(tmp_path, capsys):
    frames, truth = _target_frames(3)
    video = _write_video(tmp_path / "clip.avi", "MJPG", frames)
    before = video.read_bytes()
    code, _, err = run_main(["track", video, "--out", video, "--init-box", "21,21,20,16", *FAST], capsys)
    assert code == 2 and "input" in err
    assert video.read_bytes() == before


def test_a_file_that_is_not_a_video_is_one_error_line(tmp_path, capsys):
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"\x00not a video" * 100)
    code, _, err = run_main(["track", junk, "--out", tmp_path / "r.txt", "--init-box", "1,1,8,8"], capsys)
    assert code == 2
    assert "junk.mp4: not a folder, and not a video file OpenCV can read" in err.splitlines()[-1]


def test_frame_folder_without_groundtruth(tmp_path, capsys):
    """A bare folder of frames (no img/ level, no ground truth) with --init-box."""
    frames, truth = _target_frames()
    folder = tmp_path / "frames"
    folder.mkdir()
    for index, frame in enumerate(frames, start=1):
        cv2.imwrite(str(folder / f"{index:04d}.png"), frame)
    out = tmp_path / "boxes.txt"
    code, _, err = run_main(["track", folder, "--out", out, *FAST], capsys)
    assert code == 2 and "--init-box" in err
    code, _, err = run_main(["track", folder, "--out", out, "--init-box", "21,21,20,16", *FAST], capsys)
    assert code == 0, err
    boxes = read_box_file(out, predictions=True)
    assert len(boxes) == N_FRAMES and overlaps(boxes, truth)[1:].mean() > 0.79  # measured 0.89


def test_video_sequence_pickles_for_worker_processes(tmp_path):
    import pickle

    frames, _ = _target_frames(4)
    video = _write_video(tmp_path / "clip.avi", "MJPG", frames)
    sequence = open_sequence(video, init_box=(21, 21, 20, 16))
    sequence.frame(2)  # an open capture must not stop pickling
    clone = pickle.loads(pickle.dumps(sequence))
    np.testing.assert_array_equal(clone.frame(3), sequence.frame(3))
    assert clone.identity == sequence.identity


# ------------------------------------------------------------------ benchmark
@pytest.fixture(scope="module")
def data_root(tmp_path_factory) -> Path:
    return write_small_suite(tmp_path_factory.mktemp("data"), n_sequences=2)


def _benchmark(data_root, out, cache, capsys, *extra):
    return run_main(["benchmark", data_root, "--out", out, "--cache", cache, "--jobs", "1", *FAST, *extra], capsys)


def test_parse_seeds():
    assert parse_seeds("0-4") == (0, 1, 2, 3, 4)
    assert parse_seeds("3") == (3,)
    assert parse_seeds("0-2,7,1") == (0, 1, 2, 7)
    for bad in ("", "a", "4-2", "-1"):
        with pytest.raises(ParameterError):
            parse_seeds(bad)


def test_benchmark_writes_otb_layout_and_resumes(data_root, tmp_path, capsys):
    out = tmp_path / "results" / "NRMLC"
    names = sorted(p.name for p in data_root.iterdir())
    # First only one sequence (as if interrupted after it), then everything with two seeds.
    code, _, err = _benchmark(data_root, out, tmp_path / "cache1", capsys, "--sequences", names[0])
    assert code == 0, err
    assert "0 finished, 1 to run" in err
    assert sorted(p.name for p in out.glob("*.txt")) == [f"{names[0]}.txt"]
    first_bytes = (out / f"{names[0]}.txt").read_bytes()

    code, table, err = _benchmark(data_root, out, tmp_path / "cache2", capsys, "--seeds", "0-1")
    assert code == 0, err
    assert "1 finished, 3 to run (0 of them from the run cache" in err
    # Only the three missing runs were computed (the second cache holds exactly those).
    assert len(list((tmp_path / "cache2").glob("*.npz"))) == 3
    assert (out / f"{names[0]}.txt").read_bytes() == first_bytes
    for name in names:
        assert len(read_box_file(out / f"{name}.txt")) == 10
        assert len(read_box_file(out / "seeds" / "1" / f"{name}.txt")) == 10
    assert all(name in table for name in names)

    # A third run recomputes nothing, even from an empty cache, and rewrites no result.
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("*.txt")}
    code, _, err = _benchmark(data_root, out, tmp_path / "cache3", capsys, "--seeds", "0-1")
    assert code == 0, err
    assert "4 finished, 0 to run" in err
    assert not (tmp_path / "cache3").exists() or not any((tmp_path / "cache3").iterdir())
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.txt")} == stamps
    # Another folder on the second cache: every run is said to come from the cache.
    code, _, err = _benchmark(data_root, tmp_path / "other", tmp_path / "cache2", capsys, "--seeds", "0-1",
                              "--sequences", ",".join(names[1:]))
    assert code == 0, err
    assert f"0 finished, {2 * len(names[1:])} to run ({2 * len(names[1:])} of them from the run cache" in err

    # The summary holds what evaluate() gives on the written files.
    summary = json.loads((out / "summary.json").read_text())
    rows = {(r["sequence"], r["seed"]): r for r in summary["runs"]}
    assert set(rows) == {(n, s) for n in names for s in (0, 1)}
    for name in names:
        truth = open_sequence(data_root / name).groundtruth
        scores = evaluate(read_box_file(out / "seeds" / "1" / f"{name}.txt"), truth)
        assert rows[name, 1]["success_auc"] == pytest.approx(scores.success_auc)
        assert rows[name, 1]["mean_center_error"] == pytest.approx(scores.mean_center_error)
        assert rows[name, 1]["fps"] > 0
    csv_lines = (out / "summary.csv").read_text().splitlines()
    assert csv_lines[0].startswith("sequence,seed,frames") and len(csv_lines) == 1 + 4


def test_benchmark_never_overwrites_what_it_did_not_make(data_root, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "Car4.txt").write_text("1,2,3,4\n")
    code, _, err = _benchmark(data_root, out, tmp_path / "cache", capsys)
    assert code == 2 and "not made by nrmlc benchmark" in err
    assert (out / "Car4.txt").read_text() == "1,2,3,4\n"


def test_benchmark_refuses_other_settings_in_the_same_folder(data_root, tmp_path, capsys):
    out = tmp_path / "NRMLC"
    name = sorted(p.name for p in data_root.iterdir())[0]
    code, _, err = _benchmark(data_root, out, tmp_path / "cache", capsys, "--sequences", name, "--max-frames", "5")
    assert code == 0, err
    assert len(read_box_file(out / f"{name}.txt")) == 5
    before = (out / f"{name}.txt").read_bytes()
    code, _, err = _benchmark(data_root, out, tmp_path / "cache", capsys, "--sequences", name,
                              "--max-frames", "5", "--param", "lam=0.5")
    assert code == 2 and "lam=1.0 there, 0.5 now" in err and "another --out" in err
    assert (out / f"{name}.txt").read_bytes() == before


def test_benchmark_unknown_sequence_is_one_error_line(data_root, tmp_path, capsys):
    code, _, err = _benchmark(data_root, tmp_path / "o", tmp_path / "cache", capsys, "--sequences", "Nope")
    assert code == 2 and "no sequence Nope" in err and "synth-01" in err


# ------------------------------------------------------------------ comparison
@pytest.fixture(scope="module")
def two_trackers(data_root, tmp_path_factory):
    """NRMLC's benchmark folder and a second tracker's folder (boxes shifted, one file short, one missing)."""
    base = tmp_path_factory.mktemp("results")
    nrmlc_folder = base / "NRMLC"
    assert main(["benchmark", str(data_root), "--out", str(nrmlc_folder), "--cache", str(base / "cache"),
                 "--jobs", "1", *FAST]) == 0
    other = base / "Shifted"
    other.mkdir()
    names = sorted(p.name for p in data_root.iterdir())
    boxes = read_box_file(nrmlc_folder / f"{names[0]}.txt")
    boxes[1:, 0] += 6.0
    (other / f"{names[0]}.txt").write_text("\n".join(",".join(map(str, row)) for row in boxes[:7]) + "\n")
    return nrmlc_folder, other, names


def test_evaluate_compares_folders_with_plots(data_root, two_trackers, tmp_path, capsys):
    nrmlc_folder, other, names = two_trackers
    plot, table_csv = tmp_path / "cmp.png", tmp_path / "cmp.csv"
    code, out, err = run_main(["evaluate", "--results", nrmlc_folder, other, "--data", data_root,
                               "--plot", plot, "--csv", table_csv], capsys)
    assert code == 0, err
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and plot.stat().st_size > 10_000
    lines = out.splitlines()
    # The benchmark folder's manifest says what was run; the first line says what was scored.
    assert lines[0] == ("scored: 2 sequences (those run in the benchmark.json of NRMLC), all frames; NRMLC seed 0, "
                        "the other trackers their one result per sequence")
    nrmlc_row = next(line for line in lines if line.startswith("NRMLC "))
    other_row = next(line for line in lines if line.startswith("Shifted "))
    assert "2/2" in nrmlc_row and "1/2" in other_row
    assert f"no result file for {names[1]}" in err and "7 lines for 10 frames" in err

    # The numbers are the OTB averages over sequences of nrmlc.workbench.metrics' per-sequence scores.
    truths = [open_sequence(data_root / n).groundtruth for n in names]
    mine = [evaluate(read_box_file(nrmlc_folder / f"{n}.txt"), t) for n, t in zip(names, truths)]
    theirs = [evaluate(read_box_file(other / f"{names[0]}.txt"), truths[0]), evaluate(np.empty((0, 4)), truths[1])]
    comparison = compare([nrmlc_folder, other], data_root)
    nrmlc_scores, other_scores = (t.summary() for t in comparison.trackers)
    assert nrmlc_scores["success_auc"] == pytest.approx(np.mean([e.success_auc for e in mine]))
    assert other_scores["success_auc"] == pytest.approx(np.mean([e.success_auc for e in theirs]))
    assert other_scores["precision_20"] == pytest.approx(np.mean([e.precision_20 for e in theirs]))
    assert other_scores["missing_frames"] == 3 + 9  # three rows short on one sequence, no file for the other
    assert f"{nrmlc_scores['success_auc']:.3f}" in nrmlc_row
    csv_rows = table_csv.read_text().splitlines()
    assert csv_rows[0].startswith("tracker,seed,sequence") and len(csv_rows) == 1 + 2 * 3

    # --common scores only the sequences both have; --names renames.
    code, out, _ = run_main(["evaluate", "--results", nrmlc_folder, other, "--data", data_root, "--common",
                             "--names", "Ours,Theirs"], capsys)
    assert code == 0 and "Ours" in out and "Theirs" in out and "1/1" in out


def test_evaluate_all_seeds_averages_a_benchmark_folder(data_root, tmp_path, capsys):
    out = tmp_path / "NRMLC"
    code, _, err = _benchmark(data_root, out, tmp_path / "cache", capsys, "--seeds", "4,2,7", "--preset", "paper")
    assert code == 0, err
    assert json.loads((out / "benchmark.json").read_text())["settings"]["params"]["template_sampling"] == "annulus"
    names = sorted(p.name for p in data_root.iterdir())
    per_seed = []
    for folder in (out, out / "seeds" / "2", out / "seeds" / "7"):  # seed 4 (the first given) is the top level
        per_seed.append(np.mean([evaluate(read_box_file(folder / f"{n}.txt"),
                                          open_sequence(data_root / n).groundtruth).success_auc for n in names]))
    assert len(set(per_seed)) > 1  # the seeds differ, so averaging them is not a no-op

    one = compare([out], data_root).trackers[0]
    assert one.summary()["seeds"] == 1 and one.summary()["success_auc"] == pytest.approx(per_seed[0])
    assert any("2 more seed(s)" in note and "--all-seeds" in note for note in one.notes)

    code, table, err = run_main(["evaluate", "--results", out, "--data", data_root, "--all-seeds",
                                 "--csv", tmp_path / "c.csv"], capsys)
    assert code == 0, err
    every = compare([out], data_root, all_seeds=True).trackers[0]
    summary = every.summary()
    assert summary["seeds"] == 3 and every.seed_labels == ["4", "2", "7"]
    assert summary["success_auc"] == pytest.approx(np.mean(per_seed))
    assert summary["success_auc_std_over_seeds"] == pytest.approx(np.std(per_seed))
    assert "AUC sd" in table and f"{np.mean(per_seed):.3f}" in table
    rows = (tmp_path / "c.csv").read_text().splitlines()
    assert len(rows) == 1 + 3 * len(names) + 1 and any(r.startswith("NRMLC,7,") for r in rows)


def test_evaluate_finds_subfolders_and_refuses_other_versions(data_root, two_trackers, tmp_path, capsys):
    """Peer-results layout: files in a subfolder are found; a file starting elsewhere is not used."""
    nrmlc_folder, _, names = two_trackers
    peer = tmp_path / "Peer"
    (peer / "sparsepack").mkdir(parents=True)
    shutil.copy(nrmlc_folder / f"{names[0]}.txt", peer / "sparsepack" / f"{names[0]}.txt")
    wrong = read_box_file(nrmlc_folder / f"{names[1]}.txt") * 2.0  # "another resolution"
    (peer / f"{names[1]}.txt").write_text("\n".join(",".join(map(str, r)) for r in wrong) + "\n")
    comparison = compare([peer], data_root)
    tracker = comparison.trackers[0]
    assert tracker.files[names[0]] == peer / "sparsepack" / f"{names[0]}.txt"
    assert tracker.files[names[1]] is None
    assert any("not used" in note and "initial box" in note for note in tracker.notes)
    # A name map points a differently named file at a sequence.
    (peer / "OtherName.txt").write_text((nrmlc_folder / f"{names[1]}.txt").read_text())
    mapped = compare([peer], data_root, name_map={"othername": names[1].lower()}).trackers[0]
    assert mapped.files[names[1]] == peer / "OtherName.txt"


def test_evaluate_help_says_how_missing_predictions_count(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "Missing predictions" in text and "fewer lines than frames" in text and "failed frame" in text


def test_evaluate_single_file_form_still_works(data_root, two_trackers, capsys):
    nrmlc_folder, _, names = two_trackers
    code, out, err = run_main(["evaluate", "--results", nrmlc_folder / f"{names[0]}.txt", "--groundtruth",
                               data_root / names[0] / "groundtruth_rect.txt", "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["n_frames"] == 9
    code, _, err = run_main(["evaluate", "--results", nrmlc_folder / f"{names[0]}.txt"], capsys)
    assert code == 2 and "--groundtruth" in err


def test_evaluate_bad_folder_is_one_error_line(data_root, tmp_path, capsys):
    code, _, err = run_main(["evaluate", "--results", tmp_path / "absent", "--data", data_root], capsys)
    assert code == 2 and "absent: result folder not found" in err
    with pytest.raises(DataError):
        compare([tmp_path], tmp_path / "no-data")


def test_evaluate_refuses_an_unwritable_plot_before_scoring(data_root, two_trackers, tmp_path, capsys):
    nrmlc_folder, _, _ = two_trackers
    code, out, err = run_main(["evaluate", "--results", nrmlc_folder, "--data", data_root,
                               "--plot", tmp_path / "plot.xyz"], capsys)
    assert code == 2 and "--plot" in err and "'xyz'" in err and out == ""
    assert not (tmp_path / "plot.xyz").exists()


def test_benchmark_skips_a_folder_without_a_starting_box(data_root, tmp_path, capsys):
    root = tmp_path / "data"
    name = sorted(p.name for p in data_root.iterdir())[0]
    shutil.copytree(data_root / name, root / name)
    shutil.copytree(data_root / name / "img", root / "NoTruth" / "img")
    with pytest.warns(UserWarning, match="NoTruth: skipped, no ground-truth box on frame 1"):
        code, _, err = _benchmark(root, tmp_path / "out", tmp_path / "cache", capsys, "--max-frames", "3")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "out").glob("*.txt")) == [f"{name}.txt"]
    with pytest.warns(UserWarning, match="NoTruth: skipped"):
        code, _, err = _benchmark(root, tmp_path / "out2", tmp_path / "cache", capsys, "--sequences", "NoTruth")
    assert code == 2 and "no sequence with a ground-truth box" in err


def test_benchmark_keeps_finished_sequences_when_another_fails(data_root, tmp_path, capsys):
    """A broken frame in one sequence: one error line; the sequence that finished has its file and entry."""
    root = tmp_path / "data"
    names = sorted(p.name for p in data_root.iterdir())
    for name in names:
        shutil.copytree(data_root / name, root / name)
    # The broken sequence is the shorter one, so the longer (good) one runs first (longest first).
    broken = root / names[1]
    frames = sorted((broken / "img").iterdir())
    for extra in frames[6:]:
        extra.unlink()
    (broken / "groundtruth_rect.txt").write_text(
        "\n".join((broken / "groundtruth_rect.txt").read_text().splitlines()[:6]) + "\n")
    frames[4].write_bytes(b"not an image")
    out = tmp_path / "out"
    code, _, err = _benchmark(root, out, tmp_path / "cache", capsys)
    assert code == 2 and frames[4].name in err.splitlines()[-1]
    assert (out / f"{names[0]}.txt").is_file() and not (out / f"{names[1]}.txt").exists()
    assert list(json.loads((out / "benchmark.json").read_text())["runs"]) == [names[0]]
