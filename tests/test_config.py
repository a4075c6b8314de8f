"""nrmlc.config: the thread policy holds whatever is imported or called first, and
every compiled function takes its numba flags from the config module."""
from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent

# Runs FIRST, then a parallel kernel, then asks libgomp (through numba's OpenMP
# pool library) for the spin count it actually uses: 0 means passive waiting.
_POLICY_CHILD = r"""
import ctypes, sys
exec(sys.argv[1])
import numpy as np
from nrmlc.config import set_threads
set_threads(2)
from nrmlc.kernels.warp import warp_patches
warp_patches(np.ones((40, 40), np.float32), np.tile([[1.0, 0, 20], [0, 1, 20]], (8, 1, 1)))
import numba
print(numba.threading_layer(), flush=True)
if numba.threading_layer() == "omp":
    from numba.np.ufunc import omppool
    ctypes.CDLL(omppool.__file__).omp_display_env(1)
"""


def _spin_count(first: str, **env) -> tuple[str, int | None, str]:
    """(threading layer, libgomp's GOMP_SPINCOUNT or None, stderr) after running ``first``."""
    environment = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    environment.update(env)
    output = subprocess.run([sys.executable, "-c", _POLICY_CHILD, first], cwd=str(REPO_ROOT), env=environment,
                            capture_output=True, text=True, timeout=300)
    assert output.returncode == 0, output.stderr
    layer = output.stdout.split()[-1]
    match = re.search(r"GOMP_SPINCOUNT = '(\d+)'", output.stderr)
    return layer, (int(match.group(1)) if match else None), output.stderr


FIRST_STEPS = {
    "set_threads before any other import": "from nrmlc.config import set_threads; set_threads(2)",
    "set_threads(1) before any other import": "import nrmlc.config as c; c.set_threads(1)",
    "the tracker first": "from nrmlc import NRMLCTracker",
    "a kernel module first": "import nrmlc.kernels.warp",
    "the data layer first": "import nrmlc.data",
    "numba imported before nrmlc": "import numba",
    "nothing": "pass",
}


@pytest.mark.parametrize("first", list(FIRST_STEPS.values()), ids=list(FIRST_STEPS))
def test_openmp_workers_wait_passively_whatever_comes_first(first):
    layer, spin_count, stderr = _spin_count(first)
    if layer != "omp":
        pytest.skip(f"numba threading layer is {layer}, not OpenMP")
    assert spin_count == 0, stderr


def test_a_user_set_wait_policy_wins():
    layer, spin_count, stderr = _spin_count("pass", OMP_WAIT_POLICY="ACTIVE")
    if layer != "omp":
        pytest.skip(f"numba threading layer is {layer}, not OpenMP")
    assert spin_count is not None and spin_count > 0, stderr


def test_a_pool_started_before_nrmlc_cannot_wait_passively_and_says_so():
    # The one case the policy cannot reach: numba's pool started before nrmlc was imported.
    layer, spin_count, stderr = _spin_count("import numba; numba.set_num_threads(1)")
    if layer != "omp":
        pytest.skip(f"numba threading layer is {layer}, not OpenMP")
    assert spin_count is not None and spin_count > 0
    assert "RuntimeWarning" in stderr and "OMP_WAIT_POLICY=PASSIVE" in stderr


def _decorator_name(node: ast.expr) -> str:
    target = node.func if isinstance(node, ast.Call) else node
    return target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")


def test_every_compiled_function_takes_its_flags_from_config():
    compilers = {"njit", "jit", "vectorize", "guvectorize", "stencil", "cfunc", "generated_jit"}
    found = 0
    for path in sorted((REPO_ROOT / "nrmlc").rglob("*.py")):
        tree = ast.parse(path.read_text(), filename=str(path))
        imported = {alias.asname or alias.name for node in ast.walk(tree)
                    if isinstance(node, ast.ImportFrom) and node.module == "nrmlc.config" for alias in node.names}
        for node in ast.walk(tree):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for decorator in node.decorator_list:
                if _decorator_name(decorator) not in compilers:
                    continue
                found += 1
                where = f"{path.relative_to(REPO_ROOT)}:{node.lineno} {node.name}"
                assert isinstance(decorator, ast.Call), f"{where}: bare decorator, no flags from nrmlc.config"
                assert not decorator.args, f"{where}: positional arguments (a signature?) beside the config flags"
                assert len(decorator.keywords) == 1 and decorator.keywords[0].arg is None, (
                    f"{where}: flags must be exactly **NUMBA_FLAGS or **PARALLEL_FLAGS")
                flags = decorator.keywords[0].value
                if isinstance(flags, ast.Name) and flags.id == "EXACT_PARALLEL_FLAGS":
                    continue  # config's parallel flags without fastmath: checked below
                assert isinstance(flags, ast.Name) and flags.id in {"NUMBA_FLAGS", "PARALLEL_FLAGS"}, where
                assert flags.id in imported, f"{where}: {flags.id} not imported from nrmlc.config"
    assert found >= 8  # the kernels exist: a test that finds nothing would pass vacuously
    from nrmlc.config import PARALLEL_FLAGS
    from nrmlc.lineage.affine import EXACT_PARALLEL_FLAGS

    assert EXACT_PARALLEL_FLAGS == {**PARALLEL_FLAGS, "fastmath": False}
