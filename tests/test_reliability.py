"""Reliability: degenerate data never crashes or yields NaN, bad input to the
library gets a clear error, and files are written atomically.

(The command-line side of bad input is in test_cli.py, resumable runs in
test_runner.py, bit-identical results in test_determinism.py.)
"""
from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from nrmlc import io
from nrmlc.data import open_sequence, synthetic_suite, write_otb_sequence
from nrmlc.errors import ParameterError
from nrmlc.workbench.metrics import evaluate, overlaps
from nrmlc.data.image import as_gray_frame
from nrmlc.geometry import clip_initial_box
from nrmlc.tracker.algorithm import FrameResult, NRMLCTracker
from nrmlc.tracker.params import TrackerParams
from nrmlc.tracker.loop import track_sequence

REPO_ROOT = Path(__file__).resolve().parent.parent

#: Few particles and templates: each frame costs a few milliseconds.
SMALL = dict(n_particles=30, n_positive=10, n_negative=20, max_positive=20)


def assert_result_finite(result: FrameResult) -> None:
    """Every number the tracker reports for a frame is finite."""
    for name, value in vars(result).items():
        values = np.asarray(value, dtype=np.float64)
        assert np.isfinite(values).all(), f"{name} = {value}"


def track_frames(frames, box, **overrides) -> tuple[NRMLCTracker, np.ndarray]:
    tracker = NRMLCTracker(seed=0, **{**SMALL, **overrides})
    tracker.init(frames[0], box)
    boxes = [tracker.initial_box]
    for frame in frames[1:]:
        boxes.append(tracker.update(frame))
        assert_result_finite(tracker.last)
    boxes = np.array(boxes)
    assert np.isfinite(boxes).all() and (boxes[:, 2:] > 0).all()
    return tracker, boxes


@pytest.fixture(scope="module")
def textured_frames() -> list[np.ndarray]:
    """Six 96x128 uint8 gray frames of a synthetic sequence, and its first box."""
    sequence = synthetic_suite(n_frames=6, size=(96, 128), n_sequences=1)[0]
    return [sequence.raw_frame(i) for i in range(6)], sequence.init_box


# ------------------------------------------------------- degenerate frames
@pytest.mark.parametrize("coding, lam", [("regularized", 1.0), ("regularized", 0.0), ("constrained", 1.0),
                                         ("plain", 0.0)])
@pytest.mark.parametrize("value", [0, 128], ids=["black", "constant"])
def test_constant_frames_stay_finite(coding, lam, value):
    frames = [np.full((48, 64), value, np.uint8)] * 6
    tracker, _ = track_frames(frames, (20, 14, 24, 20), coding=coding, lam=lam, beta=lam / 10)
    # Every patch of a constant frame is the same vector: all templates are duplicates.
    assert np.ptp(tracker.templates, axis=0).max() < 1e-6


def test_duplicate_templates_singular_gram_plain_coding():
    """lambda = 0 ('plain') on identical templates: the Gram matrix is rank 1."""
    frames = [np.full((48, 64), 77, np.uint8)] * 3
    from experiments.instrumented import RecordingTracker

    tracker = RecordingTracker(seed=0, coding="plain", lam=0.0, beta=0.0, **SMALL)
    tracker.init(frames[0], (20, 14, 24, 20))
    assert np.linalg.matrix_rank(tracker.template_gram, tol=1e-6) == 1
    for frame in frames[1:]:
        tracker.update(frame)
        assert_result_finite(tracker.last)
        codes = tracker.last_coding.codes
        assert np.isfinite(codes).all()
        np.testing.assert_allclose(codes.sum(axis=1), 1.0, atol=1e-6)  # still sums to one


def test_scene_goes_black_and_comes_back(textured_frames):
    """Frames 2-3 black: until then the boxes are the clean run's, bit for bit; on the black frames
    the tracker has nothing to follow (overlap 0.12 on frame 3); once the scene is back it finds the
    target again (overlap 0.92 with the truth on the last frame; a tracker left where the black frames
    took it scores about 0.1)."""
    frames, box = textured_frames
    truth = synthetic_suite(n_frames=6, size=(96, 128), n_sequences=1)[0].groundtruth
    black = np.zeros_like(frames[0])
    _, clean = track_frames(frames, box)
    _, boxes = track_frames([frames[0], frames[1], black, black, frames[4], frames[5]], box)
    np.testing.assert_array_equal(boxes[:2], clean[:2])
    assert overlaps(boxes[5:], truth[5:])[0] > 0.7, boxes


def make_exit_reenter_folder(folder: Path) -> np.ndarray:
    """An OTB folder: a 16x16 textured square leaves a 60x80 frame on the right and comes back.

    Returns the 0-based left x of the square per frame. Ground truth is the visible part of
    the square, and 0,0,0,0 while it is wholly outside.
    """
    rng = np.random.default_rng(3)
    background = cv2.GaussianBlur(rng.random((60, 80)).astype(np.float32), (0, 0), 3)
    background = 60 + 80 * (background - background.min()) / np.ptp(background)
    yy, xx = np.mgrid[0:16, 0:16]
    square = np.where((yy // 4 + xx // 4) % 2 == 0, 230.0, 20.0) + 3 * xx
    lefts = np.concatenate([np.arange(30, 100, 10), [100, 100], np.arange(100, 29, -10)])
    (folder / "img").mkdir(parents=True)
    lines = []
    for index, left in enumerate(lefts):
        image = background.copy()
        visible = slice(left, min(left + 16, 80))
        if left < 80:
            image[22:38, visible] = square[:, : visible.stop - left]
            lines.append(f"{left + 1},23,{visible.stop - left},16")
        else:
            lines.append("0,0,0,0")
        assert cv2.imwrite(str(folder / "img" / f"{index + 1:04d}.png"), np.round(image).astype(np.uint8))
    (folder / "groundtruth_rect.txt").write_text("\n".join(lines) + "\n")
    return lefts


def test_target_leaves_the_frame_and_returns(tmp_path):
    from nrmlc.cli import main

    lefts = make_exit_reenter_folder(tmp_path / "Exit")
    assert (lefts >= 80).any() and lefts[0] == lefts[-1]
    sequence = open_sequence(tmp_path / "Exit")
    assert not sequence.annotated[lefts >= 80].any()
    out, diagnostics = tmp_path / "r.txt", tmp_path / "d.npz"
    code = main(["track", str(tmp_path / "Exit"), "--out", str(out), "--diagnostics", str(diagnostics),
                 *[f"--param={k}={v}" for k, v in SMALL.items()]])
    assert code == 0
    boxes = np.loadtxt(out, delimiter=",")
    assert boxes.shape == (len(lefts), 4) and np.isfinite(boxes).all() and (boxes[:, 2:] > 0).all()
    with np.load(diagnostics) as arrays:
        for name in arrays.files:
            values = arrays[name][1:] if arrays[name].ndim else arrays[name]  # row 0 is filler
            assert np.isfinite(values.astype(np.float64)).all(), name
    scores = evaluate(boxes, sequence.groundtruth)  # only the annotated frames are scored
    assert scores.n_frames == int(sequence.annotated[1:].sum())
    assert math.isfinite(scores.mean_overlap)


# ------------------------------------------------------------ pixel formats
def _variants(gray: np.ndarray) -> dict[str, np.ndarray]:
    return {
        "gray-hw1": gray[:, :, None],
        "gray-alpha": np.dstack([gray, np.full_like(gray, 200)]),
        "bgr": cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR),
        "bgra": cv2.cvtColor(gray, cv2.COLOR_GRAY2BGRA),
        "gray16": gray.astype(np.uint16) * 257,
        "bgr16": cv2.cvtColor(gray.astype(np.uint16) * 257, cv2.COLOR_GRAY2BGR),
        "bgra16": cv2.cvtColor(gray.astype(np.uint16) * 257, cv2.COLOR_GRAY2BGRA),
    }


def test_pixel_formats_through_the_tracker(textured_frames):
    """The same scene as gray, BGR, BGRA, 8 or 16 bit gives the same boxes: to the bit for 8-bit
    gray with a channel axis or an alpha; from colour or 16 bits to float32's rounding (OpenCV's
    luma weights sum to 1, and 257 / 65535 is 1 / 255, only to that precision), which the experts'
    blend (``expert_blend_iou``) carries into the boxes through its eps_pos* weights (the chosen
    expert's box alone did not)."""
    frames, box = textured_frames
    _, reference = track_frames(frames, box)
    for name in _variants(frames[0]):
        _, boxes = track_frames([_variants(f)[name] for f in frames], box)
        if name in ("gray-hw1", "gray-alpha"):
            np.testing.assert_array_equal(boxes, reference, err_msg=name)
        else:
            np.testing.assert_allclose(boxes, reference, rtol=1e-6, atol=0, err_msg=name)
    _, boxes = track_frames([f.astype(np.float64) for f in frames], box)  # float, any scale
    np.testing.assert_allclose(boxes[0], reference[0])


def test_pixel_formats_through_sequence_folders(textured_frames, tmp_path):
    frames, box = textured_frames
    params = TrackerParams(**SMALL)
    results = {}
    for name in ("gray", "bgr", "bgra", "gray16", "bgr16", "bgra16"):
        folder = tmp_path / name
        (folder / "img").mkdir(parents=True)
        for index, frame in enumerate(frames):
            image = frame if name == "gray" else _variants(frame)[name]
            assert cv2.imwrite(str(folder / "img" / f"{index + 1:04d}.png"), image)
        x, y, w, h = box
        (folder / "groundtruth_rect.txt").write_text(f"{x},{y},{w},{h}\n" * len(frames))
        sequence = open_sequence(folder)
        assert sequence.raw_frame(0).dtype == (np.uint16 if "16" in name else np.uint8)
        result = track_sequence(sequence, params, seed=0)
        assert np.isfinite(result.boxes).all()
        results[name] = result.boxes
    # 16 bits as 8: to float32's rounding of the scale (test_pixel_formats_through_the_tracker)
    np.testing.assert_allclose(results["gray16"], results["gray"], rtol=1e-6, atol=0)
    np.testing.assert_allclose(results["bgr16"], results["bgr"], rtol=1e-6, atol=0)


# ------------------------------------------------------ bad input (library)
@pytest.mark.parametrize("image, message", [
    ([[1, 2], [3, 4]], "must be a numpy array"),
    (np.zeros(10, np.uint8), "gray or BGR"),
    (np.zeros((1, 8), np.uint8), "at least 2x2"),
    (np.zeros((8, 8, 5), np.uint8), "gray or BGR"),
    (np.zeros((8, 8), bool), "unsupported dtype bool"),
    (np.zeros((8, 8), np.complex64), "unsupported dtype complex64"),
    (np.full((8, 8), np.nan), "NaN or infinite"),
    (np.full((8, 8, 3), np.inf, np.float32), "NaN or infinite"),
    (np.full((8, 8), 1e300), r"frame values reach 1e\+300, beyond float32's range"),
    (np.full((8, 8, 3), -1e39), r"frame values reach 1e\+39, beyond float32's range"),
], ids=["list", "1d", "1xN", "5-channels", "bool", "complex", "nan", "inf-bgr", "1e300", "beyond-float32-bgr"])
def test_bad_frames(image, message):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # refused by our line, not after numpy's overflow warning
        with pytest.raises(ParameterError, match=message):
            as_gray_frame(image)


@pytest.mark.parametrize("box, message", [
    ((200, 10, 20, 20), "wholly outside the 100x50 frame"),
    ((-40, 10, 20, 20), "wholly outside"),
    ((10, 51, 20, 20), "wholly outside"),
    ((10, -30, 20, 20), "wholly outside"),
    ((10, 10, 3.9, 20), "smaller than 4 px"),
    ((98, 10, 20, 20), "smaller than 4 px"),  # only 3 px left after clipping
    ((10, 10, 0, 20), "non-positive size"),
    ((10, 10, 20, -5), "non-positive size"),
    ((10, 10, 20), "4 finite numbers"),
    ((10, np.nan, 20, 20), "4 finite numbers"),
], ids=["right", "left", "below", "above", "narrow", "clipped-narrow", "zero-w", "negative-h", "3-numbers", "nan"])
def test_bad_initial_boxes(box, message):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the clipped-narrow case warns before it refuses
        with pytest.raises(ParameterError, match=message):
            clip_initial_box(box, (50, 100))


def test_initial_box_partly_outside_is_clipped_with_a_warning():
    with pytest.warns(UserWarning, match=r"partly outside the 100x50 frame; clipped to \[1\.0, 41\.0, 15\.0, 10\.0\]"):
        clipped = clip_initial_box((-5, 41, 21, 30), (50, 100))
    np.testing.assert_array_equal(clipped, [1, 41, 15, 10])


def test_initial_box_inside_is_kept_exactly_without_warning():
    # x + w - x != w in floating point: an inside box must not be "clipped" by rounding.
    box = np.array([53.33231058455931, 24.609775652692225, 19.200000000000003, 16.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        clipped = clip_initial_box(box, (96, 128))
    np.testing.assert_array_equal(clipped, box)
    clipped[0] = 0
    assert box[0] != 0  # a copy, not the caller's array


@pytest.mark.parametrize("overrides, message", [
    (dict(n_positive=3, n_negative=2, max_positive=3), r"dictionary_sizes: k = 8 is larger than the template count 5"),
    (dict(dictionary_sizes=(5, 17)), r"dictionary_sizes: each k must be in 1\.\.16"),
    (dict(dictionary_sizes=()), r"dictionary_sizes: needs at least one"),
    (dict(lam=-0.5), r"parameter lam: must be in \[0, 1e\+06\]"),
    (dict(beta=-1e-9), r"parameter beta: must be in \[0, 1e\+06\]"),
    (dict(n_particles=0), r"parameter n_particles: must be (>= 1|in 1\.\.)"),
    (dict(n_particles=2.5), r"parameter n_particles: must be an integer"),
    (dict(n_particles=True), r"parameter n_particles: must be an integer"),
    (dict(coding="lasso"), r"parameter coding: unknown mode 'lasso'"),
    (dict(lam=float("nan")), r"parameter lam: must be a finite number"),
    (dict(alpha=0.0), r"parameter alpha: must be in \(0, 1e\+06\]"),
    (dict(motion_sigmas=(4, 4, 0.01, 0, -1, 0)), r"parameter motion_sigmas"),
    (dict(patch_size=2), r"parameter patch_size: must be >= 4"),
    (dict(occlusion_max_negative=-5), r"parameter occlusion_max_negative: must be in 0\.\.10000, got -5"),
    (dict(update_error_threshold=-5), r"parameter update_error_threshold: must be in \[0, 4\], got -5"),
    (dict(update_error_threshold=1e308), r"parameter update_error_threshold: must be in \[0, 4\]"),
    (dict(positive_radius=-1), r"parameter positive_radius: must be in \[0, 1000\], got -1"),
    (dict(positive_radius=20), r"parameter negative_radius: must be larger than positive_radius \(20\), got 16$"),
    (dict(n_iterations=10**9), r"parameter n_iterations: must be in 0\.\.100,"),
    (dict(max_positive=0), r"parameter max_positive: must be in 1\.\.10000"),
    (dict(coefficient_tolerance=2.0), r"parameter coefficient_tolerance: must be in \[0, 1\]"),
], ids=["k-over-templates", "k-over-16", "no-k", "lam", "beta", "particles", "particles-float", "particles-bool",
        "coding", "lam-nan", "alpha", "sigma", "patch", "occlusion-negative", "error-threshold-negative",
        "error-threshold-huge", "positive-radius-negative", "radii-order", "iterations", "max-positive",
        "tolerance"])
def test_bad_parameters(overrides, message):
    with pytest.raises(ParameterError, match=message):
        TrackerParams(**overrides)
    with pytest.raises(ParameterError, match=message):
        NRMLCTracker(**overrides)


def test_every_number_has_a_range_that_means_something():
    """Each numeric parameter is bounded on both sides, so no value the tracker cannot use passes;
    patch_size's upper bound is the memory check's (``TrackerParams.estimated_bytes``)."""
    import dataclasses

    from nrmlc.tracker.parameter_fields import field_kinds

    kinds = field_kinds(TrackerParams)
    open_ended = [f.name for f in dataclasses.fields(TrackerParams) if kinds[f.name] in (int, float)
                  and (f.metadata.get("low") is None or f.metadata.get("high") is None)]
    assert open_ended == ["patch_size"]


def test_bad_tracker_use():
    with pytest.raises(ParameterError, match=r"unknown parameter 'lamda'; did you mean lam\?"):
        NRMLCTracker(lamda=1.0)
    with pytest.raises(ParameterError, match="parameter seed"):
        NRMLCTracker(seed=-1)
    with pytest.raises(ParameterError, match=r"call init\(frame, box\) before update"):
        NRMLCTracker().update(np.zeros((8, 8), np.uint8))
    with pytest.raises(ParameterError, match="frame must be a gray or BGR"):
        NRMLCTracker(**SMALL).init(np.zeros((8, 8, 2, 2), np.uint8), (1, 1, 4, 4))


# ----------------------------------------------------------- atomic writes
WRITERS = {
    "text": lambda path: io.write_text(path, "new text\n" * 1000),
    "bytes": lambda path: io.write_bytes(path, b"\x00\x01" * 5000),
    "json": lambda path: io.write_json(path, {"new": np.arange(1000)}),
    "npz": lambda path: io.write_npz(path, boxes=np.random.default_rng(0).random((500, 4))),
    "boxes": lambda path: io.write_boxes(path, np.ones((500, 4))),
}


@pytest.mark.parametrize("writer", list(WRITERS))
def test_writes_round_trip_and_leave_no_temp_file(writer, tmp_path):
    path = tmp_path / "sub" / "file.out"
    WRITERS[writer](path)
    WRITERS[writer](path)  # over an existing file
    assert os.listdir(path.parent) == ["file.out"]


def test_write_bytes_accepts_arrays(tmp_path):
    ok, encoded = cv2.imencode(".png", np.arange(64, dtype=np.uint8).reshape(8, 8))
    io.write_bytes(tmp_path / "a.png", encoded)
    np.testing.assert_array_equal(cv2.imread(str(tmp_path / "a.png"), cv2.IMREAD_UNCHANGED),
                                  np.arange(64, dtype=np.uint8).reshape(8, 8))


@pytest.mark.parametrize("where", ["fsync", "replace"])
@pytest.mark.parametrize("writer", list(WRITERS))
def test_failure_mid_write_keeps_the_old_file(writer, where, tmp_path, monkeypatch):
    """A failure after part of the data is written (fsync: e.g. disk full) or at the rename
    leaves the old file intact, nothing partial under the final name, and no temp file."""
    path = tmp_path / "file.out"
    path.write_bytes(b"old content")

    def fail(*args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(io.os, where, fail)
    with pytest.raises(OSError, match="No space left"):
        WRITERS[writer](path)
    assert path.read_bytes() == b"old content"
    assert os.listdir(tmp_path) == ["file.out"]


def test_exception_inside_the_writer_keeps_the_old_file(tmp_path, monkeypatch):
    path = tmp_path / "r.npz"
    io.write_npz(path, boxes=np.zeros((3, 4)))

    def half_then_fail(handle, **arrays):
        handle.write(b"PK\x03\x04 partial zip")
        raise KeyboardInterrupt  # Ctrl-C in the middle of the write

    monkeypatch.setattr(io.np, "savez_compressed", half_then_fail)
    with pytest.raises(KeyboardInterrupt):
        io.write_npz(path, boxes=np.ones((3, 4)))
    monkeypatch.undo()
    with np.load(path) as arrays:
        np.testing.assert_array_equal(arrays["boxes"], np.zeros((3, 4)))
    assert os.listdir(tmp_path) == ["r.npz"]


KILLED_WRITER = """
import os, sys, time
from nrmlc import io
def slow_fsync(fd):
    print("writing", flush=True)   # the data is in the temp file, not yet renamed
    time.sleep(60)
io.os.fsync = slow_fsync
io.write_text(sys.argv[1], "new content\\n" * 100000)
"""


def test_sigkill_mid_write_keeps_the_old_file(tmp_path):
    path = tmp_path / "result.txt"
    path.write_text("old content\n")
    process = subprocess.Popen([sys.executable, "-c", KILLED_WRITER, str(path)], stdout=subprocess.PIPE, text=True,
                               env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)))
    try:
        assert process.stdout.readline().strip() == "writing"
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=30)
    assert process.returncode == -signal.SIGKILL
    assert path.read_text() == "old content\n"
    strays = [p.name for p in tmp_path.iterdir() if p != path]
    assert len(strays) == 1 and strays[0].startswith(".tmp-result.txt-")  # ignored by every reader
    assert (tmp_path / strays[0]).stat().st_size > 0


def test_otb_frames_are_written_atomically(tmp_path, monkeypatch):
    import nrmlc.data.synthetic as synthetic

    written = []
    monkeypatch.setattr(synthetic, "write_bytes", lambda path, data: written.append(path) or io.write_bytes(path, data))
    sequence = synthetic_suite(n_frames=3, size=(48, 64), n_sequences=1)[0]
    write_otb_sequence(sequence, tmp_path / "S")
    assert [p.name for p in written] == ["0001.png", "0002.png", "0003.png"]
    assert sorted(os.listdir(tmp_path / "S" / "img")) == ["0001.png", "0002.png", "0003.png"]
