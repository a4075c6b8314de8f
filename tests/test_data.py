"""Tests for nrmlc.data: OTB folders, sparse-tracker packs, Sequence."""
from __future__ import annotations

import os
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.io

from nrmlc.data import Sequence, list_sequences, open_sequence, read_box_file, read_sparsepack_groundtruth
from nrmlc.data.sparsepack import read_datainfo
from nrmlc.errors import DataError, ParameterError

FRAME_SHAPE = (6, 8)  # (H, W) of the tiny test frames


def make_sequence_folder(
    folder: Path,
    n_frames: int = 3,
    groundtruth: str | None = "",
    names: list[str] | None = None,
    images: list[np.ndarray] | None = None,
) -> Path:
    """An OTB folder of gray frames (pixels of the k-th name all equal 10 * k).

    ``groundtruth`` is the text of groundtruth_rect.txt: "" (default) writes
    one box per frame, None writes no file.
    """
    (folder / "img").mkdir(parents=True)
    names = names or [f"{i:04d}.png" for i in range(1, n_frames + 1)]
    for index, name in enumerate(names):
        image = images[index] if images is not None else np.full(FRAME_SHAPE, 10 * (index + 1), np.uint8)
        assert cv2.imwrite(str(folder / "img" / name), image)
    if groundtruth == "":  # default: one box per frame
        groundtruth = gt_lines(len(names))
    if groundtruth is not None:
        (folder / "groundtruth_rect.txt").write_bytes(groundtruth.encode())
    return folder


def gt_lines(n: int) -> str:
    return "".join(f"{i + 1},2,3,4\n" for i in range(n))


# ------------------------------------------------------------ box files
@pytest.mark.parametrize(
    "text",
    [
        "1,2,3,4\n5,6,7,8\n",
        "1\t2\t3\t4\n5\t6\t7\t8\n",
        "1 2  3 4\n5 6 7   8\n",
        "1,2,3,4\r\n5,6,7,8\r\n",
        "1,2,3,4\n5,6,7,8",
        "1, 2,\t3 ,4\r\n5,6,7,8\n\n",
    ],
    ids=["comma", "tab", "spaces", "crlf", "no-final-newline", "mixed"],
)
def test_groundtruth_delimiters(tmp_path, text):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2, groundtruth=text)
    sequence = open_sequence(folder)
    np.testing.assert_array_equal(sequence.groundtruth, [[1, 2, 3, 4], [5, 6, 7, 8]])
    assert sequence.groundtruth.dtype == np.float64


def test_unannotated_rows_are_nan(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=4, groundtruth="1,2,3,4\n0,0,0,0\nNaN,NaN,NaN,NaN\n5,6,7,8\n")
    sequence = open_sequence(folder)
    assert sequence.annotated.tolist() == [True, False, False, True]
    assert np.isnan(sequence.groundtruth[1:3]).all()


# --------------------------------------------------------- OTB folders
def test_frames_sorted_by_number_not_name(tmp_path):
    names = [f"{k}.png" for k in (10, 2, 1, 3, 4, 5, 6, 7, 8, 9)]
    folder = make_sequence_folder(tmp_path / "Seq", names=names)
    sequence = open_sequence(folder)
    assert [p.name for p in sequence.image_paths] == [f"{k}.png" for k in range(1, 11)]
    # make_sequence_folder filled the k-th name with 10 * k: 10.png with 10, 2.png with 20, 1.png with 30.
    assert [float(f[0, 0]) * 255 for f in sequence][:3] == pytest.approx([30, 20, 40])
    assert float(sequence.frame(9)[0, 0]) * 255 == pytest.approx(10)


def test_sequence_interface(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=3, groundtruth=gt_lines(3))
    sequence = open_sequence(folder)
    assert sequence.name == "Seq" and sequence.path == folder
    assert len(sequence) == 3
    assert sequence.frame_size == FRAME_SHAPE
    np.testing.assert_array_equal(sequence.init_box, [1, 2, 3, 4])
    frame = sequence.frame(1)
    assert frame.dtype == np.float32 and frame.shape == FRAME_SHAPE
    assert frame[0, 0] == pytest.approx(20 / 255)
    assert sequence.frame(-1)[0, 0] == pytest.approx(30 / 255)
    with pytest.raises(IndexError):
        sequence.frame(3)


def test_multi_target_folders(tmp_path):
    folder = make_sequence_folder(tmp_path / "Jog", n_frames=2, groundtruth=None)
    (folder / "groundtruth_rect.1.txt").write_text(gt_lines(2))
    (folder / "groundtruth_rect.2.txt").write_text("5,5,2,2\n6,6,2,2\n")
    make_sequence_folder(tmp_path / "Alone", n_frames=2, groundtruth=gt_lines(2))
    (tmp_path / "notes").mkdir()  # not a sequence: skipped silently

    names = [s.name for s in list_sequences(tmp_path)]
    assert names == ["Alone", "Jog-1", "Jog-2"]
    assert open_sequence(folder).name == "Jog-1"
    second = open_sequence(folder, target=2)
    assert second.name == "Jog-2"
    np.testing.assert_array_equal(second.init_box, [5, 5, 2, 2])
    by_name = open_sequence(tmp_path / "Jog-2")
    assert by_name.name == "Jog-2" and by_name.path == folder
    with pytest.raises(DataError, match="groundtruth_rect.3.txt"):
        open_sequence(folder, target=3)


def test_iteration_is_lazy(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=3, groundtruth=gt_lines(3))
    sequence = open_sequence(folder)
    (folder / "img" / "0003.png").write_bytes(b"not a png")
    frames = iter(sequence)
    next(frames), next(frames)  # frames 1 and 2 read fine: nothing was read ahead
    with pytest.raises(DataError, match="0003.png"):
        next(frames)


# -------------------------------------------------------- pixel formats
def test_image_formats(tmp_path):
    rng = np.random.default_rng(0)
    bgr = rng.integers(0, 256, (*FRAME_SHAPE, 3), dtype=np.uint8)
    bgra = np.dstack([bgr, np.full(FRAME_SHAPE, 128, np.uint8)])
    gray16 = rng.integers(0, 65536, FRAME_SHAPE, dtype=np.uint16)
    bgr16 = rng.integers(0, 65536, (*FRAME_SHAPE, 3), dtype=np.uint16)
    gray8 = rng.integers(0, 256, FRAME_SHAPE, dtype=np.uint8)
    images = [gray8, bgr, bgra, gray16, bgr16]
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=5, groundtruth=gt_lines(5), images=images)
    sequence = open_sequence(folder)

    expected_gray = [
        gray8 / 255.0,
        cv2.cvtColor(bgr.astype(np.float32) / 255, cv2.COLOR_BGR2GRAY),
        cv2.cvtColor(bgr.astype(np.float32) / 255, cv2.COLOR_BGR2GRAY),  # alpha ignored
        gray16 / 65535.0,
        cv2.cvtColor(bgr16.astype(np.float32) / 65535, cv2.COLOR_BGR2GRAY),
    ]
    for index, expected in enumerate(expected_gray):
        frame = sequence.frame(index)
        assert frame.dtype == np.float32 and frame.shape == FRAME_SHAPE
        assert 0.0 <= frame.min() and frame.max() <= 1.0
        np.testing.assert_allclose(frame, expected, atol=1e-6)

    for index in range(5):
        color = sequence.color_frame(index)
        assert color.dtype == np.uint8 and color.shape == (*FRAME_SHAPE, 3)
    np.testing.assert_array_equal(sequence.color_frame(0)[:, :, 1], gray8)
    np.testing.assert_array_equal(sequence.color_frame(1), bgr)
    np.testing.assert_array_equal(sequence.color_frame(2), bgr)
    np.testing.assert_allclose(sequence.color_frame(3)[:, :, 0], gray16 / 257.0, atol=0.5 + 1e-9)


def test_jpeg_and_bmp_frames(tmp_path):
    images = [np.full(FRAME_SHAPE, 100, np.uint8)] * 3
    folder = make_sequence_folder(tmp_path / "Seq", names=["1.jpg", "2.BMP", "3.jpeg"], images=images)
    sequence = open_sequence(folder)
    assert len(sequence) == 3
    assert all(abs(float(f.mean()) - 100 / 255) < 3 / 255 for f in sequence)


# --------------------------------------------------------- ground truth
def test_fewer_groundtruth_lines_warns_and_pads(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=4, groundtruth=gt_lines(2))
    with pytest.warns(UserWarning, match=r"groundtruth_rect\.txt.*2 ground-truth boxes for 4 frames"):
        sequence = open_sequence(folder)
    assert sequence.groundtruth.shape == (4, 4)
    assert sequence.annotated.tolist() == [True, True, False, False]


def test_more_groundtruth_lines_warns_and_truncates(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2, groundtruth=gt_lines(5))
    with pytest.warns(UserWarning, match=r"groundtruth_rect\.txt.*extra boxes ignored"):
        sequence = open_sequence(folder)
    np.testing.assert_array_equal(sequence.groundtruth[:, 0], [1, 2])


def test_matching_groundtruth_does_not_warn(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=3, groundtruth=gt_lines(3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        open_sequence(folder)


def test_missing_groundtruth_needs_an_init_box(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", groundtruth=None)
    sequence = open_sequence(folder)
    assert np.isnan(sequence.groundtruth).all() and not sequence.annotated.any()
    with pytest.raises(DataError, match="no ground truth"):
        sequence.init_box
    given = sequence.with_init_box([2, 2, 3, 3])
    np.testing.assert_array_equal(given.init_box, [2, 2, 3, 3])
    with pytest.raises(DataError):
        sequence.init_box  # the original is unchanged
    np.testing.assert_array_equal(open_sequence(folder, init_box=(1, 1, 2, 2)).init_box, [1, 1, 2, 2])
    with pytest.raises(ParameterError):
        sequence.with_init_box([1, 1, 0, 2])


@pytest.mark.parametrize("first_line", ["0,0,0,0", "NaN,NaN,NaN,NaN", "NaN,3,4,5"])
def test_unusable_first_box_names_the_file(tmp_path, first_line):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2, groundtruth=f"{first_line}\n1,1,2,2\n")
    sequence = open_sequence(folder)
    with pytest.raises(DataError, match="groundtruth_rect.txt: frame 1"):
        sequence.init_box
    np.testing.assert_array_equal(sequence.with_init_box([1, 1, 2, 2]).init_box, [1, 1, 2, 2])


# --------------------------------------------------------------- errors
def test_missing_folder(tmp_path):
    with pytest.raises(DataError, match="Nowhere: sequence folder not found"):
        open_sequence(tmp_path / "Nowhere")


def test_not_a_folder(tmp_path):
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(DataError, match="file.txt: not a folder"):
        open_sequence(tmp_path / "file.txt")


def test_no_img_folder(tmp_path):
    (tmp_path / "Seq").mkdir()
    with pytest.raises(DataError, match="Seq: no 'img' folder"):
        open_sequence(tmp_path / "Seq")


def test_img_folder_without_images(tmp_path):
    (tmp_path / "Seq" / "img").mkdir(parents=True)
    (tmp_path / "Seq" / "img" / "readme.txt").write_text("x")
    with pytest.raises(DataError, match="img: no images"):
        open_sequence(tmp_path / "Seq")


def test_corrupt_first_image_fails_at_open(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq")
    (folder / "img" / "0001.png").write_bytes(b"\x89PNG garbage")
    with pytest.raises(DataError, match="0001.png: cannot read image"):
        open_sequence(folder)


def test_corrupt_later_image_fails_when_read(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq")
    (folder / "img" / "0002.png").write_bytes(b"")
    sequence = open_sequence(folder)
    with pytest.raises(DataError, match="0002.png: cannot read image"):
        sequence.frame(1)
    sequence.frame(2)


def test_mixed_frame_sizes(tmp_path):
    images = [np.zeros(FRAME_SHAPE, np.uint8), np.zeros((7, 8), np.uint8)]
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2, images=images, groundtruth=gt_lines(2))
    sequence = open_sequence(folder)
    with pytest.raises(DataError, match=r"0002.png: image is 7x8 \(HxW\) but frame 1 is 6x8"):
        sequence.frame(1)


def test_list_sequences_errors(tmp_path):
    with pytest.raises(DataError, match="missing: data root not found"):
        list_sequences(tmp_path / "missing")
    (tmp_path / "empty" / "notes").mkdir(parents=True)
    with pytest.raises(DataError, match="empty: no sequences"):
        list_sequences(tmp_path / "empty")


def test_malformed_groundtruth_names_the_file(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", groundtruth="1,2,3\n")
    with pytest.raises(DataError, match=r"groundtruth_rect.txt:1: expected 4 numbers"):
        open_sequence(folder)


# ------------------------------------------------------- sparse packs
def write_sparsepack(folder: Path, n_frames: int, keyframes: dict[int, np.ndarray], size=(8, 6)) -> None:
    """datainfo.txt + x_gt.mat with the given 1-based keyframe corner arrays."""
    (folder / "datainfo.txt").write_text(f"{size[0]}\r\n{size[1]}\r\n{n_frames}")
    cells = np.empty((1, len(keyframes)), dtype=object)
    for k, corners in enumerate(keyframes.values()):
        cells[0, k] = corners
    frame_index = np.array([list(keyframes)], dtype=np.uint16)
    scipy.io.savemat(str(folder / "pack_gt.mat"), {"frameIndex": frame_index, "gtCornersAll": cells})


def test_sparsepack_fallback(tmp_path):
    folder = make_sequence_folder(tmp_path / "Pack", n_frames=4, groundtruth=None)
    rotated = np.array([[2.0, 1.5, 4.0, 4.5, 2.0], [1.0, 3.0, 3.5, 1.5, 1.0]])  # not axis-aligned
    upright = np.array([[1.0, 1.0, 3.0, 3.0, 1.0], [2.0, 5.0, 5.0, 2.0, 2.0]])  # TL, BL, BR, TR, TL
    write_sparsepack(folder, 4, {1: rotated, 3: upright})
    assert read_datainfo(folder) == (8, 6, 4)

    boxes = read_sparsepack_groundtruth(folder)
    np.testing.assert_allclose(boxes[0], [1.5, 1.0, 3.0, 2.5])
    np.testing.assert_allclose(boxes[2], [1.0, 2.0, 2.0, 3.0])
    assert np.isnan(boxes[[1, 3]]).all()

    sequence = open_sequence(folder)
    assert sequence.groundtruth_path.name == "pack_gt.mat"
    np.testing.assert_array_equal(sequence.groundtruth, boxes, strict=False)

    # A groundtruth_rect.txt, when present, wins over the mat file.
    (folder / "groundtruth_rect.txt").write_text(gt_lines(4))
    assert open_sequence(folder).groundtruth[0, 0] == 1


def test_sparsepack_errors(tmp_path):
    folder = make_sequence_folder(tmp_path / "Pack", n_frames=2, groundtruth=None)
    write_sparsepack(folder, 2, {5: np.zeros((2, 5))})
    with pytest.raises(DataError, match=r"pack_gt.mat: keyframe 5 outside 1..2"):
        read_sparsepack_groundtruth(folder)
    write_sparsepack(folder, 2, {1: np.array([[1.0, 1, 3, 3, 1], [1.0, 4, 4, 1, 1]])}, size=(80, 60))
    with pytest.raises(DataError, match=r"datainfo.txt: says 80x60"):
        open_sequence(folder)
    (folder / "datainfo.txt").write_text("8 six 2")
    with pytest.raises(DataError, match="datainfo.txt: expected 3 positive integers"):
        read_sparsepack_groundtruth(folder)


# ------------------------------------------------------------ real data
@pytest.mark.realdata
@pytest.mark.parametrize("name", ["Caviar1", "Occlusion1", "Occlusion2"])
def test_sparsepack_matches_groundtruth_rect(real_data_root, name):
    folder = real_data_root / name
    from_mat = read_sparsepack_groundtruth(folder)
    from_text = read_box_file(folder / "groundtruth_rect.txt")
    assert from_mat.shape == from_text.shape
    np.testing.assert_array_equal(np.isnan(from_mat), np.isnan(from_text))
    # The text file holds the mat boxes printed with 6 significant digits
    # (Occlusion1 line 2: y = 71.47368421 -> 71.4737); a few last digits differ
    # by one unit (114.01152 -> 114.011), so the values agree to 1e-3, no better.
    np.testing.assert_allclose(from_mat, from_text, rtol=0, atol=1e-3)


@pytest.mark.realdata
def test_real_data_root(real_data_root):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Football1 has fewer boxes than frames
        sequences = {s.name: s for s in list_sequences(real_data_root)}
    for name in ["Car4", "Caviar1", "Couple", "Football1", "Jogging-1", "Jogging-2", "Occlusion1", "Occlusion2"]:
        assert name in sequences
    assert "Jogging" not in sequences
    assert list(sequences) == sorted(sequences)

    car4 = sequences["Car4"]  # CRLF, commas
    assert car4.groundtruth.shape == (len(car4), 4) and car4.annotated.all()
    couple = sequences["Couple"]  # tabs
    assert couple.annotated.all() and np.isfinite(couple.init_box).all()
    occlusion1 = sequences["Occlusion1"]  # 0,0,0,0 rows between keyframes
    np.testing.assert_array_equal(occlusion1.groundtruth[1], [120.5, 71.4737, 116, 146])
    assert not occlusion1.annotated[2]
    frame = car4.frame(0)
    assert frame.shape == car4.frame_size and frame.dtype == np.float32


@pytest.mark.realdata
def test_real_football1_pads_missing_boxes(real_data_root):
    with pytest.warns(UserWarning, match=r"Football1.groundtruth_rect.txt: 74 ground-truth boxes for 81 frames"):
        football = open_sequence(real_data_root / "Football1")
    assert len(football) == 81
    assert football.annotated.sum() == 74 and not football.annotated[74:].any()


@pytest.mark.realdata
def test_real_jogging_by_name(real_data_root):
    jogging = open_sequence(real_data_root / "Jogging-2")
    assert jogging.name == "Jogging-2" and jogging.groundtruth_path.name == "groundtruth_rect.2.txt"
    assert isinstance(jogging, Sequence)


# ------------------------------------------------ frame order and frame sets
def test_frame_number_anywhere_in_the_name(tmp_path):
    names = [f"{k}_cam0.png" for k in range(1, 21)]
    folder = make_sequence_folder(tmp_path / "Seq", names=names[::-1])
    assert [p.name for p in open_sequence(folder).image_paths] == names


@pytest.mark.parametrize("names", [
    [f"img{k:03d}.jpg" for k in range(7, 12)],  # any start number, a prefix
    [f"frame_{k}_t{k * 40}.png" for k in range(1, 5)],  # two numbers that agree on the order
    [f"{k:04d}.png" for k in (1, 2)] + ["0003.jpg", "0004.bmp"],  # mixed formats
], ids=["prefix-start-7", "two-agreeing-numbers", "mixed-formats"])
def test_accepted_frame_sets(tmp_path, names):
    folder = make_sequence_folder(tmp_path / "Seq", names=names)
    assert [p.name for p in open_sequence(folder).image_paths] == names


def test_hidden_files_are_ignored(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=3)
    (folder / "img" / "._0002.png").write_bytes(b"resource fork")
    assert len(open_sequence(folder)) == 3


def _symlink(target: str):
    def make(folder: Path) -> None:
        (folder / "img" / "0004.png").symlink_to(target)
    return make


def _names(*names):
    def make(folder: Path) -> None:
        for name in names:
            assert cv2.imwrite(str(folder / "img" / name), np.zeros(FRAME_SHAPE, np.uint8))
    return make


def _fifo(folder: Path) -> None:
    os.mkfifo(folder / "img" / "0004.png")


BAD_FRAME_SETS = {
    "duplicate-number": (_names("0003.jpg"), r"img: 0003\.(jpg|png) and 0003\.(jpg|png) have the same frame number 3"),
    "duplicate-padding": (_names("3.png"), r"have the same frame number 3"),
    "gap": (_names("0005.png"), r"img: frame numbers jump from 0003\.png to 0005\.png \(frame 4 missing\)"),
    "long-gap": (_names("0009.png"), r"jump from 0003\.png to 0009\.png \(frames 4-8 missing\)"),
    "two-patterns": (_names("frame0004.png"), r"img: frame names follow different patterns"),
    "no-number": (_names("cover.png"), r"img: frame names follow different patterns"),
    "disagreeing-numbers": (None, r"several numbers change .* disagree on the order"),
    "dangling-link": (_symlink("missing.png"), r"0004\.png: broken symbolic link"),
    "looping-link": (_symlink("0004.png"), r"0004\.png: symbolic link loop"),
    "folder-named-as-image": (lambda f: (f / "img" / "0004.png").mkdir(), r"0004\.png: not a regular file"),
    "fifo-named-as-image": (_fifo, r"0004\.png: not a regular file"),
}


@pytest.mark.parametrize("name", list(BAD_FRAME_SETS))
def test_ambiguous_frame_sets_are_refused(tmp_path, name):
    breaker, message = BAD_FRAME_SETS[name]
    if breaker is None:
        folder = make_sequence_folder(tmp_path / "Seq", names=["a1_b2.png", "a2_b1.png", "a3_b3.png"])
    else:
        folder = make_sequence_folder(tmp_path / "Seq", n_frames=3)
        breaker(folder)
    with pytest.raises(DataError, match=message):
        open_sequence(folder)


def test_one_by_one_frame_names_the_file(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2, images=[np.zeros((1, 1), np.uint8)] * 2)
    with pytest.raises(DataError, match=r"0001\.png: image is 1x1 \(HxW\); frames must be at least 2x2"):
        open_sequence(folder)


@pytest.mark.parametrize("box", ["1,2,3,4", {"x": 1, "y": 2, "w": 3, "h": 4}, b"1234", [1, 2, "three", 4]],
                         ids=["str", "dict", "bytes", "text-inside"])
def test_initial_box_of_the_wrong_type(tmp_path, box):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2)
    with pytest.raises(ParameterError, match="initial box must be 4 finite numbers"):
        open_sequence(folder, init_box=box)
    with pytest.raises(ParameterError, match="initial box must be 4 finite numbers"):
        open_sequence(folder).with_init_box(box)


# ------------------------------------------------ ground-truth text
@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16", "utf-16-le", "utf-16-be"])
def test_groundtruth_encodings(tmp_path, encoding):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2, groundtruth=None)
    (folder / "groundtruth_rect.txt").write_bytes("1,2,3,4\r\n5,6,7,8\r\n".encode(encoding))
    np.testing.assert_array_equal(open_sequence(folder).groundtruth, [[1, 2, 3, 4], [5, 6, 7, 8]])


@pytest.mark.parametrize("line, message", [
    ("1_3_2,2,3,4", r":2: not a number in '1_3_2,2,3,4'"),
    ("\uff11,2,3,4", r":2: not a number"),  # a full-width digit
    ("infinity,2,3,4", r":2: not a number"),
    ("0x10,2,3,4", r":2: not a number"),
    ("1e10,2,3,4", r":2: value beyond 1e\+09 px"),
    ("1,2,3,1e200", r":2: value beyond"),
], ids=["underscores", "full-width", "infinity-word", "hex", "huge", "1e200"])
def test_groundtruth_numbers_annotation_tools_do_not_write(tmp_path, line, message):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2, groundtruth=f"1,2,3,4\n{line}\n")
    with pytest.raises(DataError, match=r"groundtruth_rect\.txt" + message):
        open_sequence(folder)


def test_groundtruth_not_text(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2, groundtruth=None)
    (folder / "groundtruth_rect.txt").write_bytes(b"1,2,3,4\n\xff\xd8\xff\xe0 jpeg?\n")
    with pytest.raises(DataError, match=r"groundtruth_rect\.txt: not a text file"):
        open_sequence(folder)


def test_box_file_that_is_not_a_regular_file(tmp_path):
    (tmp_path / "gt.txt").mkdir()
    with pytest.raises(DataError, match=r"gt\.txt: box file is not a regular file"):
        read_box_file(tmp_path / "gt.txt")
    os.mkfifo(tmp_path / "fifo.txt")  # would block a plain open() forever
    with pytest.raises(DataError, match=r"fifo\.txt: box file is not a regular file"):
        read_box_file(tmp_path / "fifo.txt")


def test_predictions_keep_failed_rows(tmp_path):
    path = tmp_path / "r.txt"
    path.write_text("1,2,3,4\ninf,2,3,4\n1e200,1e200,1e200,1e200\n5,6,-1,0\n0,0,0,0\n")
    boxes = read_box_file(path, predictions=True)
    assert np.isinf(boxes[1, 0]) and boxes[2, 0] == 1e200 and boxes[3, 2] == -1 and np.isnan(boxes[4]).all()
    with pytest.raises(DataError, match=r"r\.txt:2: infinite value"):
        read_box_file(path)


# ------------------------------------------------ sparse packs, checked
def test_sparsepack_checks(tmp_path):
    folder = make_sequence_folder(tmp_path / "Pack", n_frames=3, groundtruth=None)
    box = np.array([[1.0, 1, 3, 3, 1], [1.0, 4, 4, 1, 1]])

    def pack(frame_index, corners, info="8 6 3"):
        cells = np.empty((1, len(corners)), dtype=object)
        for k, c in enumerate(corners):
            cells[0, k] = c
        scipy.io.savemat(str(folder / "pack_gt.mat"), {"frameIndex": np.array([frame_index]), "gtCornersAll": cells})
        (folder / "datainfo.txt").write_text(info)

    pack([1.0, 2.5], [box, box])
    with pytest.raises(DataError, match=r"pack_gt\.mat: frameIndex 2\.5 is not an integer"):
        open_sequence(folder)
    pack([1, 2], [box, np.full((2, 5), np.nan)])
    with pytest.raises(DataError, match=r"pack_gt\.mat: keyframe 2: NaN or infinite corner coordinates"):
        open_sequence(folder)
    pack([1, 2], [box, np.array(["1,2,3", "4,5,6"])])
    with pytest.raises(DataError, match=r"pack_gt\.mat: keyframe 2: corners must be numbers"):
        open_sequence(folder)
    pack([1, 1], [box, box])
    with pytest.raises(DataError, match=r"keyframe 1 appears twice"):
        open_sequence(folder)
    pack([1], [box], info="8 6 1000000000000")
    with pytest.raises(DataError, match=r"datainfo\.txt: implausible size 8x6 or frame count 1000000000000"):
        open_sequence(folder)
    pack([1], [box], info="8 6 5")
    with pytest.raises(DataError, match=r"datainfo\.txt: says 5 frames but the img folder holds 3"):
        open_sequence(folder)
    pack([1], [box], info="8.5 6 3")
    with pytest.raises(DataError, match=r"datainfo\.txt: expected 3 positive integers"):
        open_sequence(folder)
    pack([1], [box], info="8.0 6 3")  # MATLAB may write integers this way
    np.testing.assert_array_equal(open_sequence(folder).groundtruth[0], [1, 1, 2, 3])


def test_synthetic_suite_arguments():
    from nrmlc.data import synthetic_suite

    for kwargs, name in [(dict(n_sequences=0), "n_sequences"), (dict(n_sequences=-3), "n_sequences"),
                         (dict(seed=-1), "seed"), (dict(n_frames=1), "n_frames"), (dict(n_frames=10**12), "n_frames"),
                         (dict(n_sequences=2.0), "n_sequences")]:
        with pytest.raises(ParameterError, match=f"synthetic_suite: {name} must be an integer"):
            synthetic_suite(**kwargs)


def test_sequence_opened_as_dot_takes_the_folder_name(tmp_path, monkeypatch):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2)
    monkeypatch.chdir(folder)
    assert open_sequence(".").name == "Seq"
    monkeypatch.chdir(folder / "img")
    assert open_sequence("..").name == "Seq"


def test_two_files_for_one_target(tmp_path):
    folder = make_sequence_folder(tmp_path / "Jog", n_frames=2, groundtruth=None)
    (folder / "groundtruth_rect.1.txt").write_text(gt_lines(2))
    (folder / "groundtruth_rect.01.txt").write_text(gt_lines(2))
    with pytest.raises(DataError, match=r"Jog: groundtruth_rect\.01\.txt and groundtruth_rect\.1\.txt are both target 1"):
        open_sequence(folder)


@pytest.mark.parametrize("kwargs, message", [
    (dict(path=None), "path must be a str or os.PathLike, got NoneType"),
    (dict(path=3), "path must be a str or os.PathLike, got int"),
    (dict(target="1"), r"target must be an integer >= 1, got '1'"),
    (dict(target=0), "target must be an integer >= 1, got 0"),
], ids=["none", "int-path", "str-target", "zero-target"])
def test_open_sequence_arguments(tmp_path, kwargs, message):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=2)
    with pytest.raises(ParameterError, match=message):
        open_sequence(**{"path": folder, **kwargs})


def test_frame_index_must_be_an_integer(tmp_path):
    sequence = open_sequence(make_sequence_folder(tmp_path / "Seq", n_frames=3))
    assert sequence.frame(np.int64(1))[0, 0] == pytest.approx(20 / 255)
    for index in (1.5, "1", 1.0):
        with pytest.raises(TypeError):
            sequence.frame(index)


@pytest.mark.parametrize("field, value, message", [
    ("n_frames", 2.5, "n_frames must be an integer"), ("n_frames", "5", "n_frames must be an integer"),
    ("seed", True, "seed must be an integer"), ("frame_height", 40.5, "frame_height must be an integer"),
    ("noise_std", float("inf"), "noise_std must be a finite number"),
    ("motion_period", float("inf"), "motion_period must be a finite number"),
    ("target_width", float("nan"), "target_width must be a finite number"),
    ("n_frames", 10**12, r"n_frames must be in 2\.\.1000000"), ("frame_width", 10**6, "frame size must be"),
])
def test_synthetic_spec_types_and_bounds(field, value, message):
    from nrmlc.data import SyntheticSpec

    with pytest.raises(ParameterError, match=message):
        SyntheticSpec(**{field: value})


@pytest.mark.parametrize("name", ["GROUNDTRUTH_RECT.TXT", "Groundtruth_rect.txt", "groundtruth_rect.TXT"])
def test_ground_truth_named_in_any_case_is_read(name, tmp_path):
    # As a case-blind file system (Windows, macOS) lets a dataset be written; result files are read so too.
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=3, groundtruth=None)
    (folder / name).write_text(gt_lines(3))
    np.testing.assert_array_equal(open_sequence(folder).groundtruth, [[i + 1, 2, 3, 4] for i in range(3)])
    assert [s.name for s in list_sequences(tmp_path)] == ["Seq"]


def test_ground_truth_in_two_cases_is_refused(tmp_path):
    folder = make_sequence_folder(tmp_path / "Seq", n_frames=3)
    (folder / "GROUNDTRUTH_RECT.TXT").write_text(gt_lines(3))
    with pytest.raises(DataError, match=r"GROUNDTRUTH_RECT\.TXT and groundtruth_rect\.txt are both the ground truth"):
        open_sequence(folder)


def test_target_ground_truth_named_in_any_case_is_read(tmp_path):
    folder = make_sequence_folder(tmp_path / "Jog", n_frames=2, groundtruth=None)
    (folder / "GroundTruth_Rect.2.TXT").write_text("5,5,2,2\n6,6,2,2\n")
    assert [s.name for s in list_sequences(tmp_path)] == ["Jog-2"]
    np.testing.assert_array_equal(open_sequence(folder, target=2).init_box, [5, 5, 2, 2])
