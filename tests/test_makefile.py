"""The Makefile's figures target passes NUMBA_TARGET on as numba's CPU target, and PORTABLE as the
AVX2 level for numba, OpenBLAS and numpy, each with caches of its own."""
import shutil
import subprocess
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
