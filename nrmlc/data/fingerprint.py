"""Content digests of input files, for the run cache's keys (:attr:`nrmlc.data.Sequence.identity`).

A key must change when any frame's bytes change, and only then. Hashing is
cheap next to tracking (sha256 of the 1,020 frames of Car1, 18 MB, takes
about 25 ms from the page cache), but a grid asks for the keys of the same
folders thousands of times, so each file's digest is remembered in this
process under its ``(device, inode, size, mtime_ns, ctime_ns)``: a file whose
size or times changed is read again. ``ctime`` is in that tuple because
copies that keep the modification time (``cp -p``, ``rsync -a``, ``tar x``)
still set it. The one case where those numbers are ambiguous is a file
rewritten with the same size within the file system's clock resolution of
the moment it was hashed; so a file changed less than :data:`RACY_SECONDS`
before it was hashed is not remembered, and is hashed again next time (as
git does with its "racily clean" index entries).
"""
from __future__ import annotations

import hashlib
import os
import threading
import time

#: A file changed this recently when it was hashed is hashed again on the next request.
RACY_SECONDS = 2.0

_memo: dict[tuple, str] = {}
_lock = threading.Lock()


def _stamp(info: os.stat_result) -> tuple:
    return (info.st_dev, info.st_ino, info.st_size, info.st_mtime_ns, info.st_ctime_ns)


def file_digest(path: str | os.PathLike) -> str:
    """sha256 (hex) of the file's bytes, remembered while its size and times stay the same.

    Raises
    ------
    OSError
        If the file cannot be read.
    """
    path = os.path.abspath(os.fspath(path))
    before = os.stat(path)
    key = (path, *_stamp(before))
    with _lock:
        digest = _memo.get(key)
    if digest is not None:
        return digest
    with open(path, "rb") as handle:
        digest = hashlib.file_digest(handle, "sha256").hexdigest()
    after = os.stat(path)
    settled = time.time_ns() - max(after.st_mtime_ns, after.st_ctime_ns) > RACY_SECONDS * 1e9
    if _stamp(after) == _stamp(before) and settled:
        with _lock:
            _memo[key] = digest
    return digest


def forget() -> None:
    """Drop every remembered digest (tests; a long-lived process that wants to re-read everything)."""
    with _lock:
        _memo.clear()
