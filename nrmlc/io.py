"""Atomic file writes: a reader never sees a half-written file.

Each writer creates a temporary file in the destination folder (same file
system, so ``os.replace`` is an atomic rename), flushes and fsyncs it, then
renames it over the target. An interrupted run leaves either the old file
or the new one, plus at worst a stray ``.tmp-*`` file that is ignored.
"""
from __future__ import annotations

import json
import os
import tempfile
import threading
from pathlib import Path
from typing import Any, Callable

import numpy as np

_umask_lock = threading.Lock()


def _current_umask() -> int:
    # os.umask can only be read by setting it; the lock keeps our own threads from racing.
    with _umask_lock:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def _atomic(path: str | os.PathLike, write: Callable[[Any], None], mode: str) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".tmp-{path.name}-", dir=path.parent)
    # mkstemp creates 0600 files; give results the usual umask-based permissions.
    os.chmod(tmp, 0o666 & ~_current_umask())
    try:
        with os.fdopen(fd, mode) as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def write_bytes(path: str | os.PathLike, data: bytes | bytearray | memoryview | np.ndarray) -> Path:
    """Write raw bytes to ``path`` atomically (a numpy array is written as its buffer)."""
    if isinstance(data, np.ndarray):
        data = np.ascontiguousarray(data).tobytes()
    return _atomic(path, lambda f: f.write(data), "wb")


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    return _atomic(path, lambda f: f.write(text), "w")


def write_json(path: str | os.PathLike, obj: Any) -> Path:
    """Write ``obj`` as indented JSON atomically (numpy scalars/arrays allowed)."""

    def default(o: Any) -> Any:
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, Path):
            return str(o)
        raise TypeError(f"not JSON serialisable: {type(o).__name__}")

    return write_text(path, json.dumps(obj, indent=2, default=default) + "\n")


def write_npz(path: str | os.PathLike, **arrays: np.ndarray) -> Path:
    """Save arrays to a compressed ``.npz`` atomically."""
    return _atomic(path, lambda f: np.savez_compressed(f, **arrays), "wb")


def write_boxes(path: str | os.PathLike, boxes: np.ndarray) -> Path:
    """Write an (n, 4) array of ``x,y,w,h`` boxes, one OTB line per frame."""
    boxes = np.asarray(boxes, dtype=np.float64)
    lines = [",".join(f"{v:.4f}".rstrip("0").rstrip(".") for v in row) for row in boxes]
    return write_text(path, "\n".join(lines) + "\n")
