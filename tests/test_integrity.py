"""Reliability, third round: a result belongs to the data it claims to, outputs are written
all or nothing and never onto inputs, two processes share a folder, every input is checked
where it is read, resources are estimated before work, and the Python API takes numpy numbers.

(docs/RELIABILITY.md says what each guarantee is and which test here checks it.)
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.io

from nrmlc import io
from nrmlc.workbench.benchmark import run_benchmark
from nrmlc.workbench.results_layout import MANIFEST_NAME
from nrmlc.data import list_sequences, open_sequence, read_box_file, synthetic_suite, write_otb_sequence
from nrmlc.data import fingerprint
from nrmlc.errors import DataError, OutputError, ParameterError
from nrmlc.workbench.jobs import RunSpec
from nrmlc.workbench.run_cache import RunCache
from nrmlc.tracker.algorithm import NRMLCTracker
from nrmlc.tracker.params import TrackerParams
from nrmlc.tracker.loop import track_sequence

from test_cli import FAST, run_main, subprocess_env

REPO_ROOT = Path(__file__).resolve().parent.parent
SMALL = TrackerParams(n_particles=20, n_positive=10, n_negative=20, max_positive=20, redetect_count=20)


def synth(out: Path, seed: int, frames: int = 6, count: int = 1, capsys=None) -> None:
    from nrmlc.cli import main

    assert main(["synth", "--out", str(out), "--frames", str(frames), "--count", str(count), "--seed", str(seed)]) == 0
    if capsys is not None:
        capsys.readouterr()


def temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob(".tmp-*"))


# =========================================================== results belong to their data
def test_regenerated_sequence_is_not_served_from_the_cache(tmp_path, capsys):
    """The issue's case: synth, benchmark, synth again with another seed, benchmark into a new
    folder with the same cache: the second benchmark must track the new frames."""
    data, cache = tmp_path / "S", tmp_path / "C"
    synth(data, seed=0, capsys=capsys)
    args = ["--param", "n_particles=20", "--param", "n_positive=10", "--param", "n_negative=20",
            "--param", "max_positive=20", "--cache", cache]
    assert run_main(["benchmark", data, "--out", tmp_path / "A", *args], capsys)[0] == 0
    synth(data, seed=1, capsys=capsys)
    truth = read_box_file(data / "synth-01" / "groundtruth_rect.txt")
    code, out, err = run_main(["benchmark", data, "--out", tmp_path / "NEW", *args], capsys)
    assert code == 0, err
    boxes = read_box_file(tmp_path / "NEW" / "synth-01.txt")
    np.testing.assert_array_equal(boxes[0], truth[0])  # the new first box, not the old run's
    summary = json.loads((tmp_path / "NEW" / "summary.json").read_text())
    assert summary["runs"][0]["mean_overlap"] > 0.68  # measured 0.79: a loss of 0.1 fails


def test_the_key_follows_every_frame_and_the_ground_truth(tmp_path):
    folder = write_otb_sequence(synthetic_suite(n_frames=5, size=(48, 64), n_sequences=1)[0], tmp_path / "Seq")
    before = open_sequence(folder).identity
    assert open_sequence(folder).identity == before  # stable
    assert open_sequence(shutil.copytree(folder, tmp_path / "moved" / "Seq")).identity == before  # content only

    # The first ground-truth line edited.
    gt = folder / "groundtruth_rect.txt"
    lines = gt.read_text().splitlines()
    original = gt.read_text()
    lines[0] = "3,4,20,20"
    gt.write_text("\n".join(lines) + "\n")
    assert open_sequence(folder).identity != before
    gt.write_text(original)
    assert open_sequence(folder).identity == before

    # One frame's bytes changed with the same size and modification time (cp -p of other content).
    frame = folder / "img" / "0003.png"
    info = frame.stat()
    data = bytearray(frame.read_bytes())
    data[len(data) // 2] ^= 0xFF
    frame.write_bytes(bytes(data))
    os.utime(frame, ns=(info.st_atime_ns, info.st_mtime_ns))
    assert frame.stat().st_size == info.st_size and frame.stat().st_mtime_ns == info.st_mtime_ns
    assert open_sequence(folder).identity != before


def test_file_digest_is_remembered_only_while_the_file_is_unchanged(tmp_path, monkeypatch):
    path = tmp_path / "f.bin"
    path.write_bytes(b"a" * 100)
    first = fingerprint.file_digest(path)
    # Rewritten at once with the same size and times: the racy window keeps it from being remembered.
    info = path.stat()
    path.write_bytes(b"b" * 100)
    os.utime(path, ns=(info.st_atime_ns, info.st_mtime_ns))
    assert fingerprint.file_digest(path) != first
    # A settled file is remembered: the stat numbers decide, not the bytes.
    monkeypatch.setattr(fingerprint, "RACY_SECONDS", -1e9)
    fingerprint.forget()
    remembered = fingerprint.file_digest(path)
    calls = []
    real_open = open
    monkeypatch.setattr("builtins.open", lambda *a, **k: calls.append(a) or real_open(*a, **k))
    assert fingerprint.file_digest(path) == remembered and not calls


def test_key_cost_on_a_long_folder(tmp_path):
    """A 1,700-frame folder (the longest real sequences): the key costs little next to tracking."""
    folder = tmp_path / "Long" / "img"
    folder.mkdir(parents=True)
    frame = cv2.imencode(".jpg", np.random.default_rng(0).integers(0, 255, (240, 320), dtype=np.uint8))[1].tobytes()
    for index in range(1700):
        (folder / f"{index + 1:04d}.jpg").write_bytes(frame)
    (tmp_path / "Long" / "groundtruth_rect.txt").write_text("10,10,20,20\n" * 1700)
    start = time.perf_counter()
    open_sequence(tmp_path / "Long").identity
    first = time.perf_counter() - start
    start = time.perf_counter()
    open_sequence(tmp_path / "Long").identity
    again = time.perf_counter() - start
    print(f"key of a 1,700-frame folder: {first * 1000:.0f} ms first, {again * 1000:.0f} ms with open_sequence again")
    assert first < 5.0


@pytest.mark.parametrize("damage", ["no boxes", "short boxes", "no states"])
def test_incomplete_cache_entry_is_recomputed_with_a_warning(tmp_path, damage):
    sequence = synthetic_suite(n_frames=5, size=(48, 64), n_sequences=1)[0]
    spec = RunSpec(sequence, SMALL, seed=0)
    cache = RunCache(tmp_path)
    [result] = cache.run([spec], jobs=1, progress=False)
    arrays = dict(np.load(cache.path(spec)))
    if damage == "no boxes":
        del arrays["boxes"]
    elif damage == "short boxes":
        arrays["boxes"] = arrays["boxes"][:3]
    else:
        del arrays["states"]
    io.write_npz(cache.path(spec), **arrays)
    with pytest.warns(UserWarning, match=rf"{cache.path(spec).name}: incomplete cache entry"):
        [again] = cache.run([spec], jobs=1, progress=False)
    np.testing.assert_array_equal(again.boxes, result.boxes)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cache.run([spec], jobs=1, progress=False)  # stored whole again


def test_result_file_of_the_wrong_length_is_run_again(tmp_path):
    data = tmp_path / "S"
    for sequence in synthetic_suite(n_frames=6, size=(48, 64), n_sequences=1):
        write_otb_sequence(sequence, data / sequence.name)
    out, cache = tmp_path / "R", RunCache(tmp_path / "C")
    run_benchmark(data, out, SMALL, cache=cache, progress=False, log=lambda line: None)
    result = out / "synth-01.txt"
    whole = result.read_text()
    result.write_text("".join(whole.splitlines(keepends=True)[:4]))
    with pytest.warns(UserWarning, match=r"synth-01\.txt: not a finished result \(4 boxes for 6 frames\)"):
        run_benchmark(data, out, SMALL, cache=cache, progress=False, log=lambda line: None)
    assert result.read_text() == whole


@pytest.mark.parametrize("manifest, what", [
    ([1, 2], "a JSON list"),
    ({"settings": "x"}, "no 'settings' object"),
    ({"settings": {}, "primary_seed": "0", "runs": {}}, "'primary_seed' must be a seed"),
    ({"settings": {}, "primary_seed": 0, "runs": []}, "'runs' is not an object"),
    ({"settings": {}, "primary_seed": 0, "runs": {"A": {"0": {"frames": "6"}}}}, r"frames must be a positive integer"),
    ({"settings": {}, "primary_seed": 0, "runs": {"A": {"x": {"frames": 6}}}}, "the key is not a seed"),
    ({"settings": {}, "primary_seed": 0, "runs": {"A": {"0": {"frames": 6, "scores": [1]}}}}, "scores must be"),
])
def test_manifest_of_the_wrong_shape_is_one_error_line(tmp_path, capsys, manifest, what):
    data = tmp_path / "S"
    write_otb_sequence(synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0], data / "synth-01")
    out = tmp_path / "R"
    out.mkdir()
    (out / MANIFEST_NAME).write_text(json.dumps(manifest))
    code, _, err = run_main(["benchmark", data, "--out", out, "--cache", tmp_path / "C"], capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{out / MANIFEST_NAME}: not a benchmark manifest" in err and re.search(what, err), err


# ======================================================= outputs: all or nothing, never inputs
class _TruncatingWriter:
    """OpenCV's writer on a nearly full disk: takes every frame, reports nothing, and the file
    ends early (the simulated failure; the real one is test_full_disk_during_video)."""

    def __init__(self, real, path, keep: float = 0.6) -> None:
        self.real, self.path, self.keep = real, path, keep

    def write(self, image) -> None:
        self.real.write(image)

    def release(self) -> None:
        if not self.real.isOpened():
            return  # released already (abort after finish)
        self.real.release()
        size = os.path.getsize(self.path)
        with open(self.path, "r+b") as handle:
            handle.truncate(int(size * self.keep))

    def isOpened(self) -> bool:
        return self.real.isOpened()


def test_damaged_video_never_replaces_the_earlier_one(tmp_path, capsys, monkeypatch):
    import nrmlc.video as video_module

    folder = write_otb_sequence(synthetic_suite(n_frames=40, size=(96, 128), n_sequences=1)[0], tmp_path / "Seq")
    out, video = tmp_path / "r.txt", tmp_path / "OLD.avi"
    assert run_main(["track", folder, "--out", out, "--video", video, *FAST], capsys)[0] == 0
    earlier_out, earlier_video = out.read_bytes(), video.read_bytes()
    real = cv2.VideoWriter
    monkeypatch.setattr(video_module.cv2, "VideoWriter",
                        lambda path, *a: _TruncatingWriter(real(path, *a), path))
    code, _, err = run_main(["track", folder, "--out", out, "--video", video, "--seed", "1", *FAST], capsys)
    assert code == 2, err
    assert err.startswith(f"error: --video {video}: only ") and "of the 40 frames written decode back" in err
    assert out.read_bytes() == earlier_out and video.read_bytes() == earlier_video
    assert not temporaries(tmp_path)


def _small_filesystem_available() -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(["unshare", "-m", "sh", "-c", "mount -t tmpfs -o size=64k none /mnt && umount /mnt"],
                           capture_output=True)
    return probe.returncode == 0


@pytest.mark.skipif(not _small_filesystem_available(), reason="cannot mount a small tmpfs (needs unshare -m)")
def test_full_disk_during_video(tmp_path):
    """A real full disk: the video goes to a 400 kB tmpfs that an earlier video nearly fills."""
    folder = write_otb_sequence(synthetic_suite(n_frames=40, size=(96, 128), n_sequences=1)[0], tmp_path / "Seq")
    out, old = tmp_path / "r.txt", tmp_path / "old.avi"
    run = [sys.executable, "-m", "nrmlc", "track", str(folder), *FAST]
    assert subprocess.run([*run, "--out", str(out), "--video", str(old)], env=subprocess_env()).returncode == 0
    earlier_out = out.read_bytes()
    mount = tmp_path / "small"
    mount.mkdir()
    script = f"""
set -e
mount -t tmpfs -o size=400k none {mount}
cp {old} {mount}/v.avi
head -c $(( 400*1024 - $(stat -c %s {old}) * 3 / 2 )) /dev/zero > {mount}/filler || true
set +e
{' '.join(run)} --out {out} --video {mount}/v.avi --seed 1 2> {tmp_path}/err.txt
echo "rc=$?"
cmp {old} {mount}/v.avi && echo same
ls -a {mount}
"""
    result = subprocess.run(["unshare", "-m", "sh", "-c", script], env=subprocess_env(), capture_output=True, text=True,
                            timeout=300)
    err = (tmp_path / "err.txt").read_text()
    assert "rc=2" in result.stdout, (result.stdout, result.stderr, err)
    assert "same" in result.stdout
    assert ".tmp-" not in result.stdout
    assert err.strip().splitlines() == [err.strip().splitlines()[-1]] and f"{mount}/v.avi" in err, err
    assert out.read_bytes() == earlier_out


def test_a_write_never_replaces_a_device_fifo_or_folder(tmp_path):
    # Renaming over /dev/null as root turns it into a regular file; a FIFO and a link to one
    # stand in for it here (a real device would be clobbered if this failed).
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    link = tmp_path / "link.json"
    link.symlink_to(fifo)
    folder = tmp_path / "folder.json"
    folder.mkdir()
    for path in (fifo, link, folder):
        for write in (lambda: io.write_json(path, {"a": 1}), lambda: io.write_text(path, "x\n"),
                      lambda: io.temporary_for(path)):
            with pytest.raises(OutputError, match=rf"{re.escape(path.name)}: not a regular file"):
                write()
        with pytest.raises(OutputError, match="not a regular file"):
            with io.Together() as outputs:
                outputs.text(path, "x\n")
    assert fifo.is_fifo() and link.is_symlink() and folder.is_dir()
    assert not temporaries(tmp_path)


def test_a_failed_rename_undoes_the_earlier_ones(tmp_path, monkeypatch):
    first, second = tmp_path / "a.txt", tmp_path / "b.txt"
    first.write_text("old a\n")
    second.write_text("old b\n")
    real = os.replace

    def failing(src, dst, *args, **kwargs):
        if Path(dst) == second and ".tmp-" in str(src) and "-old-" not in str(src):
            raise OSError(28, "No space left on device")
        return real(src, dst, *args, **kwargs)

    monkeypatch.setattr(io.os, "replace", failing)
    with pytest.raises(OutputError, match=r"b\.txt: cannot write \(No space left on device\)"):
        with io.Together() as outputs:
            outputs.text(first, "new a\n")
            outputs.text(second, "new b\n")
            outputs.text(tmp_path / "c.txt", "new c\n")
    assert first.read_text() == "old a\n" and second.read_text() == "old b\n"
    assert not (tmp_path / "c.txt").exists() and not temporaries(tmp_path)


def test_a_full_disk_names_the_file(tmp_path, monkeypatch):
    real = os.fsync

    def full(fd):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(io.os, "fsync", full)
    with pytest.raises(OutputError, match=r"r\.txt: cannot write \(No space left on device\)"):
        io.write_text(tmp_path / "r.txt", "x\n")
    monkeypatch.setattr(io.os, "fsync", real)
    assert not list(tmp_path.iterdir())


def test_synth_writes_a_sequence_completely_or_not_at_all(tmp_path, capsys, monkeypatch):
    import nrmlc.data.synthetic as synthetic

    out = tmp_path / "S"
    synth(out, seed=0, count=2, capsys=capsys)
    before = {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}
    calls = []
    real = synthetic.write_bytes

    def dying(path, data):
        calls.append(path)
        if len(calls) == 4:
            raise OSError(28, "No space left on device")
        return real(path, data)

    monkeypatch.setattr(synthetic, "write_bytes", dying)
    code, _, err = run_main(["synth", "--out", out, "--frames", "6", "--count", "2", "--seed", "5"], capsys)
    assert code == 2 and "synth-01: cannot write (No space left on device)" in err, err
    assert {p: p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()} == before
    assert not temporaries(tmp_path)
    monkeypatch.setattr(synthetic, "write_bytes", real)
    # Something that is not ours in the second folder: refused before the first is rewritten.
    (out / "synth-02" / "notes.txt").write_text("mine")
    code, _, err = run_main(["synth", "--out", out, "--frames", "6", "--count", "2", "--seed", "5"], capsys)
    assert code == 2 and "synth-02/notes.txt: not part of a sequence" in err, err
    assert (out / "synth-01" / "img" / "0001.png").read_bytes() == before[out / "synth-01" / "img" / "0001.png"]


def test_synth_refuses_what_memory_or_disk_cannot_hold(tmp_path, capsys):
    code, _, err = run_main(["synth", "--out", tmp_path / "S", "--frames", "1000000", "--count", "1000"], capsys)
    assert code == 2 and "--out" in err and "free there; nothing was written" in err, err
    assert not (tmp_path / "S").exists() or not any((tmp_path / "S").iterdir())
    with pytest.raises(ParameterError, match=r"synthetic_suite: 1000 sequences of 1000000 frames need about"):
        synthetic_suite(n_frames=1_000_000, n_sequences=1000)


# ============================================================ two processes, one folder
def test_two_benchmarks_into_one_folder_keep_both(tmp_path):
    data = tmp_path / "S"
    for sequence in synthetic_suite(n_frames=30, size=(96, 128), n_sequences=2):
        write_otb_sequence(sequence, data / sequence.name)
    out = tmp_path / "R"
    params = ["--param", "n_particles=20", "--param", "n_positive=10", "--param", "n_negative=20",
              "--param", "max_positive=20", "--jobs", "1"]
    processes = [subprocess.Popen([sys.executable, "-m", "nrmlc", "benchmark", str(data), "--out", str(out),
                                   "--sequences", name, "--cache", str(tmp_path / f"C{name}"), *params],
                                  env=subprocess_env(), stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
                 for name in ("synth-01", "synth-02")]
    for process in processes:
        _, err = process.communicate(timeout=300)
        assert process.returncode == 0, err
    manifest = json.loads((out / MANIFEST_NAME).read_text())
    assert sorted(manifest["runs"]) == ["synth-01", "synth-02"]
    summary = json.loads((out / "summary.json").read_text())
    assert sorted(summary["per_sequence"]) == ["synth-01", "synth-02"]
    assert (out / "summary.csv").read_text().count("\nsynth-0") == 2
    assert not temporaries(out)


def test_colliding_sequence_names_are_refused(tmp_path, capsys):
    base = synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0]
    jog = write_otb_sequence(base, tmp_path / "root" / "Jog")
    gt = (jog / "groundtruth_rect.txt").read_text()
    (jog / "groundtruth_rect.txt").rename(jog / "groundtruth_rect.1.txt")
    (jog / "groundtruth_rect.2.txt").write_text(gt)
    write_otb_sequence(base, tmp_path / "root" / "Jog-1")
    with pytest.raises(DataError, match=r"two sequences are named 'Jog-1' \(.*Jog \(target file groundtruth_rect"
                                        r"\.1\.txt\) and .*Jog-1\)"):
        list_sequences(tmp_path / "root")
    code, _, err = run_main(["benchmark", tmp_path / "root", "--out", tmp_path / "R"], capsys)
    assert code == 2 and "two sequences are named 'Jog-1'" in err
    code, _, err = run_main(["benchmark", tmp_path / "root", "--out", tmp_path / "R", "--sequences", "Jog-1,Jog"], capsys)
    assert code == 2 and "two sequences are named 'Jog-1'" in err
    assert not (tmp_path / "R" / "Jog-1.txt").exists()


@pytest.mark.parametrize("name", ["../elsewhere", "/tmp", ".", "..", "sub/dir"])
def test_sequences_are_names_in_the_data_root(tmp_path, capsys, name):
    write_otb_sequence(synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0], tmp_path / "root" / "A")
    code, _, err = run_main(["benchmark", tmp_path / "root", "--out", tmp_path / "R", "--sequences", name], capsys)
    assert code == 2 and f"--sequences {name!r}: give the name of a sequence of" in err, err


# ============================================================ every input checked where read
def _jpeg_folder(tmp_path: Path, frames: int = 8) -> Path:
    sequence = synthetic_suite(n_frames=frames, size=(96, 128), n_sequences=1)[0]
    folder = tmp_path / "Seq"
    (folder / "img").mkdir(parents=True)
    for index in range(frames):
        cv2.imwrite(str(folder / "img" / f"{index + 1:04d}.jpg"), sequence.raw_frame(index))
    io.write_boxes(folder / "groundtruth_rect.txt", sequence.groundtruth)
    return folder


def test_jpeg_with_a_hole_is_refused_by_name_and_alone(tmp_path):
    folder = _jpeg_folder(tmp_path)
    frame = folder / "img" / "0005.jpg"
    data = frame.read_bytes()
    start = data.rfind(b"\xff\xda") + 20
    frame.write_bytes(data[:start] + data[start + (len(data) - start) // 2:])  # half the scan cut out
    result = subprocess.run([sys.executable, "-m", "nrmlc", "track", str(folder), "--out", str(tmp_path / "r.txt"),
                             *FAST], env=subprocess_env(), capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert lines == [lines[-1]] and lines[0].startswith(f"error: {frame}: cannot read image (damaged JPEG data"), \
        result.stderr
    assert not (tmp_path / "r.txt").exists()


def test_jpeg_with_flipped_scan_bytes_is_refused(tmp_path):
    # 40 flipped bytes mid-scan: most pixels decode wrong, and libjpeg's only line is often
    # "N extraneous bytes before marker 0xd9" (else "premature end of data segment").
    folder = _jpeg_folder(tmp_path)
    frame = folder / "img" / "0003.jpg"
    original = frame.read_bytes()
    start = original.rfind(b"\xff\xda") + 20
    messages = []
    for seed in range(6):
        data = bytearray(original)
        for position in np.random.default_rng(seed).choice(np.arange(start, len(data) - 2), 40, replace=False):
            data[position] ^= 0x5A
        frame.write_bytes(bytes(data))
        with pytest.raises(DataError, match=r"0003\.jpg: cannot read image \(damaged JPEG data: ") as refused:
            open_sequence(folder).raw_frame(2)
        messages.append(str(refused.value))
    assert any("extraneous bytes before marker 0xd9" in message for message in messages), messages


def test_jpeg_with_bytes_after_its_end_marker_reads_whole(tmp_path):
    folder = _jpeg_folder(tmp_path)
    frame = folder / "img" / "0002.jpg"
    expected = cv2.imread(str(frame), cv2.IMREAD_UNCHANGED)
    frame.write_bytes(frame.read_bytes() + b"camera trailer" * 4)  # after FFD9: libjpeg never reads it
    np.testing.assert_array_equal(open_sequence(folder).raw_frame(1), expected)


def test_damaged_frame_check_costs_little(tmp_path):
    from nrmlc.data.image import native_messages

    start = time.perf_counter()
    for _ in range(2000):
        with native_messages():
            pass
    per_frame = (time.perf_counter() - start) / 2000
    print(f"damaged-frame check: {per_frame * 1e6:.1f} us per frame")
    assert per_frame < 0.05 * 2e-3  # under 5% of a 2 ms frame


def test_good_jpegs_decode_as_before(tmp_path):
    folder = _jpeg_folder(tmp_path)
    sequence = open_sequence(folder)
    for index in range(len(sequence)):
        expected = cv2.imread(str(folder / "img" / f"{index + 1:04d}.jpg"), cv2.IMREAD_UNCHANGED)
        np.testing.assert_array_equal(sequence.raw_frame(index), expected)


def test_text_named_jpg_is_not_an_image(tmp_path):
    folder = _jpeg_folder(tmp_path)
    (folder / "img" / "0001.jpg").write_text("hello, not a picture\n")
    with pytest.raises(DataError, match=r"0001\.jpg: cannot read image \(not an image: no JPEG, PNG or BMP signature"):
        open_sequence(folder)


def test_foreign_video_lines_do_not_reach_the_user(tmp_path):
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(2000))  # no moov atom
    result = subprocess.run([sys.executable, "-m", "nrmlc", "track", str(broken), "--out", str(tmp_path / "r.txt"),
                             "--init-box", "1,1,10,10"], env=subprocess_env(), capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [result.stderr.strip().splitlines()[0]]
    assert result.stderr.startswith(f"error: {broken}:") and "moov" not in result.stderr, result.stderr


@pytest.mark.parametrize("kind", ["dangling link", "fifo", "device link", "folder", "looping link"])
@pytest.mark.parametrize("name", ["groundtruth_rect.txt", "groundtruth_rect.1.txt", "datainfo.txt"])
def test_unreadable_ground_truth_path_is_an_error_not_an_absence(tmp_path, kind, name):
    folder = write_otb_sequence(synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0], tmp_path / "Seq")
    (folder / "groundtruth_rect.txt").unlink()
    path = folder / name
    if kind == "dangling link":
        path.symlink_to(folder / "nowhere.txt")
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "device link":
        path.symlink_to("/dev/null")
    elif kind == "folder":
        path.mkdir()
    else:
        path.symlink_to(path)
    with pytest.raises(DataError, match=rf"{name}: (broken symbolic link|not a regular file|symbolic link loop)"):
        open_sequence(folder)


def _pack(tmp_path: Path, corners: np.ndarray) -> Path:
    folder = write_otb_sequence(synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0], tmp_path / "Pack")
    (folder / "groundtruth_rect.txt").unlink()
    (folder / "datainfo.txt").write_text("64 48 4")
    cells = np.empty((1, 1), dtype=object)
    cells[0, 0] = corners
    scipy.io.savemat(str(folder / "pack_gt.mat"), {"frameIndex": np.array([[1]]), "gtCornersAll": cells})
    return folder


@pytest.mark.parametrize("corners, message", [
    (np.array([[1e6, 1e6, 1e6 + 9, 1e6 + 9, 1e6], [5.0, 14, 14, 5, 5]]), r"lie far beyond the 64x48 frame"),
    (np.array([[-200.0, -200, -190, -190, -200], [5.0, 14, 14, 5, 5]]), r"lie far beyond the 64x48 frame"),
    (np.array([[10.0, 10, 10, 10, 10], [5.0, 14, 14, 5, 5]]), r"a box of zero size \(0x9 px\)"),
])
def test_sparse_pack_boxes_are_checked_when_read(tmp_path, corners, message):
    folder = _pack(tmp_path, corners)
    with pytest.raises(DataError, match=rf"pack_gt\.mat: keyframe 1: .*{message}"):
        open_sequence(folder)
    # A box sticking out of the frame a little is a target leaving it: read.
    folder = _pack(tmp_path / "ok", np.array([[50.0, 50, 70, 70, 50], [40.0, 52, 52, 40, 40]]))
    assert open_sequence(folder).groundtruth[0].tolist() == [50.0, 40.0, 20.0, 12.0]


# =================================================================== resources
@pytest.mark.parametrize("values, named", [
    (dict(patch_size=3000), "patch_size"),
    (dict(n_particles=100_000, redetect_count=100_000, n_negative=9000, max_positive=1000), "n_negative"),
])
def test_memory_is_estimated_from_the_combination(monkeypatch, values, named):
    import nrmlc.resources

    monkeypatch.setattr(nrmlc.resources, "physical_memory", lambda: 16 * 2**30)
    with pytest.raises(ParameterError, match=rf"parameter {named}: with .* a tracker needs about .*, more than this "
                                             rf"machine's 16\.0 GB"):
        TrackerParams(**values)
    assert TrackerParams().estimated_bytes() < 2**28  # the defaults need tens of MB
    assert TrackerParams.paper().estimated_bytes() < 2**28


def test_damaged_numba_cache_file_recompiles_with_one_warning(tmp_path):
    script = "import numpy as np, nrmlc.kernels as k; print(k.squared_norms(np.ones((3, 4), np.float32)).tolist())"
    env = dict(subprocess_env(), NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    first = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0 and first.stdout.strip() == "[4.0, 4.0, 4.0]", first.stderr
    damaged = list((tmp_path / "numba").rglob("distance._squared_norm*.nbc"))
    assert damaged
    for path in damaged:
        with open(path, "r+b") as handle:
            handle.truncate(100)
    second = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
    assert second.returncode == 0 and second.stdout.strip() == "[4.0, 4.0, 4.0]", second.stderr
    assert second.stderr.count("numba's cache in") == 1 and "is damaged" in second.stderr, second.stderr
    third = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
    assert third.returncode == 0 and "damaged" not in third.stderr  # cached whole again


def test_no_writable_numba_cache_runs_uncached(tmp_path):
    """A read-only install and a read-only home: numba finds no cache location; the kernels
    compile in memory, with one warning (numba alone refuses at import)."""
    copy = tmp_path / "install"
    shutil.copytree(REPO_ROOT / "nrmlc", copy / "nrmlc", ignore=shutil.ignore_patterns("__pycache__"))
    (copy / "nrmlc" / "kernels" / "__pycache__").write_text("not a folder")  # cannot be created: as read-only
    script = "import numpy as np, nrmlc.kernels as k; print(k.squared_norms(np.ones((3, 4), np.float32)).tolist())"
    env = dict(os.environ, PYTHONPATH=str(copy), HOME="/dev/null", XDG_CACHE_HOME="/dev/null/cache",
               PYTHONDONTWRITEBYTECODE="1")
    env.pop("NUMBA_CACHE_DIR", None)
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300,
                            cwd=tmp_path)
    assert result.returncode == 0 and result.stdout.strip() == "[4.0, 4.0, 4.0]", result.stderr
    assert result.stderr.count("numba cannot cache the kernels") == 1, result.stderr


def test_the_stale_cache_is_dropped_where_numba_keeps_it_under_numba_cache_dir(monkeypatch, tmp_path):
    from numba.core.caching import _CacheLocator

    from nrmlc.kernels import cache

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    kernels = REPO_ROOT / "nrmlc" / "kernels"
    assert cache.cache_folder(kernels) == tmp_path / _CacheLocator.get_suitable_cache_subpath(str(kernels / "x.py"))


# =================================================================== the Python API
def test_numpy_scalars_are_python_numbers():
    params = TrackerParams(n_particles=np.int64(20), lam=np.float32(0.5), alpha=np.int32(25),
                           dictionary_sizes=(np.int64(5), 8, 10), motion_sigmas=np.array([2.0, 2, 0.01, 0, 0.005, 0]),
                           occlusion_detection=np.bool_(True))
    assert type(params.n_particles) is int and type(params.lam) is float and type(params.alpha) is int
    assert params == TrackerParams(n_particles=20, lam=0.5, alpha=25, occlusion_detection=True)
    assert RunSpec(synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0], params, seed=np.int64(3)).seed == 3


@pytest.mark.parametrize("values", [dict(n_particles=20.0), dict(dictionary_sizes=(5.7, 8)), dict(patch_size=np.float64(32)),
                                    dict(motion_sigmas=("2", 2, 0, 0, 0, 0)), dict(occlusion_detection=1)])
def test_a_float_where_an_integer_is_needed_is_refused(values):
    with pytest.raises(ParameterError, match=rf"parameter {next(iter(values))}: must be"):
        TrackerParams(**values)


def test_a_dict_is_not_tracker_params():
    sequence = synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0]
    with pytest.raises(ParameterError, match="params must be a TrackerParams, got dict"):
        NRMLCTracker(params={"n_particles": 20})
    with pytest.raises(ParameterError, match="params must be a TrackerParams, got dict"):
        RunSpec(sequence, {"n_particles": 20})
    with pytest.raises(ParameterError, match="params must be a TrackerParams, got dict"):
        track_sequence(sequence, {"n_particles": 20})
    with pytest.raises(ParameterError, match="params must be a TrackerParams, got dict"):
        run_benchmark("nowhere", "out", {"n_particles": 20})


@pytest.mark.parametrize("n_frames", [0, -3, 2.5, "3", True])
def test_track_sequence_refuses_bad_frame_counts(n_frames):
    sequence = synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0]
    with pytest.raises(ParameterError, match="n_frames must be an integer >= 1"):
        track_sequence(sequence, SMALL, n_frames=n_frames)
    assert len(track_sequence(sequence, SMALL, n_frames=np.int64(2)).boxes) == 2


def test_two_threads_on_one_tracker_get_a_clear_error():
    sequence = synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0]
    tracker = NRMLCTracker(params=SMALL)
    tracker.init(sequence.frame(0), sequence.init_box)
    inside, release = threading.Event(), threading.Event()
    real_step = tracker.step

    def slow_step(frame, particles=None):
        inside.set()
        release.wait(10)
        return real_step(frame, particles)

    tracker.step = slow_step
    worker = threading.Thread(target=tracker.update, args=(sequence.frame(1),))
    worker.start()
    assert inside.wait(10)
    with pytest.raises(ParameterError, match="another thread is inside init or update of the same tracker"):
        tracker.update(sequence.frame(2))
    release.set()
    worker.join()
    tracker.step = real_step
    tracker.update(sequence.frame(2))  # free again


# =================================================================== found beyond the issue
def test_benchmark_out_inside_a_sequence_folder_is_refused(tmp_path, capsys):
    data = tmp_path / "S"
    write_otb_sequence(synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)[0], data / "synth-01")
    for out in (data / "synth-01", data / "synth-01" / "img" / "R"):
        code, _, err = run_main(["benchmark", data, "--out", out, "--cache", tmp_path / "C"], capsys)
        assert code == 2 and f"--out {out}: is inside the sequence folder" in err, err
    assert sorted(p.name for p in (data / "synth-01").iterdir()) == ["groundtruth_rect.txt", "img"]


def test_huge_box_file_is_refused_before_it_is_read(tmp_path, monkeypatch):
    import nrmlc.data.boxes as boxes

    path = tmp_path / "groundtruth_rect.txt"
    path.write_text("1,2,3,4\n" * 200)
    monkeypatch.setattr(boxes, "MAX_BOX_FILE_BYTES", 1000)
    with pytest.raises(DataError, match=r"groundtruth_rect\.txt: 0 MB is not a box file"):
        read_box_file(path)


def test_a_sequence_that_renders_its_own_frames_keeps_its_name_in_the_key():
    from nrmlc.data import Sequence

    class Rendered(Sequence):
        def _read_image(self, index):
            return np.full((20, 20), 10 * index, np.uint8)

    a = Rendered("a", None, np.tile([1.0, 1, 5, 5], (3, 1)), n_frames=3)
    b = Rendered("b", None, np.tile([1.0, 1, 5, 5], (3, 1)), n_frames=3)
    assert a.identity != b.identity and a.identity.startswith("Rendered:a:3:sha256=")


def test_synth_does_not_replace_a_symlinked_sequence_folder(tmp_path, capsys):
    target = tmp_path / "real"
    target.mkdir()
    (tmp_path / "S").mkdir()
    (tmp_path / "S" / "synth-01").symlink_to(target)
    code, _, err = run_main(["synth", "--out", tmp_path / "S", "--frames", "4", "--count", "1"], capsys)
    assert code == 2 and "synth-01: is a symbolic link" in err, err
    assert (tmp_path / "S" / "synth-01").is_symlink()
