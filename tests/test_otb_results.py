"""The OTB toolkit's ``<Seq>_<Tracker>.mat`` result files (nrmlc/workbench/otb_results.py) and their use in
``nrmlc evaluate``: small files written for the tests by :mod:`nrmlc.testing.otb_files`, and the
benchmark's real files when they are on this machine.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from nrmlc.cli import main
from nrmlc.workbench.score import compare
from nrmlc.data import open_sequence, read_box_file
from nrmlc.errors import DataError, ParameterError
from nrmlc.workbench.metrics import evaluate, overlaps
from nrmlc.workbench.otb_results import (
    find_otb_result,
    ivt_affine_boxes,
    l1_affine_boxes,
    otb_result_boxes,
    otb_trackers,
    read_otb_result,
    select_trackers,
    sequence_key,
    split_result_name,
)
from nrmlc.testing.otb_files import write_otb_result_files

FIXTURES: Path  # the small result files, written once per module by the fixture below
WORK = Path(__file__).resolve().parent.parent.parent
REAL_RESULTS = Path(os.environ.get("NRMLC_OTB_RESULTS", WORK / "devdata" / "otb_results"))
REAL_ANNOTATIONS = Path(os.environ.get("NRMLC_OTB_ANNOTATIONS", WORK / "shared" / "data" / "annotations" / "otb_tb100"))


@pytest.fixture(scope="module", autouse=True)
def _otb_result_files(tmp_path_factory):
    global FIXTURES
    FIXTURES = write_otb_result_files(tmp_path_factory.mktemp("otb_results"))


def truth() -> np.ndarray:
    """The fixtures' sequence: ten frames, box (11 + 2 i, 21 + i, 20, 30) on frame i."""
    i = np.arange(10, dtype=np.float64)
    return np.stack([11 + 2 * i, 21 + i, np.full_like(i, 20), np.full_like(i, 30)], axis=1)


def write_walker(root: Path, boxes: np.ndarray | None = None) -> Path:
    """``root/Walker``: ten 64x96 frames and target 2's ground truth (the sequence Walker-2)."""
    folder = root / "Walker"
    (folder / "img").mkdir(parents=True)
    rng = np.random.default_rng(0)
    for index in range(10):
        cv2.imwrite(str(folder / "img" / f"{index + 1:04d}.png"), rng.integers(0, 255, (64, 96), dtype=np.uint8))
    boxes = truth() if boxes is None else boxes
    (folder / "groundtruth_rect.2.txt").write_text("\n".join(",".join(f"{v:g}" for v in b) for b in boxes) + "\n")
    return folder


@pytest.fixture()
def walker(tmp_path):
    root = tmp_path / "data"
    write_walker(root)
    return root


class Standin:
    """What the readers need of a sequence: a name, a length, the ground truth."""

    def __init__(self, name, groundtruth):
        self.name, self.groundtruth = name, np.asarray(groundtruth, dtype=np.float64)

    def __len__(self):
        return len(self.groundtruth)


def run_main(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ------------------------------------------------------------------ names
@pytest.mark.parametrize("spelling, key", [
    ("Skating2.1", "skating2-1"), ("Skating2-1", "skating2-1"), ("skating2_1", "skating2-1"),
    ("jogging-1", "jogging-1"), ("Jogging.2", "jogging-2"), ("Human4.2", "human4-2"), ("dudek", "dudek"),
    ("Car24", "car24"), ("BlurCar1", "blurcar1"), ("fleetFace", "fleetface")])
def test_sequence_key_joins_the_benchmarks_spellings(spelling, key):
    assert sequence_key(spelling) == key


@pytest.mark.parametrize("stem, parts", [
    ("Biker_ASLA", ("Biker", "ASLA")), ("Biker_KCF_GaussHog", ("Biker", "KCF_GaussHog")),
    ("Skating2.1_MEEM", ("Skating2.1", "MEEM")), ("jogging-1_TLD", ("jogging-1", "TLD")),
    ("Jogging_1_siamfc3s", ("Jogging_1", "siamfc3s")), ("Human4_2_siamfc3s", ("Human4_2", "siamfc3s")),
    ("Biker", None)])
def test_result_file_names_split_into_sequence_and_tracker(stem, parts):
    assert split_result_name(stem) == parts


def test_trackers_of_a_folder_and_selection():
    assert otb_trackers(FIXTURES) == ["AffTracker", "BareTracker", "L1Tracker", "LateTracker", "OddTracker",
                                      "RectTracker"]
    assert select_trackers(FIXTURES, ["recttracker", "AffTracker"]) == ["RectTracker", "AffTracker"]
    with pytest.raises(ParameterError, match=r"no OTB results of Nope \(trackers there: AffTracker"):
        select_trackers(FIXTURES, ["Nope"])


# ------------------------------------------------------------------ conversion
def test_rect_is_taken_as_it_is_from_any_integer_class():
    result = read_otb_result(FIXTURES / "walker.2_RectTracker.mat")
    expected = truth()
    expected[1:, 0] += 3
    assert result.type == "rect" and result.offset == 0 and result.fps == 50.0
    assert result.boxes.dtype == np.float64
    np.testing.assert_array_equal(result.boxes, expected)


def test_ivt_affine_is_the_floored_corners_of_the_template():
    result = read_otb_result(FIXTURES / "walker.2_AffTracker.mat")
    assert result.type == "ivtAff" and result.fps == 2.5
    np.testing.assert_array_equal(result.boxes[0], truth()[0])  # frame 0: the initial box, exactly
    # Independently: map the corners (u, v) = (-w/2, -h/2) and (w/2, h/2) of the (w, h) = (32, 24)
    # template (not square: a reader taking tmplsize as (h, w) fails) with M = [tx a11 a12; ty a21 a22].
    import scipy.io

    fields = scipy.io.loadmat(FIXTURES / "walker.2_AffTracker.mat")["results"][0, 0]
    states = fields["res"][0, 0]
    np.testing.assert_array_equal(fields["tmplsize"][0, 0].ravel(), [32, 24])
    for p, box in zip(states, result.boxes):
        matrix = np.array([[p[0], p[2], p[3]], [p[1], p[4], p[5]]])
        top_left = np.floor(matrix @ [1, -16, -12])
        bottom_right = np.floor(matrix @ [1, 16, 12])
        np.testing.assert_array_equal(box, [*top_left, *(bottom_right - top_left)])
    assert np.any(result.boxes[1:, 2] != 20)  # the shear of the later frames changes the size


def test_l1_affine_is_the_rounded_corners_plus_one():
    result = read_otb_result(FIXTURES / "walker.2_L1Tracker.mat")
    assert result.type == "L1Aff"
    np.testing.assert_array_equal(result.boxes, truth())
    # A 90-degree turn: rows become columns; the box runs from corner (1, 1) to corner (rows, cols).
    box = l1_affine_boxes([[0, 1, 1, 0, 10, 20]], (12, 15))[0]
    np.testing.assert_array_equal(box, [21, 11, 12 - 1 + 1, 15 - 1 + 1])


def test_ivt_boxes_of_an_axis_aligned_state():
    np.testing.assert_array_equal(ivt_affine_boxes([[270, 107, 0.5, 0, 0, 0.8125]], (32, 32)), [[262, 94, 16, 26]])
    # tmplsize is (w, h): a 32 wide, 24 high template, u along x and v along y.
    np.testing.assert_array_equal(ivt_affine_boxes([[270, 107, 0.5, 0, 0, 0.8125]], (32, 24)), [[262, 97, 16, 19]])
    # With a rotation and shear, a12 multiplies h/2 and a21 w/2: x from 270 -+ (0.5 * 16 + 0.25 * 12),
    # y from 107 -+ (-0.1 * 16 + 0.8125 * 12).
    np.testing.assert_array_equal(ivt_affine_boxes([[270, 107, 0.5, 0.25, -0.1, 0.8125]], (32, 24)),
                                  [[259, 98, 22, 17]])


def test_a_bare_result_matrix_is_rect_without_fps():
    result = read_otb_result(FIXTURES / "walker.2_BareTracker.mat")
    assert result.type == "rect" and result.fps is None and result.offset == 0
    np.testing.assert_array_equal(result.boxes, truth())


def test_an_unknown_type_is_one_error_naming_file_and_type(walker, capsys):
    with pytest.raises(DataError, match=r"walker\.2_OddTracker\.mat: result type 'LK_Aff' is not supported"):
        read_otb_result(FIXTURES / "walker.2_OddTracker.mat")
    code, out, err = run_main(["evaluate", "--results", f"{FIXTURES}:OddTracker", "--data", walker], capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "walker.2_OddTracker.mat" in err and "'LK_Aff'" in err


@pytest.mark.parametrize("content, expected", [
    (b"not a mat file at all", r"not a readable MAT file"),
    (None, r"no 'results' variable \(variables: other\)")])
def test_broken_files_are_one_error_naming_the_file(content, expected, tmp_path):
    import scipy.io

    path = tmp_path / "Walker-2_X.mat"
    if content is None:
        scipy.io.savemat(path, {"other": np.zeros((2, 2))})
    else:
        path.write_bytes(content)
    with pytest.raises(DataError, match=expected):
        read_otb_result(path)


# ------------------------------------------------------------------ frames
def test_a_later_start_and_an_early_end_are_missing_predictions(walker):
    sequence = open_sequence(walker / "Walker-2")
    assert sequence.name == "Walker-2"
    boxes, fps, notes = otb_result_boxes(FIXTURES, "LateTracker", sequence)
    assert boxes.shape == (10, 4) and fps == 50.0
    assert np.isnan(boxes[:3]).all() and np.isnan(boxes[8:]).all()
    np.testing.assert_array_equal(boxes[3:8], truth()[3:8])
    assert any("starts at frame 4" in n and "frames 1-3 count as missing" in n for n in notes)
    assert any("frames 4-8 of 10; the last 2 count as missing" in n for n in notes)
    scores = evaluate(boxes, sequence.groundtruth)
    assert scores.n_missing == 2 + 2 and scores.n_frames == 9  # frames 2-3 and 9-10; frame 1 is not scored
    cut, _, _ = otb_result_boxes(FIXTURES, "LateTracker", sequence, max_frames=6)
    assert cut.shape == (6, 4) and np.isnan(cut[:3]).all() and not np.isnan(cut[3:]).any()


def test_the_first_box_must_be_the_sequences():
    moved = truth() * 2.0  # "another resolution"
    path, boxes, fps, notes = find_otb_result(FIXTURES, "RectTracker", Standin("Walker-2", moved))
    assert path is None and boxes is None and fps is None
    assert any("not used, its first box" in n and "IoU" in n for n in notes)
    # For a late start the file's first box is compared with the sequence's box on that frame.
    late = truth()
    late[0] += 40
    _, boxes, _, _ = find_otb_result(FIXTURES, "LateTracker", Standin("Walker-2", late))
    assert boxes is not None


def test_no_file_for_another_sequence():
    boxes, fps, notes = otb_result_boxes(FIXTURES, "RectTracker", Standin("Walker-1", truth()))
    assert boxes is None and fps is None and notes == []


def test_two_files_of_one_tracker_and_sequence_are_refused(tmp_path):
    shutil.copy(FIXTURES / "walker.2_RectTracker.mat", tmp_path / "walker.2_RectTracker.mat")
    shutil.copy(FIXTURES / "walker.2_RectTracker.mat", tmp_path / "Walker-2_RectTracker.mat")
    with pytest.raises(DataError, match=r"Walker-2_RectTracker\.mat and .*walker\.2_RectTracker\.mat both hold"):
        otb_result_boxes(tmp_path, "RectTracker", Standin("Walker-2", truth()))


# ------------------------------------------------------------------ nrmlc evaluate
def test_evaluate_reads_a_folder_of_mat_files_one_tracker_per_suffix(walker, tmp_path, capsys):
    folder = tmp_path / "otb"
    folder.mkdir()
    for name in ("RectTracker", "AffTracker", "LateTracker", "BareTracker"):
        shutil.copy(FIXTURES / f"walker.2_{name}.mat", folder)
    comparison = compare([folder], walker)
    assert [t.name for t in comparison.trackers] == ["AffTracker", "BareTracker", "LateTracker", "RectTracker"]
    by_name = {t.name: t for t in comparison.trackers}
    assert by_name["BareTracker"].summary()["success_auc"] == pytest.approx(20 / 21)  # IoU 1 fails only "> 1"
    assert by_name["LateTracker"].summary()["missing_frames"] == 4
    assert by_name["RectTracker"].fps == 50.0 and by_name["BareTracker"].fps is None
    shifted = truth()
    shifted[1:, 0] += 3
    assert by_name["RectTracker"].summary()["success_auc"] == pytest.approx(
        evaluate(shifted, truth()).success_auc)

    code, out, err = run_main(["evaluate", "--results", f"{folder}:LateTracker,RectTracker", "--data", walker],
                              capsys)
    assert code == 0, err
    assert out.splitlines()[0].startswith("scored: 1 sequence, all frames")
    assert "LateTracker" in out and "RectTracker" in out and "AffTracker" not in out
    assert "starts at frame 4" in err
    code, out, _ = run_main(["evaluate", "--results", folder, "--otb-trackers", "afftracker", "--data", walker],
                            capsys)
    assert code == 0 and "AffTracker" in out and "RectTracker" not in out
    code, _, err = run_main(["evaluate", "--results", f"{folder}:Nope", "--data", walker], capsys)
    assert code == 2 and "no OTB results of Nope" in err


def test_single_mat_file_against_a_groundtruth_file(walker, capsys):
    import json

    with pytest.warns(UserWarning) as caught:
        code, out, err = run_main(["evaluate", "--results", FIXTURES / "walker.2_LateTracker.mat", "--groundtruth",
                                   walker / "Walker" / "groundtruth_rect.2.txt", "--json"], capsys)
    assert code == 0, err
    assert any("starts at frame 4" in str(w.message) for w in caught)
    assert any("8 result boxes for 10 ground-truth boxes" in str(w.message) for w in caught)
    summary = json.loads(out)
    assert summary["n_frames"] == 9 and summary["n_missing"] == 4 and summary["n_predicted"] == 5


# ------------------------------------------------------------------ the benchmark's own files
needs_real = pytest.mark.skipif(not (REAL_RESULTS.is_dir() and REAL_ANNOTATIONS.is_dir()),
                                reason=f"OTB result files not found at {REAL_RESULTS} or annotations at "
                                       f"{REAL_ANNOTATIONS}")


@needs_real
def test_real_files_first_boxes_are_the_groundtruths():
    """Every tracker's first box on every OTB-100 sequence against the annotation (1,600 files).

    Four files of CFWLB start from a box around (0, 0) (BlurCar1, BlurCar4, David, Tiger1: the
    sequences that do not start on image 1); every other file passes.
    """
    trackers = otb_trackers(REAL_RESULTS)
    assert len(trackers) == 16 and "KCF_GaussHog" in trackers and "ASLA" in trackers
    passed, refused = 0, []
    for path in sorted(REAL_ANNOTATIONS.glob("*.txt")):
        sequence = Standin(path.stem, read_box_file(path))
        for tracker in trackers:
            _, boxes, _, notes = find_otb_result(REAL_RESULTS, tracker, sequence)
            if boxes is None:
                refused.append((sequence.name.lower(), tracker))
            else:
                passed += 1
                start = int(np.flatnonzero(np.isfinite(boxes).all(axis=1))[0])
                assert overlaps(boxes[start], sequence.groundtruth[start]) >= 0.5
    assert passed >= 1596
    assert all(tracker == "CFWLB" for _, tracker in refused), refused


@needs_real
def test_real_ivt_and_asla_conversion_reproduce_the_first_box_exactly():
    biker = read_box_file(REAL_ANNOTATIONS / "Biker.txt")
    for tracker in ("ASLA", "IVT"):
        result = read_otb_result(REAL_RESULTS / f"Biker_{tracker}.mat")
        assert result.type == "ivtAff"
        np.testing.assert_array_equal(result.boxes[0], biker[0])
    tiger = read_otb_result(REAL_RESULTS / "tiger1_MEEM.mat")
    assert (tiger.start_frame, tiger.anno_begin, tiger.offset) == (6, 1, 5)


def test_has_otb_results_needs_a_folder_with_mat_results(tmp_path):
    """A folder counts as OTB results only when it is a folder and holds ``<Seq>_<Tracker>.mat``
    files: an empty folder, one of text results, or a path that is no folder does not."""
    import scipy.io

    from nrmlc.workbench.otb_results import has_otb_results

    assert not has_otb_results(tmp_path)
    (tmp_path / "Car4.txt").write_text("1,2,3,4\n")
    assert not has_otb_results(tmp_path)
    assert not has_otb_results(tmp_path / "missing")
    scipy.io.savemat(tmp_path / "Car4_IVT.mat", {"results": np.zeros((1, 1))})
    assert has_otb_results(tmp_path)
    assert not has_otb_results(tmp_path / "Car4_IVT.mat")
