"""Keep numba's on-disk cache of the kernels consistent with their sources.

numba keys each cached function by the timestamp of *its own* source file only ("cache
invalidation fails to recognize changes in symbols defined in a different file", numba's
"Notes on Caching", caching limitations). ``coding.code_candidates`` calls the row
functions of ``distance``, so an edit to ``distance.py`` alone would leave it running its
stale machine code: another checkout, or a fresh clone, would then give other boxes for
the same seed. So the cached files of every kernel module are dropped together whenever
any kernel source, or :mod:`nrmlc.config` (the compilation flags), changes:
:func:`drop_stale_cache` runs when :mod:`nrmlc.kernels` is imported, before any kernel is
loaded.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

_KERNELS = Path(__file__).resolve().parent

#: The file in the cache folder that records which sources the cached kernels come from.
STAMP_NAME = "nrmlc-kernels.stamp"


def sources_digest(folder: Path = _KERNELS) -> str:
    """Hash of every kernel module and of ``nrmlc/config.py``."""
    digest = hashlib.sha256()
    for path in sorted(folder.glob("*.py")) + [folder.parent / "config.py"]:
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def cache_folder(folder: Path = _KERNELS) -> Path:
    """Where numba caches the kernels of ``folder``: ``__pycache__`` beside them, or the
    mirror of their path under ``$NUMBA_CACHE_DIR``."""
    custom = os.environ.get("NUMBA_CACHE_DIR", "")
    if custom:
        return Path(custom) / str(folder).lstrip(os.sep)
    return folder / "__pycache__"


def drop_stale_cache(folder: Path = _KERNELS, cache: Path | None = None) -> bool:
    """Delete the cached kernels of ``folder`` if their sources changed since they were
    cached; returns whether anything was dropped."""
    cache = cache_folder(folder) if cache is None else cache
    stamp = cache / STAMP_NAME
    digest = sources_digest(folder)
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass
    stems = {path.stem for path in folder.glob("*.py")}
    dropped = False
    for path in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")) if cache.is_dir() else []:
        if path.name.split(".", 1)[0] in stems:
            try:
                path.unlink()
                dropped = True
            except OSError:
                pass  # another process dropped it first
    try:
        cache.mkdir(parents=True, exist_ok=True)
        temporary = cache / f".{STAMP_NAME}.{os.getpid()}"
        temporary.write_text(digest)
        os.replace(temporary, stamp)
    except OSError:
        pass  # a read-only install: numba will not cache there either
    return dropped
