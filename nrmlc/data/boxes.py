"""Reading OTB-style box files (``x,y,w,h`` per line).

Conventions (OTB):
- one line per frame, four numbers, delimited by commas, tabs or spaces
  (any mix), CRLF or LF line endings, optional trailing newline;
- boxes are 1-based: pixel (1, 1) is the top-left pixel of the image;
- a row of ``0,0,0,0`` or any NaN means "frame not annotated": it is returned
  as a row of NaN so that metrics skip it;
- any other row must have ``w > 0`` and ``h > 0``: a zero or negative size
  (e.g. ``12,30,0,40``) is an error naming ``file:line``.
"""
from __future__ import annotations

import math
import os
import re

import numpy as np

from nrmlc.errors import DataError

_SPLIT = re.compile(r"[,\s;]+")


def parse_box_line(line: str, where: str) -> list[float]:
    """Parse one ``x,y,w,h`` line; ``where`` names the file and line for errors."""
    fields = [f for f in _SPLIT.split(line.strip()) if f]
    if len(fields) != 4:
        raise DataError(f"{where}: expected 4 numbers (x,y,w,h), got {len(fields)}: {line.strip()!r}")
    try:
        return [float(f) for f in fields]
    except ValueError:
        raise DataError(f"{where}: not a number in {line.strip()!r}") from None


def read_box_file(path: str | os.PathLike) -> np.ndarray:
    """Read a box file.

    Parameters
    ----------
    path : path to a text file with one ``x,y,w,h`` line per frame.

    Returns
    -------
    boxes : (n_frames, 4) float64
        1-based OTB boxes; rows of NaN where the frame is not annotated
        (``0,0,0,0`` or NaN in the file).

    Raises
    ------
    DataError
        On a missing file, a wrong field count, text, an infinite value, or a
        zero or negative size on a row other than ``0,0,0,0`` (the message
        names ``file:line``).
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise DataError(f"{path}: box file not found")
    with open(path, "r", encoding="utf-8", errors="replace", newline=None) as handle:
        lines = handle.read().splitlines()
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
        if any(math.isinf(v) for v in row):
            raise DataError(f"{where}: infinite value in {line.strip()!r}")
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
