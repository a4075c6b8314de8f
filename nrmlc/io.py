"""Atomic file writes: a reader never sees a half-written file.

Each writer creates a temporary file with a unique name in the destination
folder (same file system, so ``os.replace`` is an atomic rename), flushes and
fsyncs it, then renames it over the target. An interrupted run leaves either
the old file or the new one, plus at worst a stray ``.tmp-*`` file that is
ignored; two processes writing the same path each write their own temporary
file, so the result is one complete file or the other, never a mix.

Symbolic links are written through: a write to a link replaces the file the
link points to, atomically, and the link stays a link.

:func:`check_output` is the check a command runs on each output path
*before* any work: the destination must be writable, must not be a folder or
another non-regular file, and must not be one of the run's inputs.
"""
from __future__ import annotations

import contextlib
import errno
from io import BytesIO
import json
import math
import os
import secrets
import signal
import stat
import tempfile
import threading
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

from nrmlc.errors import OutputError, ParameterError

_umask_lock = threading.Lock()


def _current_umask() -> int:
    # os.umask can only be read by setting it; the lock keeps our own threads from racing.
    with _umask_lock:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def _target(path: str | os.PathLike) -> Path:
    """The file a write to ``path`` replaces: symbolic links are followed (written through)."""
    return Path(os.path.realpath(os.fspath(path)))


def _write_target(path: str | os.PathLike) -> Path:
    """:func:`_target`, for a write about to begin: every temporary file is created through it
    (:func:`temporary_for`, :func:`_stage`), so the renames that follow need not check again.

    Raises
    ------
    OutputError
        If that is a device, FIFO, socket or folder: a rename would replace it (as root, even
        ``/dev/null``) with a regular file.
    """
    target = _target(path)
    try:
        mode = os.stat(target).st_mode
    except OSError:
        return target  # not there yet, or not ours to judge here: the write names what fails
    if not stat.S_ISREG(mode):
        raise OutputError(f"{os.fspath(path)}: not a regular file (a device, FIFO, socket or folder); "
                          f"nothing written, give a file name")
    return target


def _prefix(name: str) -> str:
    # Short enough that a legal 255-byte file name still leaves room for ".tmp-" and the random part.
    return f".tmp-{cut_to_bytes(name, 64)}-"


def cut_to_bytes(name: str, limit: int) -> str:
    """The longest start of ``name`` whose file-system encoding takes at most ``limit`` bytes,
    cut between characters (file systems count a name's bytes, not its characters)."""
    size = 0
    for index, char in enumerate(name):
        size += len(os.fsencode(char))
        if size > limit:
            return name[:index]
    return name


#: What a file name may hold where the file system does not say (POSIX's usual NAME_MAX).
DEFAULT_NAME_MAX = 255


def name_max(folder: str | os.PathLike) -> int:
    """Bytes a file name may have in ``folder`` (or in its nearest existing parent): its file
    system's ``PC_NAME_MAX``, else :data:`DEFAULT_NAME_MAX`."""
    path = os.path.abspath(os.fspath(folder))
    while not os.path.isdir(path) and os.path.dirname(path) != path:
        path = os.path.dirname(path)
    try:
        limit = os.pathconf(path, "PC_NAME_MAX")
    except (AttributeError, OSError, ValueError):
        return DEFAULT_NAME_MAX
    return int(limit) if limit and limit > 0 else DEFAULT_NAME_MAX


def long_name(path: str | os.PathLike) -> str | None:
    """Why ``path`` cannot be created (a part of it longer, in bytes, than its file system
    allows), or None; checked before any work, so that a run is not computed for nothing."""
    text = os.fspath(path)
    parts = [part for part in Path(text).parts if part not in (os.sep, "/")]
    folder = Path(text).parent if os.path.isabs(text) else Path.cwd() / Path(text).parent
    limit = name_max(folder)
    for part in parts:
        size = len(os.fsencode(part))
        if size > limit:
            shown = part if len(part) <= 40 else f"{part[:20]}...{part[-12:]}"
            return f"the name {shown!r} is {size} bytes, more than the {limit} a file name may have there"
    return None


def _fsync_folder(folder: Path) -> None:
    # Makes the rename itself durable; not every file system allows it (best effort).
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def temporary_for(path: str | os.PathLike) -> Path:
    """Create an empty, uniquely named temporary file beside ``path``'s target.

    It keeps ``path``'s extension (some writers, like OpenCV's, choose the
    format from it). Pair it with :func:`commit` or :func:`discard`.
    """
    target = _write_target(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=_prefix(target.stem), suffix=target.suffix, dir=target.parent)
    os.close(fd)
    # mkstemp creates 0600 files; give results the usual umask-based permissions.
    os.chmod(tmp, 0o666 & ~_current_umask())
    return Path(tmp)


def _cannot_write(path: str | os.PathLike, exc: OSError) -> OutputError:
    return OutputError(f"{os.fspath(path)}: cannot write ({exc.strerror or exc}); the earlier file, if any, is kept")


def _fsync_file(tmp: str | os.PathLike, path: str | os.PathLike) -> None:
    # A full disk may only show here (delayed allocation): before anything is renamed.
    try:
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
    except OSError as exc:
        raise _cannot_write(path, exc) from None


def commit(tmp: str | os.PathLike, path: str | os.PathLike) -> Path:
    """fsync the finished temporary file ``tmp`` and rename it over ``path``'s target.

    Raises
    ------
    OutputError
        If it cannot be written or renamed (the message names ``path``); ``tmp`` is removed.
    """
    try:
        _fsync_file(tmp, path)
    except BaseException:
        discard(tmp)
        raise
    return _replace(tmp, path)


def _replace(tmp: str | os.PathLike, path: str | os.PathLike) -> Path:
    """Rename the fsynced ``tmp`` over ``path``'s target (``tmp`` is removed if that fails)."""
    try:
        target = _target(path)
        os.replace(tmp, target)
    except OSError as exc:
        discard(tmp)
        raise _cannot_write(path, exc) from None
    except BaseException:
        discard(tmp)
        raise
    _fsync_folder(target.parent)
    return Path(path)


def discard(tmp: str | os.PathLike) -> None:
    """Remove a temporary file (a failed or interrupted write); the target is untouched."""
    try:
        os.unlink(tmp)
    except FileNotFoundError:
        pass


def _stage(path: str | os.PathLike, write: Callable[[Any], None], mode: str) -> Path:
    """Write and fsync a uniquely named temporary file beside ``path``'s target; return its path."""
    target = _write_target(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=_prefix(target.name), dir=target.parent)
    except OSError as exc:
        raise _cannot_write(path, exc) from None
    try:
        # mkstemp creates 0600 files; give results the usual umask-based permissions.
        os.chmod(tmp, 0o666 & ~_current_umask())
        with os.fdopen(fd, mode) as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
    except OSError as exc:  # a full disk, a quota: named, and nothing replaced
        discard(tmp)
        if isinstance(exc, OutputError):
            raise
        raise _cannot_write(path, exc) from None
    except BaseException:
        discard(tmp)
        raise
    return Path(tmp)


def _atomic(path: str | os.PathLike, write: Callable[[Any], None], mode: str) -> Path:
    return _replace(_stage(path, write, mode), path)


def _keep_old(target: Path) -> Path | None:
    """A hard link to ``target``'s current file beside it (None: no file there, or no hard links
    on this file system), so that a rename over it can be undone."""
    if not target.is_file():
        return None
    for _ in range(100):
        backup = target.parent / f"{_prefix(target.name)}old-{secrets.token_hex(4)}"
        try:
            os.link(target, backup)
            return backup
        except FileExistsError:
            continue
        except OSError:
            return None
    return None


@contextlib.contextmanager
def _signals_held():
    """Hold SIGINT, SIGTERM and SIGHUP back (delivered after the block), so that a group of
    renames is never cut in the middle by an interrupt."""
    held = {signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", signal.SIGTERM)}
    try:
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    except (AttributeError, OSError, ValueError):
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


class Together:
    """Several outputs of one run, renamed over their targets only once all are written.

    Use as a context manager: each method writes a temporary file; leaving the
    block normally renames every one of them over its target, leaving it with
    an exception removes them all, so a run that fails while writing its
    second output (a full disk) does not leave its first one replaced.

    The renames are all or nothing too: every temporary file is fsynced
    first (where a full disk may show), the old file at each target is kept
    as a hard link beside it, and if one rename fails the ones before it are
    undone from those links (a target that did not exist is removed again);
    SIGINT, SIGTERM and SIGHUP are held back while the renames run. Only on a
    file system without hard links can a failed later rename leave an
    earlier target replaced.
    """

    def __init__(self) -> None:
        self._pending: list[tuple[Path, str | os.PathLike]] = []

    def __enter__(self) -> "Together":
        return self

    def text(self, path: str | os.PathLike, text: str) -> None:
        self._pending.append((_stage(path, lambda f: f.write(text), "w"), path))

    def boxes(self, path: str | os.PathLike, boxes: np.ndarray) -> None:
        self.text(path, format_boxes(boxes, path))

    def npz(self, path: str | os.PathLike, **arrays: np.ndarray) -> None:
        self._pending.append((_stage(path, lambda f: np.savez_compressed(f, **arrays), "wb"), path))

    def file(self, tmp: str | os.PathLike, path: str | os.PathLike) -> None:
        """Adopt a temporary file written elsewhere (see :func:`temporary_for`)."""
        self._pending.append((Path(tmp), path))

    def __exit__(self, kind, value, traceback) -> bool:
        pending, self._pending = self._pending, []
        if kind is not None:
            for tmp, _ in pending:
                discard(tmp)
            return False
        backups: list[Path | None] = []
        try:
            for tmp, path in pending:
                _fsync_file(tmp, path)
            with _signals_held():
                targets = [_target(path) for _, path in pending]
                existed = [target.exists() for target in targets]
                backups = [_keep_old(target) for target in targets]
                for done, ((tmp, path), target) in enumerate(zip(pending, targets)):
                    try:
                        os.replace(tmp, target)
                    except OSError as exc:
                        for earlier in range(done):
                            _undo(targets[earlier], existed[earlier], backups[earlier])
                        raise _cannot_write(path, exc) from None
        finally:
            for tmp, _ in pending:
                discard(tmp)  # already renamed: nothing there
            for backup in backups:
                if backup is not None:
                    discard(backup)
        for folder in {target.parent for target in targets}:
            _fsync_folder(folder)
        return False


def _undo(target: Path, existed: bool, backup: Path | None) -> None:
    """Put back the file a rename replaced (or remove the new one where there was none)."""
    try:
        if backup is not None:
            os.replace(backup, target)
        elif not existed:
            os.unlink(target)
    except OSError:
        pass  # best effort: the error that started this is the one reported


def _same_file(a: os.stat_result, b: os.stat_result) -> bool:
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


def check_output(path: str | os.PathLike, option: str, inputs: Iterable[str | os.PathLike] = (),
                 input_folders: Iterable[str | os.PathLike] = (),
                 folder_role: str = "holds this run's input frames") -> Path:
    """Refuse an output path before any work is done.

    Parameters
    ----------
    path : the path the user gave.
    option : how the user gave it, for messages (``--out``).
    inputs : files the run reads (images, ground truth): the output must not
        be one of them, whatever the path (links and hard links included).
    input_folders : folders the run reads every file of (the frames'
        folder): the output must not go inside them.
    folder_role : what such a folder is, for the message.

    Returns
    -------
    Path
        ``path`` unchanged.

    Raises
    ------
    ParameterError
        If the path is empty, a folder, a device, FIFO or socket, a looping
        link, one of the ``inputs`` or inside ``input_folders``, or its
        folder cannot be created or written to (tested by creating and
        removing a temporary file). The message names ``path`` as given.
    """
    text = os.fspath(path)
    where = f"{option} {text}"
    if not text.strip():
        raise ParameterError(f"{option}: empty path")
    if text == "-":
        raise ParameterError(f"{option} -: standard output is not supported (results are written atomically); "
                             f"give a file name")
    if text.endswith((os.sep, "/")) or os.path.basename(text) in (".", ".."):
        raise ParameterError(f"{where}: names a folder; give a file name")
    too_long = long_name(text)
    if too_long:
        raise ParameterError(f"{where}: {too_long}; give a shorter name")
    try:
        info = os.stat(text)
    except FileNotFoundError:
        info = None  # not there yet (or a link to a file not there yet: it will be created)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise ParameterError(f"{where}: symbolic link loop") from None
        if exc.errno == errno.ENOTDIR:
            raise ParameterError(f"{where}: a parent of this path is a file, not a folder") from None
        raise ParameterError(f"{where}: cannot use this path ({exc.strerror or exc})") from None
    if info is not None and stat.S_ISDIR(info.st_mode):
        raise ParameterError(f"{where}: is a folder; give a file name")
    if info is not None and not stat.S_ISREG(info.st_mode):
        raise ParameterError(f"{where}: not a regular file (a device, FIFO or socket); give a file name")
    target = _target(text)
    if info is not None:
        for source in inputs:
            try:
                same = _same_file(info, os.stat(source))
            except OSError:
                continue
            if same:
                raise ParameterError(f"{where}: is an input of this run ({os.fspath(source)}); "
                                     f"choose another file")
    for folder in input_folders:
        folder = _target(folder)
        if folder == target.parent or folder in target.parents:
            raise ParameterError(f"{where}: is inside {folder}, which {folder_role}; write it elsewhere")
    _probe(target.parent, target.name, where)
    return Path(text)


def _probe(folder: Path, name: str, where: str) -> None:
    """Refuse ``folder`` if it cannot be created or written to: the nearest existing folder
    decides whether the missing ones can be created (tested by creating and removing a
    temporary file named after ``name``)."""
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise ParameterError(f"{where}: {folder} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=_prefix(name), dir=folder)
    except OSError as exc:
        raise ParameterError(f"{where}: cannot write to folder {folder} ({exc.strerror or exc})") from None
    try:
        os.close(fd)
    finally:
        os.unlink(probe)  # even if an interrupt lands here


def check_folder(path: str | os.PathLike, option: str, where: str | None = None) -> Path:
    """Refuse an output folder before any work is done (the folder counterpart of :func:`check_output`).

    ``where`` names the folder in messages (default ``"<option> <path>"``; a default folder the
    user did not give says so instead).

    Raises
    ------
    ParameterError
        If the path is empty, a file or anything but a folder, a symbolic link to nothing (a
        folder cannot be created through it), a looping link, too long a name (in bytes), or
        if it cannot be created or written to. The message names ``path`` as given.
    """
    text = os.fspath(path)
    where = where or f"{option} {text}"
    if not text.strip():
        raise ParameterError(f"{option}: empty path")
    too_long = long_name(text)
    if too_long:
        raise ParameterError(f"{where}: {too_long}; give a shorter name")
    # Every part of the path, so that a link anywhere along it is seen (mkdir stops at a dangling one).
    current = Path(text)
    for part in [current, *current.parents]:
        if os.path.islink(part) and not os.path.exists(part):
            if _loops(part):
                raise ParameterError(f"{where}: symbolic link loop")
            raise ParameterError(f"{where}: {part} is a symbolic link to {os.readlink(part)}, which does not "
                                 f"exist; create that folder or give another {option}")
    try:
        info = os.stat(text)
    except FileNotFoundError:
        info = None
    except OSError as exc:
        if exc.errno == errno.ENOTDIR:
            raise ParameterError(f"{where}: a parent of this path is a file, not a folder") from None
        raise ParameterError(f"{where}: cannot use this path ({exc.strerror or exc})") from None
    if info is not None and not stat.S_ISDIR(info.st_mode):
        raise ParameterError(f"{where}: exists and is not a folder; give a folder")
    target = _target(text)
    _probe(target, ".probe", where)
    return Path(text)


def _loops(path: str | os.PathLike) -> bool:
    try:
        os.stat(path)
    except OSError as exc:
        return exc.errno == errno.ELOOP
    return False


def write_bytes(path: str | os.PathLike, data: bytes | bytearray | memoryview | np.ndarray) -> Path:
    """Write raw bytes to ``path`` atomically (a numpy array is written as its buffer)."""
    if isinstance(data, np.ndarray):
        data = np.ascontiguousarray(data).tobytes()
    return _atomic(path, lambda f: f.write(data), "wb")


#: What matplotlib stamps into a file that differs between identical runs: the date (SVG, PDF,
#: PostScript). SVG's element ids are random too, unless ``svg.hashsalt`` is fixed.
_UNDATED = {"svg": {"Date": None}, "pdf": {"CreationDate": None}, "ps": {"CreationDate": None},
            "eps": {"CreationDate": None}}


def write_figure(figure, path: str | os.PathLike, dpi: int = 130) -> Path:
    """Write a matplotlib ``figure`` to ``path`` atomically, in the format its suffix names, and
    close it. Identical figures give identical bytes in every format (no date, fixed SVG ids)."""
    import matplotlib
    import matplotlib.pyplot as plt

    kind = Path(path).suffix.lstrip(".").lower()
    buffer = BytesIO()
    try:
        with matplotlib.rc_context({"svg.hashsalt": "nrmlc"}):
            figure.savefig(buffer, format=kind, dpi=dpi, metadata=_UNDATED.get(kind))
    finally:
        plt.close(figure)
    return write_bytes(path, buffer.getvalue())


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    return _atomic(path, lambda f: f.write(text), "w")


def json_ready(obj: Any) -> Any:
    """``obj`` with numpy arrays and scalars as Python values, paths as strings and NaN/inf
    floats as None, so that it is strict JSON (``json.dumps`` would write NaN, which
    JavaScript, jq and most other readers refuse)."""
    if isinstance(obj, dict):
        return {str(k): json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_ready(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_ready(obj.tolist())
    if isinstance(obj, np.generic):
        return json_ready(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json(path: str | os.PathLike, obj: Any) -> Path:
    """Write ``obj`` as indented, strict JSON atomically (:func:`json_ready`: numpy values
    allowed, NaN/inf written as null)."""
    return write_text(path, json.dumps(json_ready(obj), indent=2, allow_nan=False) + "\n")


def write_npz(path: str | os.PathLike, **arrays: np.ndarray) -> Path:
    """Save arrays to a compressed ``.npz`` atomically."""
    return _atomic(path, lambda f: np.savez_compressed(f, **arrays), "wb")


def format_number(value: float) -> str:
    """The shortest text that reads back as exactly ``value`` (``12``, ``0.5``, ``1e-07``, ``nan``)."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def write_boxes(path: str | os.PathLike, boxes: np.ndarray) -> Path:
    """Write an (n, 4) array of ``x,y,w,h`` boxes, one OTB line per frame.

    Every value is written exactly (the shortest round-trip form), so a box
    read back with :func:`nrmlc.data.read_box_file` equals the one written,
    however small or large.
    """
    return write_text(path, format_boxes(boxes, path))


def format_boxes(boxes: np.ndarray, path: str | os.PathLike = "boxes") -> str:
    """The text of a box file: one exact ``x,y,w,h`` line per row of an (n, 4) array."""
    boxes = np.asarray(boxes, dtype=np.float64)
    if boxes.ndim != 2 or boxes.shape[1] != 4 or len(boxes) == 0:
        raise ParameterError(f"{os.fspath(path)}: boxes must have shape (n, 4) with n >= 1, got {boxes.shape}")
    return "\n".join(",".join(format_number(v) for v in row) for row in boxes) + "\n"
