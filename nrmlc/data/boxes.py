"""Reading OTB-style box files (``x,y,w,h`` per line).

Conventions (OTB):
- one line per frame, four numbers, delimited by commas, tabs or spaces
  (any mix), CRLF or LF line endings, optional trailing newline;
- boxes are 1-based: pixel (1, 1) is the top-left pixel of the image;
- a row of ``0,0,0,0`` or any NaN means "frame not annotated": it is returned
  as a row of NaN so that metrics skip it;
- any other row must have ``w > 0`` and ``h > 0``: a zero or negative size
  (e.g. ``12,30,0,40``) is an error naming ``file:line``;
- numbers are written as annotation tools write them: ASCII decimals with an
  optional exponent (``12``, ``-3.5``, ``1e-05``), or ``NaN``; forms that
  Python's ``float()`` also accepts (``1_3_2``, non-ASCII digits,
  ``infinity``) are errors, and so is a value beyond ``MAX_COORDINATE``
  (1e9 px: no image is that large, and larger values overflow the areas);
- the text is UTF-8 (with or without a byte-order mark) or UTF-16 (with a
  byte-order mark, or detected from its zero bytes).

Result files (``read_box_file(path, predictions=True)``) are read with the
same syntax, but a row that is infinite, beyond ``MAX_COORDINATE`` or of
non-positive size is kept as it is: it is a failed prediction, which
:func:`nrmlc.workbench.metrics.evaluate` scores as a failure, not a broken file.
"""
from __future__ import annotations

import math
import os
import re

import numpy as np

from nrmlc.errors import DataError

_SPLIT = re.compile(r"[,\s;]+")
# What annotation tools and our own writer produce (inf only so that result files
# can say "no box"; the ground-truth reader refuses it with its own message).
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:nan|inf)", re.IGNORECASE)

#: Largest coordinate or size (pixels) taken as a real box.
MAX_COORDINATE = 1e9
#: Largest box file read: 10^7 lines of 4 long numbers (a sparse pack allows 10^7 frames too).
MAX_BOX_FILE_BYTES = 1 << 30


def parse_box_line(line: str, where: str) -> list[float]:
    """Parse one ``x,y,w,h`` line; ``where`` names the file and line for errors."""
    fields = [f for f in _SPLIT.split(line.strip()) if f]
    if len(fields) != 4:
        raise DataError(f"{where}: expected 4 numbers (x,y,w,h), got {len(fields)}: {line.strip()!r}")
    if not all(_NUMBER.fullmatch(f) for f in fields):
        raise DataError(f"{where}: not a number in {line.strip()!r}")
    return [float(f) for f in fields]


def _decode(data: bytes, path: str) -> str:
    """Text of a box file: UTF-8 (BOM optional) or UTF-16 (BOM, or NUL bytes of ASCII text)."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        encoding = "utf-16"
    elif data.startswith(b"\xef\xbb\xbf"):
        encoding = "utf-8-sig"
    elif len(data) >= 2 and data[1::2].count(0) > len(data) // 4:
        encoding = "utf-16-le"  # ASCII digits in UTF-16 without a BOM: every second byte is 0
    elif len(data) >= 2 and data[0::2].count(0) > len(data) // 4:
        encoding = "utf-16-be"
    else:
        encoding = "utf-8"
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not a text file (cannot decode byte {exc.start} as {encoding})") from None


def read_box_file(path: str | os.PathLike, predictions: bool = False) -> np.ndarray:
    """Read a box file.

    Parameters
    ----------
    path : path to a text file with one ``x,y,w,h`` line per frame.
    predictions : read a tracker's result file: infinite, huge or empty
        boxes are kept (failed predictions) instead of refused.

    Returns
    -------
    boxes : (n_frames, 4) float64
        1-based OTB boxes; rows of NaN where the frame is not annotated
        (``0,0,0,0`` or NaN in the file).

    Raises
    ------
    DataError
        On a missing or non-regular file, a wrong field count, text, an
        infinite value or one beyond ``MAX_COORDINATE``, or a zero or
        negative size on a row other than ``0,0,0,0`` (the message names
        ``file:line``); the last three not for ``predictions``.
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise DataError(f"{path}: box file not found")
    if not os.path.isfile(path):
        # A folder, or a FIFO that would block the read forever.
        raise DataError(f"{path}: box file is not a regular file")
    size = os.path.getsize(path)
    if size > MAX_BOX_FILE_BYTES:
        # Read whole into memory otherwise (a mislabelled video or archive of gigabytes).
        raise DataError(f"{path}: {size / 2**20:.0f} MB is not a box file (at most {MAX_BOX_FILE_BYTES >> 20} MB, "
                        f"about 10^7 boxes)")
    with open(path, "rb") as handle:
        lines = _decode(handle.read(), path).splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise DataError(f"{path}: box file is empty")
    rows = []
    for number, line in enumerate(lines, start=1):
        where = f"{path}:{number}"
        if not line.strip():
            raise DataError(f"{where}: empty line inside the box file")
        row = parse_box_line(line, where)
        if any(math.isnan(v) for v in row) or all(v == 0 for v in row):
            rows.append([math.nan] * 4)
            continue
        if predictions:
            rows.append(row)
            continue
        if any(math.isinf(v) for v in row):
            raise DataError(f"{where}: infinite value in {line.strip()!r}")
        if any(abs(v) > MAX_COORDINATE for v in row):
            raise DataError(f"{where}: value beyond {MAX_COORDINATE:g} px in {line.strip()!r}")
        if row[2] <= 0 or row[3] <= 0:
            # Only the full 0,0,0,0 row means "unannotated" (OTB); a box with a
            # position but no area is a broken annotation, not a missing one.
            kind = "negative" if min(row[2], row[3]) < 0 else "zero"
            raise DataError(
                f"{where}: {kind} box size in {line.strip()!r} (w and h must be > 0; "
                f"write 0,0,0,0 for an unannotated frame)"
            )
        rows.append(row)
    return np.asarray(rows, dtype=np.float64)
