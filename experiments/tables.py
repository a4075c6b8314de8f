"""Numbers into files: the one number formatter, mean ± std, CSV and PNG writers.

Every experiment script formats its tables with :func:`fmt` and writes through
:func:`write_csv`, :func:`save_figure` and :func:`nrmlc.io.write_json` (strict JSON), all
atomic (a killed run leaves the old file or the new one).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: What a missing or non-finite number prints as.
MISSING = "–"


def mean_std(values) -> tuple[float, float]:
    """Mean and (population) standard deviation of the finite values.

    (nan, nan) for no value; the std is NaN for a single value (one seed has
    no spread to report, and :func:`fmt` then prints the mean alone).
    """
    array = np.asarray([v for v in values if v is not None], dtype=np.float64)
    array = array[np.isfinite(array)]
    if array.size == 0:
        return math.nan, math.nan
    return float(array.mean()), float(array.std()) if array.size > 1 else math.nan


def fmt(value, digits: int | None = None, std=None) -> str:
    """A number for a markdown table; :data:`MISSING` when it is missing or not finite.

    Parameters
    ----------
    value : float or None
    digits : int, optional
        Decimals (``0.53``, ``± std`` with as many). None: 3 significant digits, in
        scientific notation below 1e-3 and from 1e4 on (for statistics of any scale).
    std : float, optional
        Shown as ``value ± std`` when finite.
    """
    if value is None or not math.isfinite(float(value)):
        return MISSING
    value = float(value)
    if digits is None:
        if value != 0 and (abs(value) < 1e-3 or abs(value) >= 1e4):
            return f"{value:.2e}" if abs(value) < 1e-3 else f"{value:.3g}"
        return f"{value:.3g}"
    text = f"{value:.{digits}f}"
    if std is not None and math.isfinite(std):
        text += f" ± {std:.{digits}f}"
    return text


def write_csv(path, header: list[str], rows: list[list]) -> Path:
    """Write a CSV atomically (floats with 6 significant digits, missing values empty)."""
    import csv
    import io as _io

    from nrmlc import io

    def cell(value):
        if value is None:
            return ""
        if isinstance(value, float):
            return "" if not math.isfinite(value) else f"{value:.6g}"
        return value

    buffer = _io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows([[cell(v) for v in row] for row in rows])
    return io.write_text(path, buffer.getvalue())


def percentiles(values: np.ndarray, qs=(0, 0.1, 1, 5, 25, 50, 75, 95, 99, 99.9, 100)) -> dict:
    values = np.asarray(values, dtype=np.float64).ravel()
    return {f"p{q:g}": float(np.percentile(values, q)) for q in qs} if values.size else {}


def save_figure(fig, path, dpi: int = 100, rect=None) -> Path:
    """Lay out ``fig`` (``tight_layout`` within ``rect``), write it to ``path`` as PNG
    atomically (a killed run leaves the old file or the new one, never half of one) and
    close it."""
    import io as _io

    import matplotlib.pyplot as plt

    from nrmlc import io

    fig.tight_layout(rect=rect)
    buffer = _io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    return io.write_bytes(path, buffer.getvalue())
