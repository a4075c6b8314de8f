"""Every reader of ``nrmlc evaluate`` (result ``.txt`` files, OTB ``.mat`` files, attribute files,
``benchmark.json``) fed truncated, oversized, wrong-type, non-finite, link, FIFO and wrong-case
inputs: each gives one error line naming the file (exit status 2) or a documented note naming
it, never a traceback and never a silent change of score. Also: one manifest check for
``benchmark`` and ``evaluate``, a folder's kind decided by what it holds, and outputs written
together. No tracking: every input is written here.
"""
from __future__ import annotations

import csv
import json
import os
import shutil
import struct
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from nrmlc.cli import main
from nrmlc.data import open_sequence
from nrmlc.workbench import benchmark, otb_results
from nrmlc.workbench.attributes import MAX_ATTRIBUTE_BYTES
from nrmlc.workbench.manifest import MAX_MANIFEST_BYTES
from nrmlc.workbench.results_layout import MANIFEST_NAME

N_FRAMES = 10
#: Every case's first sequence, the one its inputs are about.
TARGET = "synth-01"


# ------------------------------------------------------------------ inputs
def truth(data_root, name) -> np.ndarray:
    return open_sequence(data_root / name).groundtruth


def shifted(data_root, name, dx=2.0) -> np.ndarray:
    boxes = truth(data_root, name).copy()
    boxes[1:, 0] += dx
    return boxes


def box_text(boxes) -> str:
    return "\n".join(",".join(f"{v:g}" for v in row) for row in boxes) + "\n"


def save_mat(path: Path, **fields) -> None:
    """An OTB result file: a 1x1 cell ``results`` holding the struct ``fields``."""
    cell = np.empty((1, 1), dtype=object)
    cell[0, 0] = fields
    scipy.io.savemat(path, {"results": cell}, do_compression=False, oned_as="row")


def rect_fields(boxes, fps=20.0) -> dict:
    return {"res": np.asarray(boxes, dtype=np.float64), "type": "rect", "fps": np.array([[fps]]),
            "len": np.array([[len(boxes)]]), "startFrame": np.array([[1]]), "annoBegin": np.array([[1]])}


def folder_of(parent: Path, folder_name: str, names, write) -> Path:
    """A new folder ``parent/folder_name`` holding ``write(folder, name)``'s file for each sequence."""
    folder = parent / folder_name
    folder.mkdir()
    for index, name in enumerate(names):
        write(folder, index, name)
    return folder


@pytest.fixture()
def txt_folder(data_root, names, tmp_path) -> Path:
    return folder_of(tmp_path, "Peer", names, lambda folder, _, name: (folder / f"{name}.txt").write_text(
        box_text(shifted(data_root, name))))


@pytest.fixture()
def mat_folder(data_root, names, tmp_path) -> Path:
    return folder_of(tmp_path, "OTB", names, lambda folder, _, name: save_mat(
        folder / f"{name}_Mat.mat", **rect_fields(shifted(data_root, name))))


@pytest.fixture()
def attribute_folder(names, tmp_path) -> Path:
    def write(folder, index, name):  # each sequence has one attribute of its own
        (folder / f"{name}.txt").write_text(",".join("1" if i == index else "0" for i in range(11)) + "\n")

    return folder_of(tmp_path, "anno", names, write)


@pytest.fixture()
def bench_folder(data_root, names, tmp_path) -> Path:
    """What ``nrmlc benchmark --seeds 0`` leaves: results, and a manifest of their runs."""
    folder = folder_of(tmp_path, "NRMLC", names, lambda folder, _, name: (folder / f"{name}.txt").write_text(
        box_text(shifted(data_root, name, 1.0))))
    manifest = {"settings": {"params": {}, "max_frames": None, "data": str(data_root.resolve())},
                "primary_seed": 0,
                "runs": {name: {"0": {"frames": N_FRAMES, "fps": 10.0, "scores": None, "code_version": "t"}}
                         for name in names}}
    (folder / MANIFEST_NAME).write_text(json.dumps(manifest))
    return folder


def run_main(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def evaluate(folder, data_root, capsys, *more, as_json=True):
    argv = ["evaluate", "--results", folder, "--data", data_root, *more] + (["--json"] if as_json else [])
    code, out, err = run_main(argv, capsys)
    return code, (json.loads(out) if as_json and code == 0 else out), err


def assert_error(code, err, path, what) -> None:
    """One error line naming ``path``, exit status 2."""
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert str(path) in lines[0] and what in lines[0], err


def assert_note(code, err, path, what) -> None:
    """Exit status 0 and a note line naming ``path``."""
    assert code == 0, err
    notes = [line for line in err.splitlines() if line.startswith("note: ") and str(path) in line]
    assert notes and any(what in line for line in notes), err


def auc(result, tracker, sequence=TARGET) -> float:
    entry = next(t for t in result["trackers"] if t["tracker"] == tracker)
    return entry["per_sequence"][sequence]["success_auc"]


def dangling_link(path: Path) -> None:
    path.unlink(missing_ok=True)
    path.symlink_to(path.parent / "nowhere")


def fifo(path: Path) -> None:
    path.unlink(missing_ok=True)
    os.mkfifo(path)


def sparse(path: Path, size: int) -> None:
    """A file of ``size`` bytes that takes no disk (nothing reads it: it is refused by its size)."""
    with open(path, "wb") as handle:
        handle.truncate(size)


def truncated(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2 + 3])


# ------------------------------------------------------------------ result .txt files
#: case -> (how the file is spoilt, what the line says, whether it stops the command or is a note).
RESULT_CASES = {
    "link": (dangling_link, "broken symbolic link", "error"),
    "fifo": (fifo, "not a regular file", "error"),
    "folder": (lambda p: (p.unlink(), p.mkdir()), "not a regular file", "error"),
    "oversized": (lambda p: sparse(p, (1 << 30) + 1), "is too large (result file", "error"),
    "truncated": (lambda p: p.write_text(p.read_text()[:-9]), "not used, unreadable", "note"),
    "text": (lambda p: p.write_text("a,b,c,d\n" * N_FRAMES), "not used, unreadable", "note"),
    "binary": (lambda p: p.write_bytes(bytes(range(256)) * 4), "not used, unreadable", "note"),
    "empty": (lambda p: p.write_text(""), "not used, unreadable", "note"),
}


@pytest.mark.parametrize("case", sorted(RESULT_CASES))
def test_result_file_that_cannot_be_read_is_named(case, txt_folder, data_root, capsys):
    """Unreadable as a file: one error line; readable but malformed: a note, the sequence failed."""
    make, what, verdict = RESULT_CASES[case]
    path = txt_folder / f"{TARGET}.txt"
    make(path)
    code, result, err = evaluate(txt_folder, data_root, capsys)
    if verdict == "error":
        assert_error(code, err, path, what)
    else:
        assert_note(code, err, path, what)
        assert auc(result, "Peer") == 0.0


def test_non_finite_result_rows_are_failed_frames(txt_folder, data_root, capsys):
    path = txt_folder / f"{TARGET}.txt"
    lines = path.read_text().splitlines()
    lines[3], lines[4] = "inf,1,2,3", "nan,nan,nan,nan"
    path.write_text("\n".join(lines) + "\n")
    code, result, err = evaluate(txt_folder, data_root, capsys)
    assert code == 0, err
    entry = next(t for t in result["trackers"] if t["tracker"] == "Peer")["per_sequence"][TARGET]
    assert entry["n_missing"] == 2 and entry["file"] == str(path)


@pytest.mark.parametrize("kind, file_name, suffix", [("txt", f"{TARGET}.txt", ".TXT"), ("txt", f"{TARGET}.txt", ".Txt"),
                                                     ("mat", f"{TARGET}_Mat.mat", ".MAT"),
                                                     ("mat", f"{TARGET}_Mat.mat", ".Mat")])
def test_result_file_extension_in_any_case_is_the_same_file(kind, file_name, suffix, data_root, capsys, request):
    folder = request.getfixturevalue(f"{kind}_folder")
    tracker = "Peer" if kind == "txt" else "Mat"
    _, before, _ = evaluate(folder, data_root, capsys)
    path = folder / file_name
    path.rename(path.with_suffix(suffix))
    code, after, err = evaluate(folder, data_root, capsys)
    assert code == 0 and "no result file" not in err, err
    assert auc(after, tracker) == auc(before, tracker) > 0


def test_two_cases_of_one_result_file_are_refused(txt_folder, data_root, capsys):
    shutil.copy(txt_folder / f"{TARGET}.txt", txt_folder / f"{TARGET}.TXT")
    code, _, err = evaluate(txt_folder, data_root, capsys)
    assert_error(code, err, txt_folder, "both name sequence")


def test_hidden_temporary_is_not_a_result(txt_folder, data_root, capsys):
    _, before, _ = evaluate(txt_folder, data_root, capsys)
    (txt_folder / f".tmp-{TARGET}.txt-1a2b").write_text("junk\n")
    (txt_folder / f".{TARGET}.txt").write_text("junk\n")
    code, after, err = evaluate(txt_folder, data_root, capsys)
    assert code == 0 and "junk" not in err and ".tmp-" not in err, err
    assert after["trackers"] == before["trackers"]


@pytest.mark.parametrize("case", ["link", "fifo"])
def test_single_result_file_that_cannot_be_read_is_refused(case, txt_folder, data_root, capsys):
    path = txt_folder / f"{TARGET}.txt"
    RESULT_CASES[case][0](path)
    code, _, err = run_main(["evaluate", "--results", path, "--groundtruth",
                             data_root / TARGET / "groundtruth_rect.txt"], capsys)
    assert_error(code, err, path, RESULT_CASES[case][1])


# ------------------------------------------------------------------ OTB .mat files
def _set(**changes):
    """A change of one field of a ``.mat`` file's results{1}."""
    def make(path: Path, data_root) -> None:
        fields = rect_fields(shifted(data_root, TARGET))
        fields.update(changes)
        save_mat(path, **{k: v for k, v in fields.items() if v is not None})
    return make


def _affine(tmplsize):
    def make(path: Path, data_root) -> None:
        states = np.zeros((N_FRAMES, 6))
        states[:, 2] = states[:, 5] = 1.0
        save_mat(path, res=states, type="ivtAff", tmplsize=tmplsize, fps=np.array([[5.0]]))
    return make


MAT_NOTES = {
    "truncated": (lambda p, d: truncated(p), "not a readable MAT file"),
    "junk": (lambda p, d: p.write_bytes(b"MATLAB 5.0 junk" + bytes(300)), "not a readable MAT file"),
    "tmplsize text": (_affine("32x24"), "field 'tmplsize' is not numeric (text)"),
    "tmplsize struct": (_affine({"w": np.array([[32.0]]), "h": np.array([[24.0]])}),
                        "field 'tmplsize' is not numeric (a struct)"),
    "tmplsize infinite": (_affine(np.array([[np.inf, 24.0]])), "tmplsize must be two positive numbers"),
    "res text": (_set(res="1,2,3,4"), "res is not numeric"),
    "res struct": (_set(res={"x": np.array([[1.0]])}), "res is not numeric"),
    "type number": (_set(type=np.array([[4.0]])), "field 'type' is not text"),
    "type empty": (_set(type=np.zeros((0, 0))), "field 'type' is not text"),
    "fps text": (_set(fps="fast"), "field 'fps' is not numeric (text)"),
    "startFrame struct": (_set(startFrame={"a": np.array([[1.0]])}), "field 'startFrame' is not numeric"),
    "len text": (_set(len="ten"), "field 'len' is not numeric"),
    "no results": (lambda p, d: scipy.io.savemat(p, {"other": np.eye(2)}), "no 'results' variable"),
}


@pytest.mark.parametrize("case", sorted(MAT_NOTES))
def test_malformed_mat_file_is_a_note_naming_it(case, mat_folder, data_root, capsys):
    make, what = MAT_NOTES[case]
    path = mat_folder / f"{TARGET}_Mat.mat"
    make(path, data_root)
    code, result, err = evaluate(mat_folder, data_root, capsys)
    assert_note(code, err, path, what)
    assert auc(result, "Mat") == 0.0  # no result there: every frame missing, as the note says


@pytest.mark.parametrize("case", ["tmplsize text", "tmplsize struct", "type number", "truncated"])
def test_malformed_single_mat_file_is_one_error_line(case, mat_folder, data_root, capsys):
    make, what = MAT_NOTES[case]
    path = mat_folder / f"{TARGET}_Mat.mat"
    make(path, data_root)
    code, _, err = run_main(["evaluate", "--results", path, "--groundtruth",
                             data_root / TARGET / "groundtruth_rect.txt"], capsys)
    assert_error(code, err, path, what)


def test_non_finite_mat_values_are_failed_frames_and_no_speed(mat_folder, data_root, capsys):
    boxes = shifted(data_root, TARGET)
    boxes[4] = [np.inf, 1, 2, 3]
    boxes[5] = [1e300, 1e300, 1e300, 1e300]
    for fps, name in ((np.inf, "Inf"), (-1e308, "Neg"), (1e300, "Huge")):
        save_mat(mat_folder / f"{TARGET}_{name}.mat", **rect_fields(boxes, fps=fps))
    code, result, err = evaluate(f"{mat_folder}:Inf,Neg,Huge", data_root, capsys)
    assert code == 0, err
    for tracker in result["trackers"]:
        assert tracker["per_sequence"][TARGET]["n_missing"] == 2
        assert tracker["fps"] is None  # not finite, negative, beyond one frame a nanosecond: not a speed


MAT_ERRORS = {
    "link": (dangling_link, "broken symbolic link"),
    "fifo": (fifo, "not a regular file"),
    "oversized": (lambda p: sparse(p, otb_results.MAX_MAT_BYTES + 1), "is too large (OTB result file"),
}


@pytest.mark.parametrize("case", sorted(MAT_ERRORS))
def test_mat_file_that_cannot_be_read_is_refused_by_name(case, mat_folder, data_root, capsys):
    make, what = MAT_ERRORS[case]
    path = mat_folder / f"{TARGET}_Mat.mat"
    make(path)
    code, _, err = evaluate(mat_folder, data_root, capsys)
    assert_error(code, err, path, what)


def compressed_mat(path: Path, inflated: int) -> None:
    """A MAT v5 file of one compressed variable that inflates to ``inflated`` bytes of zeros."""
    header = b"MATLAB 5.0 MAT-file, written for a test".ljust(116, b" ") + bytes(8) + struct.pack("<H", 0x0100) + b"IM"
    packer = zlib.compressobj(1)
    zeros = bytes(1 << 20)
    body = b"".join(packer.compress(zeros) for _ in range(inflated >> 20)) + packer.flush()
    path.write_bytes(header + struct.pack("<II", 15, len(body)) + body)


def test_mat_file_that_inflates_beyond_the_limit_is_refused_before_loading(mat_folder, data_root, capsys,
                                                                           monkeypatch):
    path = mat_folder / f"{TARGET}_Mat.mat"
    compressed_mat(path, otb_results.MAX_MAT_CONTENT_BYTES + (1 << 20))
    assert path.stat().st_size < 2 << 20  # a small file, over 200 times as large inflated
    monkeypatch.setattr(scipy.io, "loadmat", lambda *a, **k: pytest.fail("loaded"))
    code, _, err = evaluate(mat_folder, data_root, capsys)
    assert_error(code, err, path, "once decompressed")


def test_memory_running_out_on_a_mat_file_stops_the_command(mat_folder, data_root, capsys, monkeypatch):
    def out_of_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(scipy.io, "loadmat", out_of_memory)
    path = mat_folder / f"{TARGET}_Mat.mat"
    code, _, err = evaluate(mat_folder, data_root, capsys)
    assert_error(code, err, path, "ran out of memory")
    assert "not used" not in err


def test_memory_running_out_on_a_result_file_stops_the_command(txt_folder, data_root, capsys, monkeypatch):
    import nrmlc.data

    def out_of_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(nrmlc.data, "read_box_file", out_of_memory)
    code, _, err = evaluate(txt_folder, data_root, capsys)
    assert_error(code, err, txt_folder, "ran out of memory")


# ------------------------------------------------------------------ a folder's kind
@pytest.mark.parametrize("stray", ["readme.txt", "README.TXT", f".tmp-{TARGET}.txt-9f8e"])
def test_a_stray_txt_file_leaves_a_mat_folder_a_mat_folder(stray, mat_folder, data_root, capsys):
    _, before, _ = evaluate(mat_folder, data_root, capsys)
    (mat_folder / stray).write_text("results of the OTB benchmark\n")
    code, after, err = evaluate(mat_folder, data_root, capsys)
    assert code == 0, err
    assert [t["tracker"] for t in after["trackers"]] == ["Mat"]
    assert after["trackers"] == before["trackers"]


def test_a_stray_mat_file_leaves_a_txt_folder_a_txt_folder(txt_folder, data_root, capsys):
    _, before, _ = evaluate(txt_folder, data_root, capsys)
    save_mat(txt_folder / "notes_v2.mat", **rect_fields(np.ones((2, 4))))
    code, after, err = evaluate(txt_folder, data_root, capsys)
    assert code == 0, err
    assert after["trackers"] == before["trackers"]


def test_a_folder_of_both_kinds_is_read_as_the_larger_and_says_so(mat_folder, data_root, names, capsys):
    (mat_folder / f"{TARGET}.txt").write_text(box_text(truth(data_root, TARGET)))
    code, result, err = evaluate(mat_folder, data_root, capsys)
    assert code == 0, err
    assert [t["tracker"] for t in result["trackers"]] == ["Mat"]
    note = [line for line in err.splitlines() if "holds both" in line]
    assert len(note) == 1 and str(mat_folder) in note[0] and "read as the .mat files" in note[0], err
    for name in names[1:]:  # now more .txt results than .mat ones
        (mat_folder / f"{name}.txt").write_text(box_text(truth(data_root, name)))
        (mat_folder / f"{name}_Mat.mat").unlink()
    code, result, err = evaluate(mat_folder, data_root, capsys)
    assert code == 0 and [t["tracker"] for t in result["trackers"]] == [mat_folder.name], err
    assert "read as a folder of <Seq>.txt files" in err


# ------------------------------------------------------------------ attribute files
ATTRIBUTE_ERRORS = {
    "truncated": (lambda p: p.write_text("0,1,0,0,1"), "expected 11 flags"),
    "text": (lambda p: p.write_text("IV,SV"), "expected 11 flags"),
    "binary": (lambda p: p.write_bytes(b"\xff\xfe\x00\x81" * 10), "cannot read the attribute file"),
    "non-finite": (lambda p: p.write_text("nan,0,0,0,0,0,0,0,0,0,inf"), "expected 11 flags"),
    "oversized": (lambda p: sparse(p, MAX_ATTRIBUTE_BYTES + 1), "is too large (attribute file"),
    "link": (dangling_link, "broken symbolic link"),
    "fifo": (fifo, "not a regular file"),
}


@pytest.mark.parametrize("case", sorted(ATTRIBUTE_ERRORS))
def test_attribute_file_that_cannot_be_read_is_refused_by_name(case, txt_folder, attribute_folder, data_root,
                                                               capsys):
    make, what = ATTRIBUTE_ERRORS[case]
    path = attribute_folder / f"{TARGET}.txt"
    make(path)
    code, _, err = evaluate(txt_folder, data_root, capsys, "--attributes", attribute_folder)
    assert_error(code, err, path, what)


def test_attribute_extension_in_any_case_is_the_same_file(txt_folder, attribute_folder, data_root, capsys):
    _, before, _ = evaluate(txt_folder, data_root, capsys, "--attributes", attribute_folder)
    path = attribute_folder / f"{TARGET}.txt"
    path.rename(path.with_suffix(".TXT"))
    code, after, err = evaluate(txt_folder, data_root, capsys, "--attributes", attribute_folder)
    assert code == 0 and "no attribute file" not in err, err
    assert after["attributes"] == before["attributes"]


def test_missing_attribute_file_is_a_note(txt_folder, attribute_folder, data_root, capsys):
    (attribute_folder / f"{TARGET}.txt").unlink()
    code, _, err = evaluate(txt_folder, data_root, capsys, "--attributes", attribute_folder)
    assert_note(code, err, attribute_folder, f"no attribute file in {attribute_folder} for {TARGET}")


# ------------------------------------------------------------------ manifests
def _edit(change):
    def make(path: Path) -> None:
        manifest = json.loads(path.read_text())
        change(manifest)
        path.write_text(json.dumps(manifest))
    return make


def _run(manifest) -> dict:
    return manifest["runs"][TARGET]["0"]


MANIFEST_ERRORS = {
    "truncated": (truncated, "not a benchmark manifest (JSONDecodeError"),
    "binary": (lambda p: p.write_bytes(b"\x80\xff" * 8), "not a benchmark manifest"),
    "deep": (lambda p: p.write_text("[" * 100_000 + "]" * 100_000), "not a benchmark manifest"),
    "oversized": (lambda p: sparse(p, MAX_MANIFEST_BYTES + 1), "is too large (benchmark manifest"),
    "link": (dangling_link, "broken symbolic link"),
    "fifo": (fifo, "not a regular file"),
    "folder": (lambda p: (p.unlink(), p.mkdir()), "not a regular file"),
    "max_frames text": (_edit(lambda m: m["settings"].update(max_frames="abc")), "'settings.max_frames' must be"),
    "max_frames negative": (_edit(lambda m: m["settings"].update(max_frames=-5)), "'settings.max_frames' must be"),
    "max_frames float": (_edit(lambda m: m["settings"].update(max_frames=2.7)), "'settings.max_frames' must be"),
    "max_frames bool": (_edit(lambda m: m["settings"].update(max_frames=True)), "'settings.max_frames' must be"),
    "data number": (_edit(lambda m: m["settings"].update(data=5)), "'settings.data' must be"),
    "params list": (_edit(lambda m: m["settings"].update(params=[1])), "'settings.params' is not an object"),
    "run a list": (_edit(lambda m: m["runs"].update({TARGET: [1]})), f"runs['{TARGET}'] is not an object"),
    "entry a list": (_edit(lambda m: m["runs"][TARGET].update({"0": [1]})), "is not an object"),
    "frames text": (_edit(lambda m: _run(m).update(frames="x")), "frames must be a positive integer"),
    "frames float": (_edit(lambda m: _run(m).update(frames=9.5)), "frames must be a positive integer"),
    "frames huge": (_edit(lambda m: _run(m).update(frames=10**30)), "frames must be a positive integer"),
    "primary_seed list": (_edit(lambda m: m.update(primary_seed=[1])), "'primary_seed' must be a seed"),
    "primary_seed null with runs": (_edit(lambda m: m.update(primary_seed=None)), "no 'primary_seed'"),
    "seed key padded": (_edit(lambda m: m["runs"][TARGET].update({"00": _run(m)})), "the key is not a seed"),
    "fps text": (_edit(lambda m: _run(m).update(fps="abc")), ".fps must be a number"),
    "fps infinite": (lambda p: p.write_text(p.read_text().replace('"fps": 10.0', '"fps": Infinity', 1)),
                     "Infinity is not a JSON number"),
    "fps overflowing": (lambda p: p.write_text(p.read_text().replace('"fps": 10.0', '"fps": 1e400', 1)),
                        ".fps must be a number"),
    "fps negative": (_edit(lambda m: _run(m).update(fps=-1e308)), ".fps must be a number"),
    "fps bool": (_edit(lambda m: _run(m).update(fps=True)), ".fps must be a number"),
    "scores nan": (lambda p: p.write_text(p.read_text().replace('"scores": null', '"scores": {"success_auc": NaN}',
                                                                1)), "NaN is not a JSON number"),
    "scores out of range": (_edit(lambda m: _run(m).update(scores={"success_auc": 7})), "scores must be"),
    "run key a path": (_edit(lambda m: m["runs"].update({"../../etc": {"0": {"frames": 3}}})),
                       "runs key '../../etc' is not a sequence name"),
    "run keys of one name": (_edit(lambda m: m["runs"].update({TARGET.upper(): m["runs"][TARGET]})),
                             "runs has both"),
    "identity a number": (_edit(lambda m: _run(m).update(sequence_identity=5)),
                          ".sequence_identity must be the sequence's content key (text) or absent, got 5"),
    "identity null": (_edit(lambda m: _run(m).update(sequence_identity=None)),
                      ".sequence_identity must be the sequence's content key (text) or absent, got None"),
    "identity a list": (_edit(lambda m: _run(m).update(sequence_identity=["frames:10"])),
                        ".sequence_identity must be"),
}


@pytest.mark.parametrize("case", sorted(MANIFEST_ERRORS))
def test_manifest_evaluate_cannot_follow_is_refused_by_name(case, bench_folder, data_root, capsys):
    make, what = MANIFEST_ERRORS[case]
    path = bench_folder / MANIFEST_NAME
    make(path)
    code, _, err = evaluate(bench_folder, data_root, capsys, "--speed-plot", bench_folder.parent / "speed.png")
    assert_error(code, err, path, what)
    assert "--sequences" not in err


@pytest.mark.parametrize("case", ["fps infinite", "fps negative", "max_frames float", "run key a path", "truncated",
                                  "link", "identity a number"])
def test_benchmark_refuses_the_manifests_evaluate_refuses(case, bench_folder, data_root, tmp_path, capsys):
    make, what = MANIFEST_ERRORS[case]
    path = bench_folder / MANIFEST_NAME
    make(path)
    code, _, err = run_main(["benchmark", data_root, "--out", bench_folder, "--cache", tmp_path / "C"], capsys)
    assert_error(code, err, path, what)
    assert case == "link" or "or choose another --out" in err


def test_memory_running_out_on_a_manifest_stops_the_command(bench_folder, data_root, capsys, monkeypatch):
    import nrmlc.workbench.manifest as manifest

    def out_of_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(manifest.json, "loads", out_of_memory)
    code, _, err = evaluate(bench_folder, data_root, capsys)
    assert_error(code, err, bench_folder / MANIFEST_NAME, "ran out of memory")


def test_a_run_without_its_result_file_is_left_out_of_evaluate(bench_folder, data_root, names, capsys):
    path = bench_folder / MANIFEST_NAME
    _edit(lambda m: m["runs"][TARGET].update({"3": {"frames": N_FRAMES, "fps": 1e6}}))(path)
    _edit(lambda m: m["runs"].update({"synth-09": {"0": {"frames": N_FRAMES, "fps": 1e6}}}))(path)
    code, result, err = evaluate(bench_folder, data_root, capsys)
    assert_note(code, err, bench_folder / "seeds" / "3" / f"{TARGET}.txt", "the file is not there")
    assert_note(code, err, bench_folder / "synth-09.txt", "the file is not there")
    assert result["sequences"] == names  # not synth-09, which never ran
    assert result["trackers"][0]["fps"] == pytest.approx(10.0)  # not the lost runs' speed


def test_a_run_without_its_result_file_gets_no_summary_row(bench_folder, data_root):
    path = bench_folder / MANIFEST_NAME
    _edit(lambda m: m["runs"][TARGET].update({"3": {"frames": N_FRAMES, "fps": 5.0}}))(path)
    settings = json.loads(path.read_text())["settings"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        manifest = benchmark._read_manifest(bench_folder, settings)
    assert any(f"seeds/3/{TARGET}.txt" in str(w.message) and "left out" in str(w.message) for w in caught)
    rows = benchmark.summarize(manifest)["runs"]
    assert [(r["sequence"], r["seed"]) for r in rows if r["sequence"] == TARGET] == [(TARGET, 0)]


# ------------------------------------------------------------------ other seeds' folders
def _seed_run(bench_folder, data_root, names, seed: str) -> Path:
    """Seed ``seed``'s results in ``seeds/<seed>/`` and its entries in the manifest."""
    folder = bench_folder / "seeds" / seed
    folder.mkdir(parents=True)
    for name in names:
        (folder / f"{name}.txt").write_text(box_text(shifted(data_root, name, 3.0)))
    _edit(lambda m: [m["runs"][name].update({seed: {"frames": N_FRAMES, "fps": 10.0}}) for name in names])(
        bench_folder / MANIFEST_NAME)
    return folder


SEED_FOLDER_ERRORS = {
    "link": (dangling_link, "broken symbolic link"),
    "fifo": (fifo, "named as a seed's results folder, but not a folder"),
    "file": (lambda p: p.write_text("x\n"), "named as a seed's results folder, but not a folder"),
}


@pytest.mark.parametrize("case", sorted(SEED_FOLDER_ERRORS))
def test_seed_folder_that_is_no_folder_is_refused_by_name(case, bench_folder, data_root, names, capsys):
    _seed_run(bench_folder, data_root, names, "1")
    make, what = SEED_FOLDER_ERRORS[case]
    path = bench_folder / "seeds" / "2"
    make(path)
    code, _, err = evaluate(bench_folder, data_root, capsys, "--all-seeds")
    assert_error(code, err, path, what)


def test_seeds_that_is_a_dangling_link_is_refused_by_name(bench_folder, data_root, capsys):
    dangling_link(bench_folder / "seeds")
    code, _, err = evaluate(bench_folder, data_root, capsys, "--all-seeds")
    assert_error(code, err, bench_folder / "seeds", "broken symbolic link")


def test_entries_of_seeds_that_name_no_seed_are_not_seeds(bench_folder, data_root, names, capsys):
    _seed_run(bench_folder, data_root, names, "1")
    (bench_folder / "seeds" / "README").write_text("x\n")
    (bench_folder / "seeds" / "\u00b3").mkdir()  # a superscript three: a digit to str.isdigit, not a seed
    code, result, err = evaluate(bench_folder, data_root, capsys, "--all-seeds")
    assert code == 0, err
    assert result["trackers"][0]["seeds"] == 2  # seeds 0 and 1 (the superscript was a traceback before)


# ------------------------------------------------------------------ sparse-pack ground truth
def test_a_hidden_copy_beside_a_sparse_pack_mat_is_not_a_second_ground_truth(tmp_path):
    from test_data import write_sparsepack

    from nrmlc.data import open_sequence
    from nrmlc.data.synthetic import synthetic_suite, write_otb_sequence

    [sequence] = synthetic_suite(n_frames=4, size=(48, 64), n_sequences=1)
    folder = write_otb_sequence(sequence, tmp_path / "Pack")
    (folder / "groundtruth_rect.txt").unlink()
    corners = np.array([[10.0, 10, 30, 30, 10], [5.0, 25, 25, 5, 5]])
    write_sparsepack(folder, 4, {1: corners}, size=(64, 48))
    expected = open_sequence(folder).groundtruth
    (folder / "._pack_gt.mat").write_bytes(b"\x00\x05\x16\x07 Mac OS X metadata")  # AppleDouble
    assert open_sequence(folder).groundtruth_path.name == "pack_gt.mat"
    (folder / "pack_gt.mat").rename(folder / "PACK_GT.MAT")
    found = open_sequence(folder)
    assert found.groundtruth_path.name == "PACK_GT.MAT"
    np.testing.assert_array_equal(found.groundtruth, expected)


# ------------------------------------------------------------------ outputs: all or none
def test_a_refused_speed_plot_writes_no_other_output(txt_folder, data_root, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "scores.csv").write_text("old\n")
    code, _, err = evaluate(txt_folder, data_root, capsys, "--csv", out / "scores.csv", "--plot", out / "p.png",
                            "--speed-plot", out / "speed.png")
    assert code == 2 and "--speed-plot" in err and "record their speed" in err, err
    assert sorted(p.name for p in out.iterdir()) == ["scores.csv"]
    assert (out / "scores.csv").read_text() == "old\n"


@pytest.mark.parametrize("failure", [KeyboardInterrupt, OSError])
def test_a_failure_while_writing_leaves_every_earlier_output(failure, bench_folder, data_root, tmp_path, capsys,
                                                              monkeypatch):
    import nrmlc.workbench.evaluate_cli as evaluate_cli

    out = tmp_path / "out"
    out.mkdir()
    (out / "scores.csv").write_text("old\n")

    def broken_plot(comparison, path):
        raise failure(28, "No space left on device")

    monkeypatch.setattr(evaluate_cli, "plot_comparison", broken_plot)
    code, _, err = evaluate(bench_folder, data_root, capsys, "--csv", out / "scores.csv", "--plot", out / "p.png",
                            "--speed-plot", out / "speed.png")
    assert code == (130 if failure is KeyboardInterrupt else 2), err
    assert sorted(p.name for p in out.iterdir()) == ["scores.csv"]  # no new plot, no temporary file
    assert (out / "scores.csv").read_text() == "old\n"


def test_outputs_are_written_together(bench_folder, data_root, tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = evaluate(bench_folder, data_root, capsys, "--csv", out / "scores.csv", "--plot", out / "p.png",
                            "--speed-plot", out / "speed.png", as_json=False)
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["p.png", "scores.csv", "speed.png"]
    with open(out / "scores.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert {r["sequence"] for r in rows} >= {TARGET, "ALL"}
    assert f"plots: {out / 'p.png'}" in err and f"speed plot: {out / 'speed.png'}" in err
