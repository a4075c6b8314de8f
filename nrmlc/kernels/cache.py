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
    """Where numba caches the kernels of ``folder``: ``__pycache__`` beside them, or, under
    ``$NUMBA_CACHE_DIR``, the sub-folder numba derives from their path (``kernels_<sha1 of the
    folder>`` since numba 0.5x; it was once the mirror of the path, which is kept as a fallback
    where numba does not say)."""
    custom = os.environ.get("NUMBA_CACHE_DIR", "")
    if custom:
        try:
            from numba.core.caching import _CacheLocator

            return Path(custom) / _CacheLocator.get_suitable_cache_subpath(str(folder / "coding.py"))
        except (ImportError, AttributeError):
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
        try:
            temporary.write_text(digest)
            os.replace(temporary, stamp)
        finally:
            if temporary.exists():  # a failed write or an interrupt: no stray file
                temporary.unlink()
    except OSError:
        pass  # a read-only install: numba will not cache there either
    return dropped


# ------------------------------------------------------ a cache that never stops the tool
_warned: set[str] = set()


def _warn_once(kind: str, message: str) -> None:
    import warnings

    if kind not in _warned:
        _warned.add(kind)
        warnings.warn(message, stacklevel=3)


def cache_location_available(folder: Path = _KERNELS) -> bool:
    """Whether numba can cache the kernels of ``folder`` anywhere (``$NUMBA_CACHE_DIR``, the
    ``__pycache__`` beside them, or the user's cache folder): numba's own locators, asked
    as it will ask them. Without one, ``cache=True`` fails at import."""
    try:
        from numba.core import caching

        locators = getattr(caching, "CacheImpl", None) or caching._CacheImpl
        locators = locators._locator_classes
    except (ImportError, AttributeError):  # another numba: let it decide for itself
        return True

    def probe():  # any function: the locators only read its first line number
        pass

    source = str(folder / "coding.py")
    for locator in locators:
        try:
            if locator.from_function(probe, source) is not None:
                return True
        except Exception:  # a locator that cannot even look counts as none
            continue
    return False


def make_cache_robust(folder: Path = _KERNELS) -> None:
    """Make numba's on-disk cache of the kernels optional, never a reason to stop.

    - No place to cache (a read-only install with a read-only home and no
      ``$NUMBA_CACHE_DIR``): the kernels compile in memory (``cache=False``),
      with one warning. The flag changes no compiled code.
    - A cache file that cannot be read back (a truncated ``.nbc`` or ``.nbi``,
      an ``UnpicklingError``, ``EOFError``, anything its rebuild raises): its
      index is removed and the function is compiled again (and cached anew),
      with one warning; saving that fails (a full disk, lost permissions) only
      warns. numba's own loader raises in those cases (0.68).

    Called by :mod:`nrmlc.kernels` before any kernel module is imported.
    """
    from nrmlc import config

    if not cache_location_available(folder):
        for flags in (config.NUMBA_FLAGS, config.PARALLEL_FLAGS):
            flags["cache"] = False
        _warn_once("no-location", f"numba cannot cache the kernels (neither {cache_folder(folder)} nor the user's "
                                  f"cache folder is writable; set NUMBA_CACHE_DIR to a folder of your own): "
                                  f"they are compiled in every process, about 20-60 s")
    try:
        from numba.core import caching
    except ImportError:
        return
    cache_class = caching.Cache
    if getattr(cache_class.load_overload, "_nrmlc_robust", False):
        return
    load, save = cache_class.load_overload, cache_class.save_overload

    def load_overload(self, sig, target_context):
        try:
            return load(self, sig, target_context)
        except Exception as exc:
            index = getattr(getattr(self, "_cache_file", None), "_index_path", None)
            if index:
                try:
                    os.unlink(index)  # the index names the data files: without it they are unused, then replaced
                except OSError:
                    pass
            _warn_once("damaged", f"numba's cache in {getattr(self, '_cache_path', '?')} is damaged "
                                  f"({type(exc).__name__}: {exc}); compiling the kernels again")
            return None

    def save_overload(self, sig, data):
        try:
            return save(self, sig, data)
        except Exception as exc:
            _warn_once("unwritable", f"cannot write numba's cache in {getattr(self, '_cache_path', '?')} "
                                     f"({type(exc).__name__}: {exc}); the compiled kernels are kept in memory only")

    load_overload._nrmlc_robust = True
    cache_class.load_overload, cache_class.save_overload = load_overload, save_overload
