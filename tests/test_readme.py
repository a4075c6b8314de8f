"""The README's console examples run as written and print what the README shows.

Every ```console block of README.md is run in order, in one fresh temporary folder, with the
repository's ``.venv/bin`` first on PATH (so ``nrmlc`` is this checkout's) and the run cache inside
that folder. Each ``$ `` line is a command; the lines after it, up to the next command, are what it
prints (standard output and standard error together). Timing fields (fps, frames/s, minutes,
seconds, and the fps column of a table) are normalised before the comparison; everything else,
boxes and scores included, must match exactly (up to runs of spaces, which column widths move).
The ```python block runs too, on a sequence written where it expects one.

The commands run at the portable CPU level that ``figures/`` is made with (``make figures
PORTABLE=1``: numba's haswell target, OpenBLAS's Haswell kernels, numpy without AVX-512, OpenCV's
IPP at AVX2; docs/RELIABILITY.md#determinism), so that the printed boxes and scores are the same
on every x86-64 CPU with AVX2 and FMA, with or without AVX-512.

To refresh the README's outputs after a change of the CLI: ``python tests/test_readme.py --update``.
"""
from __future__ import annotations

import argparse
import os
import re
import shlex
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
BIN = ROOT / ".venv" / "bin"
DEMO = "/tmp/nrmlc-demo"  # where the README's Python example reads its sequence

TIMING = re.compile(r"\b\d+(?:\.\d+)?(?= ?(?:fps|frames/s|min|s)\b)")
NUMBER = re.compile(r"^-?\d+(?:\.\d+)?$")
COMPILING = re.compile(r"^\[nrmlc\] (compiling the numba kernels|kernels compiled in)")


def console_blocks(text: str) -> list[list[tuple[str, list[str]]]]:
    """Each ```console block as [(command, expected output lines), ...]."""
    blocks, current, inside = [], None, False
    for line in text.splitlines():
        if line.strip() == "```console":
            inside, current = True, []
        elif inside and line.strip() == "```":
            inside = False
            blocks.append(current)
        elif inside:
            if line.startswith("$ "):
                current.append((line[2:], []))
            elif current:
                current[-1][1].append(line)
    return blocks


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def normalise(lines: list[str]) -> list[str]:
    """Collapse runs of spaces; replace timing fields (and the fps column of tables) by <t>."""
    out, fps_table = [], False
    for line in lines:
        tokens = line.split()
        if not tokens:
            fps_table = False
            out.append("")
            continue
        if tokens[-1] == "fps":
            fps_table = True
        elif fps_table and NUMBER.match(tokens[-1]):
            tokens[-1] = "<t>"
        out.append(TIMING.sub("<t>", " ".join(tokens)))
    while out and out[-1] == "":
        out.pop()
    return out


def portable_env() -> dict[str, str]:
    """The environment ``make figures PORTABLE=1`` runs in, read from the Makefile (its
    ``LIBRARY_ENV``, ``NUMBA_TARGET`` and ``TARGET_NAME`` under PORTABLE)."""
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    portable = makefile.split("ifneq ($(PORTABLE),)", 1)[1].split("else", 1)[0]
    value = {name: re.search(rf"^{name}\s*:=\s*(.+)$", portable, flags=re.M).group(1).strip()
             for name in ("NUMBA_TARGET", "LIBRARY_ENV", "TARGET_NAME")}
    env = dict(item.split("=", 1) for item in shlex.split(value["LIBRARY_ENV"]))
    return {**env, "NUMBA_CPU_NAME": value["NUMBA_TARGET"], "NUMBA_CPU_FEATURES": "",
            "NUMBA_CACHE_DIR": str(ROOT / ".cache" / f"numba-{value['TARGET_NAME']}")}


def run_command(command: str, cwd: Path, bin_dir: Path) -> list[str]:
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
               PYTHONHASHSEED="0", PYTHONUNBUFFERED="1", COLUMNS="100", **portable_env())
    result = subprocess.run(["bash", "-c", command], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, timeout=900)
    # Whether the kernels were compiled before (the portable target's cache is its own) is not
    # the example's business.
    return [line for line in result.stdout.rstrip("\n").splitlines() if not COMPILING.match(line)]


def run_readme(bin_dir: Path, workdir: Path) -> list[tuple[str, list[str], list[str]]]:
    """(command, expected, printed) for every command of every console block, in order."""
    runs = []
    for block in console_blocks(README.read_text(encoding="utf-8")):
        for command, expected in block:
            runs.append((command, expected, run_command(command, workdir, bin_dir)))
    return runs


def run_python_examples(bin_dir: Path, workdir: Path) -> None:
    demo = workdir / "nrmlc-demo"
    subprocess.run([str(bin_dir / "nrmlc"), "synth", "--out", str(demo), "--frames", "40", "--count", "1"],
                   cwd=workdir, check=True, capture_output=True)
    for code in python_blocks(README.read_text(encoding="utf-8")):
        result = subprocess.run([str(bin_dir / "python"), "-c", code.replace(DEMO, str(demo))], cwd=workdir,
                                capture_output=True, text=True, timeout=900)
        assert result.returncode == 0, f"the README's Python example failed:\n{result.stderr}"


def test_console_examples_print_what_the_readme_shows(tmp_path):
    mismatches = []
    for command, expected, printed in run_readme(BIN, tmp_path):
        if normalise(expected) != normalise(printed):
            mismatches.append(f"$ {command}\n--- README\n" + "\n".join(expected) + "\n--- printed\n" + "\n".join(printed))
    assert not mismatches, "refresh with `python tests/test_readme.py --update`:\n\n" + "\n\n".join(mismatches)


def test_python_example_runs_from_any_folder(tmp_path):
    run_python_examples(BIN, tmp_path)


def test_readme_is_short_and_has_no_history():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200
    assert not re.search(r"round [0-9]", text, flags=re.I)


def test_the_library_tells_no_history():
    """No docstring or comment of the package cites a development round (the record does)."""
    package = README.parent / "nrmlc"
    cited = [f"{path.relative_to(package.parent)}:{number}" for path in sorted(package.rglob("*.py"))
             for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if re.search(r"round [0-9]", line, flags=re.I)]
    assert not cited, cited


def update(bin_dir: Path) -> None:
    """Rewrite every console block's outputs with what its commands print now."""
    with tempfile.TemporaryDirectory() as folder:
        runs = iter(run_readme(bin_dir, Path(folder)))
        lines, out, inside = README.read_text(encoding="utf-8").splitlines(), [], False
        for line in lines:
            if line.strip() == "```console":
                inside = True
                out.append(line)
            elif inside and line.strip() == "```":
                inside = False
                out.append(line)
            elif inside:
                if line.startswith("$ "):
                    command, _, printed = next(runs)
                    out.append(f"$ {command}")
                    out.extend(printed)
            else:
                out.append(line)
        README.write_text("\n".join(out) + "\n", encoding="utf-8")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="refresh the README's console outputs")
    parser.add_argument("--update", action="store_true", required=True)
    parser.add_argument("--bin", type=Path, default=BIN, help="folder whose nrmlc runs the examples")
    update(parser.parse_args().bin)
