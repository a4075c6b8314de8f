"""Outputs of ``track``: nothing the user has is overwritten by accident, and
nothing is lost.

- ``--out``, ``--video`` and ``--diagnostics`` are checked before tracking
  starts: a folder, a device or FIFO, a looping link, an input of the run (the
  ground truth, a frame, through a link or a hard link), a file inside the
  frames' folder, a ground-truth name in the sequence folder, two outputs on
  one file, an unwritable destination are each one ``error:`` line naming the
  path the user gave, and the tracker is never called;
- every output is written to a unique temporary file and renamed only when
  the run succeeds: an exception, SIGINT or SIGTERM leaves an earlier file
  byte for byte, and two runs writing the same paths at once each leave a
  complete file;
- a symbolic link is written through (the link stays, its target is replaced);
- boxes round-trip exactly through the result file.
"""
from __future__ import annotations

import os
import shutil
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from nrmlc import io
from nrmlc.cli import main
from nrmlc.data import open_sequence, read_box_file, synthetic_suite, write_otb_sequence
from nrmlc.errors import ParameterError
# The command-line tests' OTB folder (8 small synthetic frames), fast settings and helpers.
from test_cli import FAST, N_FRAMES, base_folder, run_main, seq, subprocess_env  # noqa: F401 (fixtures)


def temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob(".tmp-*"))


def video_frames(path: Path) -> int:
    capture = cv2.VideoCapture(str(path))
    count = 0
    while capture.read()[0]:
        count += 1
    capture.release()
    return count


# ------------------------------------------------- refused before tracking
def _fifo(path: Path) -> None:
    os.mkfifo(path)


def _loop(path: Path) -> None:
    path.symlink_to(path.name)


def _parent_is_file(path: Path) -> None:
    path.parent.write_text("a file")


REFUSED = {
    # option, path (relative to tmp_path; {seq} is the sequence), set-up, message
    "out-is-groundtruth": ("--out", "{seq}/groundtruth_rect.txt", None, r"is an input of this run"),
    "out-is-a-frame": ("--out", "{seq}/img/0003.png", None, r"(is an input of this run|holds this run's input frames)"),
    "out-link-to-groundtruth": ("--out", "link.txt", lambda p, s: p.symlink_to(s / "groundtruth_rect.txt"),
                                r"is an input of this run"),
    "out-hardlink-to-groundtruth": ("--out", "hard.txt", lambda p, s: os.link(s / "groundtruth_rect.txt", p),
                                    r"is an input of this run"),
    "out-inside-img": ("--out", "{seq}/img/result.txt", None, r"holds this run's input frames"),
    "out-new-target-groundtruth": ("--out", "{seq}/groundtruth_rect.2.txt", None, r"would become part of the sequence"),
    "out-is-a-folder": ("--out", "folder", lambda p, s: p.mkdir(), r"is a folder"),
    "out-is-a-device": ("--out", "/dev/null", None, r"not a regular file"),
    "out-is-a-fifo": ("--out", "fifo.txt", lambda p, s: _fifo(p), r"not a regular file"),
    "out-link-loop": ("--out", "loop.txt", lambda p, s: _loop(p), r"symbolic link loop"),
    "out-parent-is-a-file": ("--out", "file/r.txt", lambda p, s: _parent_is_file(p), r"is a file, not a folder"),
    "out-unwritable-folder": ("--out", "/proc/nrmlc-test/r.txt", None, r"cannot write to folder"),
    "out-empty": ("--out", "", None, r"--out: empty path"),
    "out-trailing-slash": ("--out", "results/", None, r"names a folder; give a file name"),
    "video-is-groundtruth": ("--video", "{seq}/groundtruth_rect.txt", None, r"unknown video extension"),
    "video-link-to-frame": ("--video", "v.mp4", lambda p, s: p.symlink_to(s / "img" / "0001.png"),
                            r"is an input of this run"),
    "video-is-a-folder": ("--video", "v.mp4", lambda p, s: p.mkdir(), r"is a folder"),
    "video-unwritable": ("--video", "/proc/nrmlc-test/v.mp4", None, r"cannot write to folder"),
    "diagnostics-is-groundtruth": ("--diagnostics", "{seq}/groundtruth_rect.txt", None, r"is an input of this run"),
    "diagnostics-same-as-out": ("--diagnostics", "result.txt", None, r"the same file as --out"),
    "diagnostics-is-a-device": ("--diagnostics", "/dev/null", None, r"not a regular file"),
}


@pytest.mark.parametrize("name", list(REFUSED))
def test_bad_outputs_are_refused_before_tracking(name, seq, tmp_path, capsys, monkeypatch):
    import nrmlc.tracker.loop

    option, raw, setup, expected = REFUSED[name]
    given = raw.replace("{seq}", str(seq))
    path = Path(given) if os.path.isabs(given) or given.startswith(str(seq)) else tmp_path / given
    if setup is not None:
        setup(path, seq)
    given = (str(path) + ("/" if raw.endswith("/") else "")) if raw else ""  # Path drops a trailing slash
    before = {p: p.read_bytes() for p in seq.rglob("*") if p.is_file()}

    def not_called(*args, **kwargs):
        raise AssertionError("the tracker ran before the outputs were checked")

    monkeypatch.setattr(nrmlc.tracker.loop, "track_sequence", not_called)
    out = tmp_path / "result.txt"
    out.write_text("earlier result\n")
    argv = ["track", seq, "--out", out, *FAST]
    if option == "--out":
        argv[3] = given
    else:
        argv += [option, given]
    code, _, err = run_main(argv, capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert re.search(expected, lines[0]), lines[0]
    assert f"{option} {given}" in lines[0] or (not given and option in lines[0])  # the user's own path
    assert out.read_text() == "earlier result\n"
    assert {p: p.read_bytes() for p in seq.rglob("*") if p.is_file()} == before  # inputs untouched
    assert not temporaries(tmp_path)


@pytest.mark.parametrize("target_exists", [True, False], ids=["link", "dangling-link"])
def test_symlinked_output_is_written_through(target_exists, seq, tmp_path, capsys):
    target = tmp_path / "results" / "r.txt"
    target.parent.mkdir()
    if target_exists:
        target.write_text("earlier\n")
    link = tmp_path / "link.txt"
    link.symlink_to(target)
    code, _, err = run_main(["track", seq, "--out", link, "--frames", "3", *FAST], capsys)
    assert code == 0, err
    assert link.is_symlink() and os.readlink(link) == str(target)  # the link stays a link
    assert len(read_box_file(target, predictions=True)) == 3
    assert not temporaries(tmp_path)


def test_check_output_library(tmp_path):
    inputs = [tmp_path / "gt.txt"]
    inputs[0].write_text("1,2,3,4\n")
    assert io.check_output(tmp_path / "new" / "deeper" / "r.txt", "out") == tmp_path / "new" / "deeper" / "r.txt"
    assert not (tmp_path / "new").exists()  # checking creates nothing
    with pytest.raises(ParameterError, match=r"^out .*gt\.txt: is an input of this run"):
        io.check_output(inputs[0], "out", inputs=inputs)
    with pytest.raises(ParameterError, match="is a folder"):
        io.check_output(tmp_path, "out")
    with pytest.raises(ParameterError, match="holds this run's input frames"):
        io.check_output(tmp_path / "r.txt", "out", input_folders=[tmp_path])
    assert not temporaries(tmp_path)


# ------------------------------------------------------ atomic video
def test_video_and_outputs_are_complete_and_leave_no_temporary(seq, tmp_path, capsys):
    out, video, diagnostics = tmp_path / "r.txt", tmp_path / "v.mp4", tmp_path / "d.npz"
    code, _, err = run_main(["track", seq, "--out", out, "--video", video, "--diagnostics", diagnostics, *FAST], capsys)
    assert code == 0, err
    assert video_frames(video) == N_FRAMES
    assert len(read_box_file(out)) == N_FRAMES
    with np.load(diagnostics) as arrays:
        assert arrays["boxes"].shape == (N_FRAMES, 4)
    assert not temporaries(tmp_path)


@pytest.mark.parametrize("failure", ["corrupt-frame", "exception-in-writer"])
def test_failed_run_keeps_the_earlier_video(failure, seq, tmp_path, capsys, monkeypatch):
    out, video = tmp_path / "r.txt", tmp_path / "v.mp4"
    code, _, err = run_main(["track", seq, "--out", out, "--video", video, *FAST], capsys)
    assert code == 0, err
    before_video, before_out = video.read_bytes(), out.read_bytes()
    if failure == "corrupt-frame":
        (seq / "img" / "0005.png").write_bytes(b"garbage")
    else:
        import nrmlc.video

        calls = []
        original = nrmlc.video.BoxVideoWriter.on_frame

        def failing(self, index, tracker, frame):
            calls.append(index)
            if index == 3:
                raise OSError("disk full")
            original(self, index, tracker, frame)

        monkeypatch.setattr(nrmlc.video.BoxVideoWriter, "on_frame", failing)
    code, _, err = run_main(["track", seq, "--out", out, "--video", video, "--seed", "1", *FAST], capsys)
    assert code == 2 and err.startswith("error: "), err
    assert video.read_bytes() == before_video and out.read_bytes() == before_out
    assert not temporaries(tmp_path)


def test_unknown_video_extension_is_our_line_only(seq, tmp_path):
    result = subprocess.run([sys.executable, "-m", "nrmlc", "track", str(seq), "--out", str(tmp_path / "r.txt"),
                             "--video", str(tmp_path / "v.xyz"), *FAST], env=subprocess_env(), capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        f"error: --video {tmp_path / 'v.xyz'}: unknown video extension '.xyz'; use one of .mp4, .m4v, .mov, .avi, .mkv"]
    assert not (tmp_path / "r.txt").exists() and not temporaries(tmp_path)


def _default_sigint() -> None:
    # A shell without job control starts background commands with SIGINT ignored, and `nohup`
    # ignores SIGHUP; the run leaves an ignored signal ignored (as it should), so a test suite run
    # as `make test &` or under nohup would see the run finish. The child gets the default
    # dispositions, as in a terminal.
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, signal.SIG_DFL)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=["SIGINT", "SIGTERM", "SIGHUP"])
def test_signal_during_a_video_run_keeps_earlier_files(signum, tmp_path):
    # Long enough that the signal arrives well before the end: the fast settings track these
    # frames at 400-650 fps, and the partial video appears about 0.5 s into the run.
    sequence = synthetic_suite(n_frames=1200, size=(96, 128), n_sequences=1)[0]
    folder = write_otb_sequence(sequence, tmp_path / "Long")
    out, video = tmp_path / "r.txt", tmp_path / "v.mp4"
    out.write_text("earlier result\n")
    video.write_bytes(b"an earlier video")
    process = subprocess.Popen([sys.executable, "-m", "nrmlc", "track", str(folder), "--out", str(out),
                                "--video", str(video), *FAST], env=subprocess_env(), stderr=subprocess.PIPE,
                               text=True, preexec_fn=_default_sigint)
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline and process.poll() is None:
        partial = [p for p in tmp_path.glob(".tmp-v-*.mp4") if p.stat().st_size > 0]
        if partial:
            break
        time.sleep(0.05)
    assert process.poll() is None, "the run ended before it could be interrupted"
    time.sleep(0.3)  # well inside the run: frames are being tracked and drawn
    assert process.poll() is None, "the run ended before the signal: make the sequence longer"
    process.send_signal(signum)
    _, err = process.communicate(timeout=60)
    # 130, or death by SIGINT: CPython may end a run whose Ctrl-C was handled by re-sending
    # itself SIGINT (so that a shell sees an interrupted program); $? is 130 either way.
    assert process.returncode in (130, -signal.SIGINT), err
    assert err.strip().splitlines()[-1] == "interrupted"
    assert "Traceback" not in err
    assert out.read_text() == "earlier result\n"
    assert video.read_bytes() == b"an earlier video"
    assert not temporaries(tmp_path)


def test_two_concurrent_runs_on_the_same_outputs(seq, tmp_path):
    out, video = tmp_path / "same.txt", tmp_path / "same.mp4"
    alone = {}
    for seed in (0, 1):  # what each run writes on its own
        assert main(["track", str(seq), "--out", str(tmp_path / f"alone{seed}.txt"), "--seed", str(seed), *FAST]) == 0
        alone[seed] = (tmp_path / f"alone{seed}.txt").read_text()
    assert alone[0] != alone[1]
    processes = [subprocess.Popen([sys.executable, "-m", "nrmlc", "track", str(seq), "--out", str(out), "--video",
                                   str(video), "--seed", str(seed), *FAST], env=subprocess_env(),
                                  stderr=subprocess.PIPE, text=True) for seed in (0, 1)]
    for process in processes:
        _, err = process.communicate(timeout=120)
        assert process.returncode == 0, err
    assert out.read_text() in (alone[0], alone[1])  # one whole result, never a mix
    assert video_frames(video) == N_FRAMES
    assert not temporaries(tmp_path)


# ------------------------------------------------------ exact round trip
def test_result_files_round_trip_every_box(tmp_path):
    boxes = np.array([
        [1.0, 2.0, 3.0, 4.0],
        [53.33231058455931, 24.609775652692225, 19.200000000000003, 16.0],
        [10.0, 10.0, 1e-7, 3e-5],  # a tiny box: written as 0 with 4 decimals before
        [-12.5, -0.0001, 1e-300, 5e-324],
        [1e8, 123456789.123, 0.1, 0.2],
        [np.nan] * 4,
    ])
    io.write_boxes(tmp_path / "r.txt", boxes)
    np.testing.assert_array_equal(read_box_file(tmp_path / "r.txt", predictions=True), boxes)
    assert (tmp_path / "r.txt").read_text().splitlines()[0] == "1,2,3,4"


def test_track_output_round_trips_and_evaluates(seq, tmp_path, capsys):
    out = tmp_path / "r.txt"
    diagnostics = tmp_path / "d.npz"
    assert run_main(["track", seq, "--out", out, "--diagnostics", diagnostics, *FAST], capsys)[0] == 0
    with np.load(diagnostics) as arrays:
        np.testing.assert_array_equal(read_box_file(out), arrays["boxes"])
    code, stdout, err = run_main(["evaluate", "--results", out, "--groundtruth", seq / "groundtruth_rect.txt"], capsys)
    assert code == 0, err


# ------------------------------------------------------ cache identity
def test_sequence_identity_is_its_content(seq, tmp_path):
    """A folder is keyed by its frames' bytes and its ground truth: not by its path or name."""
    sequence = open_sequence(seq)
    assert re.fullmatch(rf"frames:{N_FRAMES}:sha256=[0-9a-f]{{32}}", sequence.identity)
    assert open_sequence(shutil.copytree(seq, tmp_path / "elsewhere" / "Other")).identity == sequence.identity
    synthetic = synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0]
    assert synthetic.identity == f"synthetic:{synthetic.spec!r}"
    moved = sequence.with_init_box((3, 4.5, 20, 21))
    assert moved.identity == sequence.identity + ":init_box=3.0,4.5,20.0,21.0"
    assert open_sequence(seq, init_box=(3, 4.5, 20, 21)).identity == moved.identity
    assert synthetic.with_init_box((1, 2, 10, 10)).identity == synthetic.identity + ":init_box=1.0,2.0,10.0,10.0"
    from nrmlc.workbench.jobs import sequence_identity

    assert sequence_identity(moved) == moved.identity


def test_long_output_name_is_written(seq, tmp_path, capsys):
    out = tmp_path / ("r" * 250 + ".txt")  # a legal name; the temporary name must not exceed the limit
    code, _, err = run_main(["track", seq, "--out", out, "--frames", "2", *FAST], capsys)
    assert code == 0, err
    assert len(read_box_file(out)) == 2 and not temporaries(tmp_path)


def test_video_writer_that_wrote_nothing_keeps_the_earlier_video(seq, tmp_path):
    from nrmlc.errors import OutputError
    from nrmlc.video import BoxVideoWriter

    video = tmp_path / "v.mp4"
    video.write_bytes(b"an earlier video")
    writer = BoxVideoWriter(video, open_sequence(seq))
    writer.writer.release()
    writer.tmp_path.write_bytes(b"")  # released before any frame: an empty file, as after a failed write

    class Silent:  # what OpenCV does on a full disk: accepts frames, writes nothing, reports nothing
        def write(self, image):
            pass

        def release(self):
            pass

    writer.writer = Silent()
    writer.frames_written = 3
    with pytest.raises(OutputError, match=r"--video .*v\.mp4: the video writer wrote nothing"):
        writer.close()
    assert video.read_bytes() == b"an earlier video" and not temporaries(tmp_path)


@pytest.mark.parametrize("boxes", [np.ones(4), np.ones((3, 5)), np.ones((0, 4))], ids=["1-d", "5-columns", "empty"])
def test_write_boxes_refuses_other_shapes(boxes, tmp_path):
    with pytest.raises(ParameterError, match=r"r\.txt: boxes must have shape \(n, 4\)"):
        io.write_boxes(tmp_path / "r.txt", boxes)
    assert not (tmp_path / "r.txt").exists()


def test_failure_writing_one_output_keeps_every_earlier_output(seq, tmp_path, capsys, monkeypatch):
    out, video, diagnostics = tmp_path / "r.txt", tmp_path / "v.mp4", tmp_path / "d.npz"
    for path in (out, video, diagnostics):
        path.write_bytes(b"earlier " + path.name.encode())

    def disk_full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(np, "savez_compressed", disk_full)  # --diagnostics is written after --out
    code, _, err = run_main(["track", seq, "--out", out, "--video", video, "--diagnostics", diagnostics, *FAST],
                            capsys)
    assert code == 2 and "No space left on device" in err, err
    for path in (out, video, diagnostics):
        assert path.read_bytes() == b"earlier " + path.name.encode()
    assert not temporaries(tmp_path)


def test_json_is_strict_whatever_the_values(tmp_path):
    import json

    def refuse(constant):
        raise ValueError(f"non-standard JSON constant {constant}")

    path = io.write_json(tmp_path / "r.json", {"nan": float("nan"), "inf": np.float32("inf"), 3: np.arange(2),
                                               "row": (np.float64(0.5), -np.inf), "path": tmp_path})
    # json.loads would accept NaN; parse_constant makes it fail as JavaScript or jq would.
    assert json.loads(path.read_text(), parse_constant=refuse) == {
        "nan": None, "inf": None, "3": [0, 1], "row": [0.5, None], "path": str(tmp_path)}


def test_what_an_interrupt_cut_short_prints_nothing_after_it(seq, tmp_path, monkeypatch, capsys):
    """The interrupt can land inside numba's compiler: in llvmlite's ``ObjectRef.__init__``, whose
    half-built object fails in its ``__del__`` (AttributeError, at the process's exit), and inside a
    cache save, which then warns. Once the interrupt has come, neither is printed: the run ends
    with the one line "interrupted" (a CI run ended with the AttributeError's line)."""
    import warnings

    from llvmlite.binding.ffi import ObjectRef

    import nrmlc.errors
    import nrmlc.tracker.loop
    from nrmlc.cli import console_main

    reported = []
    monkeypatch.setattr(sys, "unraisablehook", reported.append)
    half_built = []

    def interrupted(*args, **kwargs):
        nrmlc.errors.interrupt_requested.set()
        ref = ObjectRef.__new__(ObjectRef)
        ref._ptr = object()  # as an interrupt between __init__'s first two lines leaves it
        half_built.append(ref)
        warnings.warn("cannot write numba's cache in /somewhere (RuntimeError: no compiled object yet)")
        raise KeyboardInterrupt

    monkeypatch.setattr(nrmlc.tracker.loop, "track_sequence", interrupted)
    monkeypatch.setattr(sys, "argv", ["nrmlc", "track", str(seq), "--out", str(tmp_path / "r.txt"), *FAST])
    with warnings.catch_warnings():  # shown as Python shows it, not recorded as pytest does
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, category, filename, lineno, file=None, line=None: sys.stderr.write(
            warnings.formatwarning(message, category, filename, lineno, line))
        assert console_main() == 130
    half_built.clear()  # collected after main() returned, as at the process's exit
    assert capsys.readouterr().err == "interrupted\n"
    assert reported == []
    # Without an interrupt, a finaliser's error is reported as Python would.
    nrmlc.errors.interrupt_requested.clear()
    ref = ObjectRef.__new__(ObjectRef)
    ref._ptr = object()
    del ref
    assert [unraisable.exc_type for unraisable in reported] == [AttributeError]


def test_an_interrupt_a_finaliser_swallowed_still_ends_the_run(seq, tmp_path, monkeypatch, capsys):
    """A KeyboardInterrupt raised inside a ``__del__`` is printed and dropped by Python, and the
    run would go on to replace the outputs; the signal's flag stops it before the commit."""
    import nrmlc.errors
    import nrmlc.tracker.loop

    real = nrmlc.tracker.loop.track_sequence

    def swallowed(*args, **kwargs):
        result = real(*args, **kwargs)
        nrmlc.errors.interrupt_requested.set()  # as _terminate does, its exception lost
        return result

    monkeypatch.setattr(nrmlc.tracker.loop, "track_sequence", swallowed)
    out = tmp_path / "r.txt"
    out.write_text("earlier result\n")
    assert main(["track", str(seq), "--out", str(out), *FAST]) == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == "interrupted"
    assert out.read_text() == "earlier result\n" and not temporaries(tmp_path)
    monkeypatch.undo()
    assert main(["track", str(seq), "--out", str(out), *FAST]) == 0  # the next run starts clear
    assert out.read_text() != "earlier result\n"


@pytest.mark.parametrize("suffix", ["svg", "pdf", "png"])
def test_identical_figures_give_identical_files(suffix, tmp_path):
    """No date and no random SVG ids in a plot: two identical figures are the same bytes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written, open_before = [], set(plt.get_fignums())  # earlier tests may leave figures open
    for attempt in range(2):
        figure, axis = plt.subplots(figsize=(3, 2))
        axis.plot([0, 1, 2], [0, 1, 0.5], label="tracker")
        axis.legend()
        written.append(io.write_figure(figure, tmp_path / f"plot{attempt}.{suffix}").read_bytes())
        time.sleep(1.1)  # a date in the file would now differ by a second
    assert written[0] == written[1]
    assert set(plt.get_fignums()) == open_before  # each figure written is closed
