"""The Makefile's figures target passes NUMBA_TARGET on as numba's CPU target, and PORTABLE as the
AVX2 level for numba, OpenBLAS and numpy, each with caches of its own; its set-up installs the
package as a static path entry (quietly: no setuptools deprecation warning); what the README's
examples write in the clone is git-ignored."""
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _dry_run(*settings: str) -> str:
    """The figures recipe as ``make -n`` prints it, its continuation lines joined."""
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    out = subprocess.run(["make", "-n", "-C", str(ROOT), "figures", "DATA=somewhere", *settings],
                         capture_output=True, text=True, check=True).stdout
    return " ".join(out.replace("\\\n", " ").split())


def test_numba_target_sets_the_cpu_its_feature_defaults_and_caches_of_its_own():
    recipe = _dry_run("NUMBA_TARGET=znver4")
    assert ("NUMBA_CPU_NAME=znver4 NUMBA_CPU_FEATURES= NUMBA_CACHE_DIR=.cache/numba-znver4 "
            in recipe)
    assert "-m experiments.run_all --cache .cache/runs-znver4 --data \"somewhere\"" in recipe


def test_without_it_numba_compiles_for_the_host_into_the_usual_caches():
    recipe = _dry_run()
    assert "NUMBA_CPU_NAME" not in recipe and "--cache" not in recipe
    assert "-m experiments.run_all --data \"somewhere\"" in recipe


def test_portable_holds_numba_openblas_numpy_and_ipp_at_the_avx2_level_with_caches_of_its_own():
    recipe = _dry_run("PORTABLE=1")
    assert ('OPENBLAS_CORETYPE=Haswell NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" OPENCV_IPP=avx2 '
            "NUMBA_CPU_NAME=haswell NUMBA_CPU_FEATURES= NUMBA_CACHE_DIR=.cache/numba-portable " in recipe)
    assert "-m experiments.run_all --cache .cache/runs-portable --data \"somewhere\"" in recipe


def test_the_install_is_a_static_path_entry_without_the_deprecated_compat_mode():
    makefile = (ROOT / "Makefile").read_text()
    assert "pip install --quiet --no-deps -e ." in makefile
    assert "editable_mode" not in makefile  # 'compat' warns on every install
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    # what makes setuptools write a .pth of this folder instead of its import hook
    assert setuptools["package-dir"] == {"": "."}


def _found_from(folder: Path) -> str:
    """Where ``import nrmlc`` finds the package from ``folder``, by the install alone (no PYTHONPATH)."""
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    code = "import importlib.util; spec = importlib.util.find_spec('nrmlc'); print(spec and spec.origin)"
    return subprocess.run([sys.executable, "-c", code], cwd=folder, env=env, capture_output=True, text=True,
                          check=True).stdout.strip()


def test_import_nrmlc_from_a_folder_holding_a_clone_named_nrmlc(tmp_path):
    package = str(ROOT / "nrmlc" / "__init__.py")
    (tmp_path / "elsewhere").mkdir()
    if _found_from(tmp_path / "elsewhere") != package:
        pytest.skip("nrmlc is not installed from this checkout")
    (tmp_path / "nrmlc").mkdir()  # a clone: a folder named nrmlc, no __init__.py at its top
    (tmp_path / "nrmlc" / "README.md").write_text("a clone\n")
    assert _found_from(tmp_path) == package


#: What the README's examples write in the current folder, the clone.
README_OUTPUTS = ("data/synth-01/groundtruth_rect.txt", "results/NRMLC/synth-01.txt", "cache/runs/x.npz", "plot.png",
                  "synth-01.txt")


@pytest.mark.parametrize("path", README_OUTPUTS)
def test_what_the_readme_examples_write_is_ignored(path):
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    assert subprocess.run(["git", "-C", str(ROOT), "check-ignore", "-q", path]).returncode == 0


def test_the_package_of_the_same_names_is_not_ignored():
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    for path in ("nrmlc/data/__init__.py", "tests/data/x.txt", "experiments/results/x.txt"):
        assert subprocess.run(["git", "-C", str(ROOT), "check-ignore", "-q", path]).returncode == 1, path
