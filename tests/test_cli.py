"""The command line on bad input: one ``error: ...`` line naming the file or
parameter, exit status 2, no traceback (unless ``--debug``); warnings for the
recoverable cases (short ground truth, initial box partly outside).

Most cases call :func:`nrmlc.cli.main` in-process (fast); a few run
``python -m nrmlc`` in a subprocess to see exactly what a user sees.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from nrmlc.cli import main
from nrmlc.data import synthetic_suite, write_otb_sequence

REPO_ROOT = Path(__file__).resolve().parent.parent
N_FRAMES = 8
#: Small and quick: every case that gets as far as tracking finishes in well under a second.
FAST = ["--particles", "20", "--param", "n_positive=10", "--param", "n_negative=20", "--param", "max_positive=20"]


@pytest.fixture(scope="module")
def base_folder(tmp_path_factory) -> Path:
    """An OTB folder: 8 synthetic 96x128 frames (PNG) + groundtruth_rect.txt."""
    sequence = synthetic_suite(n_frames=N_FRAMES, size=(96, 128), n_sequences=1)[0]
    return write_otb_sequence(sequence, tmp_path_factory.mktemp("cli") / "Seq")


@pytest.fixture
def seq(base_folder, tmp_path) -> Path:
    """A fresh copy of the base folder that a test may break."""
    return Path(shutil.copytree(base_folder, tmp_path / "Seq"))


def run_main(argv: list[str], capsys) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def subprocess_env() -> dict:
    # PYTHONPATH: import this checkout whatever the venv's install looks like.
    return dict(os.environ, PYTHONPATH=str(REPO_ROOT), PYTHONHASHSEED="0")


def run_cli(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "nrmlc", *map(str, argv)], cwd=cwd, env=subprocess_env(),
                          capture_output=True, text=True, timeout=120)


def set_gt_line(folder: Path, number: int, text: str) -> None:
    path = folder / "groundtruth_rect.txt"
    lines = path.read_text().splitlines()
    lines[number - 1] = text
    path.write_text("\n".join(lines) + "\n")


# --------------------------------------------------------------- the cases
# Each case: how to break the folder, extra arguments, and the text the error line must hold
# (the file, file:line or parameter it names). ``{seq}`` is the folder.
def _nothing(folder: Path) -> None:
    pass


def _empty_folder(folder: Path) -> None:
    shutil.rmtree(folder)
    folder.mkdir()


def _no_images(folder: Path) -> None:
    for file in (folder / "img").iterdir():
        file.unlink()
    (folder / "img" / "notes.txt").write_text("no frames here")


def _corrupt(name: str, data: bytes):
    def breaker(folder: Path) -> None:
        (folder / "img" / name).write_bytes(data)
    return breaker


def _truncated_jpeg(folder: Path) -> None:
    image = cv2.imread(str(folder / "img" / "0003.png"), cv2.IMREAD_UNCHANGED)
    ok, encoded = cv2.imencode(".jpg", image)
    assert ok
    (folder / "img" / "0003.png").unlink()
    data = encoded.tobytes()
    (folder / "img" / "0003.jpg").write_bytes(data[: len(data) // 2])


def _mixed_sizes(folder: Path) -> None:
    assert cv2.imwrite(str(folder / "img" / "0004.png"), np.zeros((50, 60), np.uint8))


def _gt(number: int, text: str):
    def breaker(folder: Path) -> None:
        set_gt_line(folder, number, text)
    return breaker


def _remove(name: str):
    def breaker(folder: Path) -> None:
        (folder / "img" / name).unlink()
    return breaker


def _copy(name: str, to: str):
    def breaker(folder: Path) -> None:
        shutil.copy(folder / "img" / name, folder / "img" / to)
    return breaker


def _link(name: str, target: str):
    def breaker(folder: Path) -> None:
        (folder / "img" / name).symlink_to(target)
    return breaker


def _all_frames(image: np.ndarray):
    def breaker(folder: Path) -> None:
        for file in (folder / "img").iterdir():
            assert cv2.imwrite(str(file), image)
    return breaker


def _gt_bytes(data: bytes):
    def breaker(folder: Path) -> None:
        (folder / "groundtruth_rect.txt").write_bytes(data)
    return breaker


def _truncate(name: str):
    def breaker(folder: Path) -> None:
        data = (folder / "img" / name).read_bytes()
        (folder / "img" / name).write_bytes(data[: len(data) // 2])
    return breaker


def _truncated_bmp(folder: Path) -> None:
    image = cv2.imread(str(folder / "img" / "0003.png"), cv2.IMREAD_UNCHANGED)
    (folder / "img" / "0003.png").unlink()
    ok, encoded = cv2.imencode(".bmp", image)
    assert ok
    (folder / "img" / "0003.bmp").write_bytes(encoded.tobytes()[:-500])


def _as_file(folder: Path) -> None:
    shutil.rmtree(folder)
    folder.write_text("not a folder")


BAD_INPUT = {
    # sequence folders and images
    "missing-folder": (_nothing, ["track", "{seq}-absent"], r"Seq-absent: sequence folder not found"),
    "empty-folder": (_empty_folder, [], r"Seq: no 'img' folder"),
    "no-images": (_no_images, [], r"img: no images"),
    "not-a-folder": (_as_file, [], r"Seq: not a folder"),
    "corrupt-first-image": (_corrupt("0001.png", b"\x89PNG\r\n\x1a\n garbage"), [], r"0001\.png: cannot read image"),
    "corrupt-later-image": (_corrupt("0005.png", b"garbage"), [], r"0005\.png: cannot read image"),
    "empty-image-file": (_corrupt("0002.png", b""), [], r"0002\.png: cannot read image \(empty file\)"),
    "truncated-jpeg": (_truncated_jpeg, [], r"0003\.jpg: cannot read image \(truncated JPEG"),
    "mixed-sizes": (_mixed_sizes, [], r"0004\.png: image is 50x60 \(HxW\) but frame 1 is 96x128"),
    # ground truth
    "gt-field-count": (_gt(3, "1,2,3"), [], r"groundtruth_rect\.txt:3: expected 4 numbers"),
    "gt-text": (_gt(2, "10,20,abc,30"), [], r"groundtruth_rect\.txt:2: not a number"),
    "gt-negative-size": (_gt(4, "10,20,-5,30"), [], r"groundtruth_rect\.txt:4: negative box size"),
    "gt-zero-width": (_gt(5, "10,20,0,30"), [], r"groundtruth_rect\.txt:5: zero box size"),
    "gt-infinite": (_gt(2, "10,20,inf,30"), [], r"groundtruth_rect\.txt:2: infinite value"),
    "gt-nan-first-line": (_gt(1, "NaN,20,30,30"), [], r"groundtruth_rect\.txt: frame 1 is not annotated"),
    "gt-unannotated-first-line": (_gt(1, "0,0,0,0"), [], r"groundtruth_rect\.txt: frame 1 is not annotated"),
    # initial box
    "init-box-outside": (_nothing, ["--init-box", "500,500,20,20"], r"initial box .* lies wholly outside the 128x96 frame"),
    "init-box-tiny": (_nothing, ["--init-box", "10,10,3,20"], r"initial box .* is smaller than 4 px"),
    "init-box-clipped-tiny": (_nothing, ["--init-box", "126,10,20,20"], r"initial box .* is smaller than 4 px"),
    "init-box-3-numbers": (_nothing, ["--init-box", "10,10,20"], r"--init-box: expected 4 numbers"),
    "init-box-nan": (_nothing, ["--init-box", "nan,10,20,20"], r"initial box must be 4 finite numbers"),
    # parameters
    "k-above-template-count": (_nothing, ["--param", "n_positive=2", "--param", "n_negative=3", "--param", "max_positive=2"],
                               r"parameter dictionary_sizes: k = 8 is larger than the template count 5"),
    "k-above-solver-limit": (_nothing, ["--param", "dictionary_sizes=5,8,40"], r"parameter dictionary_sizes: each k"),
    "negative-lambda": (_nothing, ["--lambda", "-1"], r"parameter lam: must be in \[0, 1e\+06\]"),
    "negative-beta": (_nothing, ["--beta", "-0.1"], r"parameter beta: must be in \[0, 1e\+06\]"),
    "negative-lambda-param": (_nothing, ["--param", "lam=-2"], r"parameter lam: must be in \[0, 1e\+06\]"),
    "zero-particles": (_nothing, ["--particles", "0"], r"parameter n_particles: must be (>= 1|in 1\.\.)"),
    "unknown-coding": (_nothing, ["--param", "coding=sparse"], r"parameter coding: unknown mode 'sparse'"),
    "param-no-equals": (_nothing, ["--param", "lam"], r"--param 'lam': expected name=value"),
    "param-unknown-name": (_nothing, ["--param", "lamda=1"], r"--param 'lamda=1': unknown parameter 'lamda'"),
    "param-not-a-number": (_nothing, ["--param", "lam=abc"], r"--param 'lam=abc': cannot read 'abc' as float"),
    "param-not-an-int": (_nothing, ["--param", "n_particles=1.5"], r"--param 'n_particles=1.5': cannot read"),
    "param-not-a-bool": (_nothing, ["--param", "occlusion_detection=maybe"], r"cannot read 'maybe' as bool"),
    "param-bad-tuple": (_nothing, ["--param", "dictionary_sizes=5,x"], r"--param 'dictionary_sizes=5,x': cannot read"),
    "param-nan": (_nothing, ["--param", "beta=nan"], r"parameter beta: must be a finite number"),
    "param-wrong-length": (_nothing, ["--param", "motion_sigmas=1,2"], r"parameter motion_sigmas: must be 6"),
    "zero-frames": (_nothing, ["--frames", "0"], r"--frames must be >= 1"),
    "zero-threads": (_nothing, ["--threads", "0"], r"threads must be >= 1"),
    "too-many-threads": (_nothing, ["--threads", "100000"], r"--threads 100000: at most \d+ here"),
    "negative-seed": (_nothing, ["--seed", "-1"], r"parameter seed: must be a non-negative integer"),
    # the other commands
    "evaluate-missing-results": (_nothing, ["evaluate", "--results", "{seq}/absent.txt", "--groundtruth",
                                            "{seq}/groundtruth_rect.txt"], r"absent\.txt: box file not found"),
    "evaluate-bad-groundtruth": (_gt(2, "1,2,3,4,5"), ["evaluate", "--results", "{seq}/groundtruth_rect.txt",
                                                       "--groundtruth", "{seq}/groundtruth_rect.txt"],
                                 r"groundtruth_rect\.txt:2: expected 4 numbers"),
    "list-missing-root": (_nothing, ["list", "{seq}/nowhere"], r"nowhere: data root not found"),
    # second round of the reliability checks
    "track-a-data-root": (_nothing, ["track", "{seq}/.."], r"no 'img' folder with the frames; it looks like a data "
                                                           r"root: give one sequence folder, e\.g\. \S*Seq"),
    "list-a-sequence": (_nothing, ["list", "{seq}"], r"Seq: no sequences .*; it is itself a sequence folder"),
    "truncated-png": (_truncate("0003.png"), [], r"0003\.png: cannot read image \(truncated PNG: no IEND chunk\)"),
    "truncated-bmp": (_truncated_bmp, [], r"0003\.bmp: cannot read image \(truncated BMP: \d+ of \d+ bytes\)"),
    "init-box-empty": (_nothing, ["--init-box="], r"--init-box: expected 4 numbers \(x,y,w,h\), got 0"),
    "particles-disagree": (_nothing, ["--particles", "40", "--param", "n_particles=30"],
                           r"--particles 40 and --param n_particles=30 disagree"),
    "frame-gap": (_remove("0004.png"), [], r"img: frame numbers jump from 0003\.png to 0005\.png \(frame 4 missing\)"),
    "frame-duplicate": (_copy("0003.png", "0003.jpg"), [], r"img: 0003\.(jpg|png) and 0003\.(jpg|png) have the same"),
    "frame-patterns": (_copy("0003.png", "thumb.png"), [], r"img: frame names follow different patterns"),
    "frame-dangling-link": (_link("0009.png", "gone.png"), [], r"0009\.png: broken symbolic link"),
    "frame-link-loop": (_link("0009.png", "0009.png"), [], r"0009\.png: symbolic link loop"),
    "frame-1x1": (_all_frames(np.zeros((1, 1), np.uint8)), [], r"0001\.png: image is 1x1 \(HxW\); frames must be"),
    "gt-underscores": (_gt(3, "1_3_2,20,30,30"), [], r"groundtruth_rect\.txt:3: not a number in '1_3_2,20,30,30'"),
    "gt-absurd": (_gt(3, "1e200,20,30,30"), [], r"groundtruth_rect\.txt:3: value beyond 1e\+09 px"),
    "gt-binary": (_gt_bytes(b"1,2,3,4\n\xff\xfe\xfa\n"), [], r"groundtruth_rect\.txt: not a text file"),
    "target-zero": (_nothing, ["--target", "0"], r"--target must be >= 1, got 0"),
    "video-extension": (_nothing, ["--video", "{seq}/../v.xyz"], r"--video .*v\.xyz: unknown video extension '\.xyz'"),
    "video-no-extension": (_nothing, ["--video", "{seq}/../video"], r"unknown video extension '\(none\)'"),
    "out-is-stdout": (_nothing, ["track", "{seq}", "--out", "-"], r"--out -: standard output is not supported"),
    "out-is-groundtruth": (_nothing, ["track", "{seq}", "--out", "{seq}/groundtruth_rect.txt"],
                           r"--out \S*groundtruth_rect\.txt: is an input of this run"),
    "synth-count-zero": (_nothing, ["synth", "--out", "{seq}/../synth", "--count", "0"], r"--count must be in 1\.\.1000, got 0"),
    "synth-count-negative": (_nothing, ["synth", "--out", "{seq}/../synth", "--count", "-3"], r"--count must be in 1\.\.1000, got -3"),
    "synth-seed-negative": (_nothing, ["synth", "--out", "{seq}/../synth", "--seed", "-1"], r"--seed must be in 0\.\."),
    "synth-one-frame": (_nothing, ["synth", "--out", "{seq}/../synth", "--frames", "1"], r"--frames must be in 2\.\."),
    "synth-out-is-a-file": (_nothing, ["synth", "--out", "{seq}/groundtruth_rect.txt"], r"is a file, not a folder"),
    "evaluate-absurd-groundtruth": (_gt(3, "1e200,1e200,1e200,1e200"), ["evaluate", "--results", "{seq}/groundtruth_rect.txt",
                                                                       "--groundtruth", "{seq}/groundtruth_rect.txt"],
                                    r"groundtruth_rect\.txt:3: value beyond"),
}


def case_argv(args: list[str], seq: Path, out: Path) -> list[str]:
    args = [a.replace("{seq}", str(seq)) for a in args]
    if args and args[0] in ("track", "evaluate", "list", "synth"):
        if args[0] != "track" or "--out" in args:
            return args if args[0] != "track" else [*args, *FAST]
        return [*args, "--out", str(out), *FAST]
    return ["track", str(seq), "--out", str(out), *FAST, *args]


@pytest.mark.filterwarnings("ignore:initial box .* is partly outside:UserWarning")
@pytest.mark.parametrize("name", list(BAD_INPUT))
def test_bad_input_is_one_error_line(name, seq, tmp_path, capsys):
    breaker, args, expected = BAD_INPUT[name]
    breaker(seq)
    out_file = tmp_path / "result.txt"
    out_file.write_text("previous result\n")
    code, _, err = run_main(case_argv(args, seq, out_file), capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert re.search(expected, lines[0]), lines[0]
    assert "Traceback" not in err
    # A failed run never replaces (or truncates) an earlier result.
    assert out_file.read_text() == "previous result\n"


def test_unknown_coding_choice_is_a_usage_error(seq, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["track", str(seq), "--out", str(tmp_path / "r.txt"), "--coding", "sparse"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "argument --coding: invalid choice: 'sparse'" in err and "Traceback" not in err


def test_debug_raises_instead(seq, tmp_path):
    from nrmlc.errors import DataError, ParameterError

    with pytest.raises(DataError, match="sequence folder not found"):
        main(["--debug", "track", f"{seq}-absent", "--out", str(tmp_path / "r.txt")])
    with pytest.raises(ParameterError, match="parameter lam"):  # --debug also accepted after the command
        main(["track", str(seq), "--out", str(tmp_path / "r.txt"), "--lambda", "-1", "--debug"])


def test_main_restores_warning_format(seq, tmp_path, capsys):
    import warnings

    before = warnings.formatwarning
    run_main(["track", f"{seq}-absent", "--out", tmp_path / "r.txt"], capsys)
    assert warnings.formatwarning is before


# ------------------------------------------------ recoverable: warn and go on
def test_short_groundtruth_warns_and_evaluates_annotated_frames(seq, tmp_path, capsys):
    path = seq / "groundtruth_rect.txt"
    path.write_text("".join(path.read_text().splitlines(keepends=True)[:5]))
    out_file = tmp_path / "r.txt"
    with pytest.warns(UserWarning, match=r"groundtruth_rect\.txt: 5 ground-truth boxes for 8 frames"):
        code, _, err = run_main(["track", seq, "--out", out_file, *FAST], capsys)
    assert code == 0
    assert "mean overlap" in err  # frames 2..5 were scored
    assert len(out_file.read_text().splitlines()) == N_FRAMES
    with pytest.warns(UserWarning, match=r"5 ground-truth boxes for 8 result boxes; only the first 5"):
        code, out, _ = run_main(["evaluate", "--results", out_file, "--groundtruth", path, "--json"], capsys)
    assert code == 0 and '"n_frames": 4' in out  # frames 2..5 (frame 1 is the given box)


@pytest.mark.filterwarnings("ignore:initial box .* is partly outside:UserWarning")
@pytest.mark.parametrize("form", [["--init-box", "-4,-2,20,20"], ["--init-box=-4,-2,20,20"]], ids=["space", "equals"])
def test_negative_initial_box_needs_no_equals_sign(form, seq, tmp_path, capsys):
    out_file = tmp_path / "r.txt"
    code, _, err = run_main(["track", seq, "--out", out_file, *form, "--frames", "2", *FAST], capsys)
    assert code == 0, err
    assert out_file.read_text().splitlines()[0] == "1,1,15,17"


def test_synth_writes_what_list_reads(tmp_path, capsys):
    code, out, err = run_main(["synth", "--out", tmp_path / "s", "--frames", "3", "--count", "2", "--seed", "4"], capsys)
    assert code == 0, err
    assert len(out.splitlines()) == 2
    code, out, err = run_main(["list", tmp_path / "s"], capsys)
    assert code == 0 and "synth-01" in out and "synth-02" in out, err


def test_short_results_warn_that_the_rest_are_failures(seq, tmp_path, capsys):
    out_file = tmp_path / "r.txt"
    assert run_main(["track", seq, "--out", out_file, "--frames", "3", *FAST], capsys)[0] == 0
    with pytest.warns(UserWarning, match=r"r\.txt: 3 result boxes for 8 ground-truth boxes; the annotated frames "
                                         r"after frame 3 count as failures"):
        code, out, _ = run_main(["evaluate", "--results", out_file, "--groundtruth", seq / "groundtruth_rect.txt",
                                 "--json"], capsys)
    assert code == 0 and '"n_missing": 5' in out


def test_initial_box_partly_outside_is_clipped(seq, tmp_path, capsys):
    out_file = tmp_path / "r.txt"
    with pytest.warns(UserWarning, match=r"partly outside the 128x96 frame; clipped to \[1\.0, 1\.0, 15\.0, 17\.0\]"):
        code, _, _ = run_main(["track", seq, "--out", out_file, "--init-box=-4,-2,20,20", "--frames", "2", *FAST],
                              capsys)
    assert code == 0
    first = [float(v) for v in out_file.read_text().splitlines()[0].split(",")]
    assert first == [1.0, 1.0, 15.0, 17.0]


# ------------------------------------------------ what a user sees (subprocess)
def test_subprocess_error_line_and_debug_traceback(seq, tmp_path):
    (seq / "img" / "0004.png").write_bytes(b"not a png")
    args = ["track", seq, "--out", tmp_path / "r.txt", *FAST]
    plain = run_cli(args, tmp_path)
    assert plain.returncode == 2
    assert "Traceback" not in plain.stderr
    # The last line is ours; libpng may print its own complaint before it.
    assert re.fullmatch(r"error: \S*0004\.png: cannot read image \(.*\)", plain.stderr.strip().splitlines()[-1])
    debug = run_cli(["--debug", "track", f"{seq}-absent", "--out", tmp_path / "r.txt"], tmp_path)
    assert debug.returncode != 0
    assert "Traceback" in debug.stderr and "nrmlc.errors.DataError: " in debug.stderr


def test_subprocess_truncated_png_is_our_line_only(seq, tmp_path):
    data = (seq / "img" / "0004.png").read_bytes()
    (seq / "img" / "0004.png").write_bytes(data[: len(data) // 2])
    result = run_cli(["track", seq, "--out", tmp_path / "r.txt", *FAST], tmp_path)
    assert result.returncode == 2
    # Nothing from libpng or OpenCV: refused before decoding.
    assert result.stderr.strip().splitlines() == [
        f"error: {seq / 'img' / '0004.png'}: cannot read image (truncated PNG: no IEND chunk)"]


def test_subprocess_warnings_are_one_line_each(seq, tmp_path):
    path = seq / "groundtruth_rect.txt"
    path.write_text("".join(path.read_text().splitlines(keepends=True)[:6]))
    result = run_cli(["track", seq, "--out", tmp_path / "r.txt", "--init-box", "120,40,20,20", "--frames", "3", *FAST],
                     tmp_path)
    assert result.returncode == 0, result.stderr
    warnings = [line for line in result.stderr.splitlines() if line.startswith("warning: ")]
    assert len(warnings) == 2, result.stderr
    assert "6 ground-truth boxes for 8 frames" in warnings[0]
    assert "partly outside the 128x96 frame; clipped to [120.0, 40.0, 9.0, 20.0]" in warnings[1]
    assert "Traceback" not in result.stderr and "UserWarning" not in result.stderr


def test_track_preset_paper_changes_the_parameters_and_options_still_apply(seq, tmp_path, capsys, monkeypatch):
    import nrmlc.tracker.loop as run

    seen = []
    real = run.track_sequence

    def spy(sequence, params=None, **kwargs):
        seen.append(params)
        return real(sequence, params, **kwargs)

    monkeypatch.setattr(run, "track_sequence", spy)
    out = tmp_path / "r.txt"
    code, _, err = run_main(["track", str(seq), "--out", str(out), "--frames", "3", "--particles", "40",
                             "--preset", "paper"], capsys)
    assert code == 0, err
    assert seen[-1].template_sampling == "annulus" and seen[-1].alpha == 2.5 and seen[-1].n_particles == 40
    with pytest.raises(SystemExit) as stop:
        main(["track", str(seq), "--out", str(out), "--preset", "nope"])
    assert stop.value.code == 2 and "argument --preset: invalid choice: 'nope'" in capsys.readouterr().err


def test_the_usage_line_names_the_command_as_invoked(tmp_path):
    script = Path(sys.executable).parent / "nrmlc"
    if not script.exists():
        pytest.skip("the nrmlc script is not installed beside this Python")
    for command, name in (([str(script)], "usage: nrmlc "), ([sys.executable, "-m", "nrmlc"], "usage: python -m nrmlc ")):
        done = subprocess.run(command + ["track"], capture_output=True, text=True, cwd=tmp_path)
        assert done.returncode == 2 and done.stderr.startswith(name), done.stderr
