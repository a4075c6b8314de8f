"""What a stored run was computed with: the version of the sources that decide its boxes, the
numba target the kernels were compiled for, and the library settings that move SIMD levels.

:func:`code_version` is part of every run's cache key (:mod:`nrmlc.workbench.run_cache`); the
numba target and the library settings are stored beside each run for the record, since runs
can differ between targets (docs/RELIABILITY.md#determinism) but the key does not hold them.
"""
from __future__ import annotations

import ast
import functools
import hashlib
import io as text_io
import os
import tokenize
from pathlib import Path

#: Sources whose change can change a run's boxes. ``data`` is included because it
#: decodes and converts the frames (and renders the synthetic ones) and reads the
#: initial box: a change there changes what the tracker sees.
_RESULT_SOURCES = ("geometry.py", "config.py", "data", "kernels", "tracker")

# The variables that move OpenBLAS's, numpy's and OpenCV's IPP kernels off the host's best SIMD
# level (`make figures PORTABLE=1`); they can change the boxes as the numba target can (IPP only
# the peers' and the synthetic suite's drawing, whose integer pixels the tests pin).
LIBRARY_VARIABLES = ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES", "OPENCV_IPP")


def code_version() -> str:
    """Hash of every source file that can change a tracking result, as :func:`executable_text`
    gives it: a comment or docstring edited leaves the version, and the run cache, as they were."""
    root = Path(__file__).resolve().parents[1]  # the nrmlc package: file names are hashed relative to it
    digest = hashlib.sha256()
    for name in _RESULT_SOURCES:
        path = root / name
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for file in files:
            digest.update(str(file.relative_to(root)).encode())
            digest.update(executable_text(file.read_bytes().decode("utf-8")).encode())
    return digest.hexdigest()[:16]


@functools.lru_cache(maxsize=256)
def executable_text(source: str) -> str:
    """``source`` (a Python module) without its comments, its string statements (docstrings) and
    its blank lines, and each line without trailing blanks: what of a file can change a run.

    Where the spans cut come from the parser and the tokenizer, which agree on them across Python
    versions (the text kept is the source's own, never a dump of the tree). Memoised on the text:
    :func:`code_version` reads the files every time (an edit is seen) but parses each text once,
    where a process makes several run caches (a grid, the tests)."""
    lines = source.splitlines()

    def position(line: int, offset: int) -> tuple[int, int]:
        """(line, column in characters) of the parser's (line, offset in UTF-8 bytes)."""
        return line, len(lines[line - 1].encode("utf-8")[:offset].decode("utf-8"))

    spans = [(position(node.lineno, node.col_offset), position(node.end_lineno, node.end_col_offset))
             for node in ast.walk(ast.parse(source))
             if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
             and isinstance(node.value.value, str)]
    spans += [(token.start, token.end) for token in tokenize.generate_tokens(text_io.StringIO(source).readline)
              if token.type == tokenize.COMMENT]
    for (first, start), (last, end) in sorted(spans, reverse=True):  # from the end: earlier spans stay put
        lines[first - 1:last] = [lines[first - 1][:start] + lines[last - 1][end:]]
    return "\n".join(line.rstrip() for line in lines if line.strip())


@functools.cache
def numba_target() -> str:
    """The CPU numba compiles the kernels for in this process: ``NUMBA_CPU_NAME`` or the host's,
    and which features (``NUMBA_CPU_FEATURES``, or the host's). Runs can differ between targets
    (docs/RELIABILITY.md#determinism), and the cache key does not hold it: it is stored beside
    each run and checked when runs are read (:meth:`nrmlc.workbench.run_cache.RunCache.run`).
    Fixed for the process (numba reads the variables once), so it is worked out once."""
    import numba
    from llvmlite import binding

    name = numba.config.CPU_NAME or binding.get_host_cpu_name()
    features = numba.config.CPU_FEATURES
    return f"{name} ({'host features' if features is None else 'features: ' + (features or 'none')})"


def library_settings() -> dict:
    """{variable: value} of :data:`LIBRARY_VARIABLES` set in this process, recorded beside each
    stored run (``library_settings``) for the record only: reading runs does not compare them."""
    return {name: os.environ[name] for name in LIBRARY_VARIABLES if name in os.environ}
