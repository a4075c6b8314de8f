"""Scores per OTB attribute (``nrmlc evaluate ... --attributes DIR``), as the OTB toolkit's perfPlot.

An attribute folder holds one ``<Seq>.txt`` per sequence: the benchmark's 11 flags, 0 or 1,
separated by commas or white space, in the toolkit's order (``perfPlot_TB100.m``'s ``attName``,
checked on the files: Car4 is IV and SV, Deer MB, FM, IPR, BC and LR):

    IV illumination variation, OPR out-of-plane rotation, SV scale variation, OCC occlusion,
    DEF deformation, MB motion blur, FM fast motion, IPR in-plane rotation, OV out of view,
    BC background clutter, LR low resolution.

A sequence's file is found as its result files are (:func:`nrmlc.workbench.otb_results.sequence_key`:
``Skating2.1.txt`` is Skating2-1's, ``jogging-1.txt`` Jogging-1's, ``Car4.TXT`` Car4's); a two-target
sequence without a file of its own takes its folder's (``Jogging.txt`` for Jogging-1 and Jogging-2).
A sequence without a file is left out of every attribute, with a note; a file that is malformed,
a broken link, a FIFO, a folder or larger than :data:`MAX_ATTRIBUTE_BYTES` stops the command with
one line naming it.

A tracker's score on an attribute is the toolkit's: the mean of its per-sequence success (and
precision) curves over the scored sequences that have the attribute, AUC the mean of that
curve, precision@20 its value at 20 px; the count of those sequences is shown beside it.
The toolkit draws no plot for an attribute of fewer than 2 sequences; here it is shown, with
its count.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from nrmlc import io
from nrmlc.errors import DataError
from nrmlc.workbench.otb_results import sequence_key
from nrmlc.workbench.results_layout import check_input_file, has_suffix, reading

#: (code, name) in the order of the flags in the benchmark's attribute files.
ATTRIBUTES = (
    ("IV", "illumination variation"),
    ("OPR", "out-of-plane rotation"),
    ("SV", "scale variation"),
    ("OCC", "occlusion"),
    ("DEF", "deformation"),
    ("MB", "motion blur"),
    ("FM", "fast motion"),
    ("IPR", "in-plane rotation"),
    ("OV", "out of view"),
    ("BC", "background clutter"),
    ("LR", "low resolution"),
)
_SPLIT = re.compile(r"[,\s]+")
#: An attribute file's extension (any case: ``Car4.TXT`` is Car4's).
ATTRIBUTE_SUFFIX = ".txt"
#: Largest attribute file read (11 flags take 22 bytes; room for any spacing).
MAX_ATTRIBUTE_BYTES = 64 << 10
_TARGET = re.compile(r"^(.+)-\d+$")


def read_attribute_file(path) -> frozenset:
    """The attribute codes set in one ``<Seq>.txt`` (11 flags, see the module docstring).

    Raises
    ------
    DataError
        Naming the file, for anything but 11 values of 0 or 1, a missing file, a broken link, a
        FIFO or a folder.
    InputTooLarge
        For a file of more than :data:`MAX_ATTRIBUTE_BYTES`.
    """
    path = Path(path)
    if not check_input_file(path, "attribute file", MAX_ATTRIBUTE_BYTES):
        raise DataError(f"{path}: attribute file not found")
    try:
        with reading(path, "attribute file"):
            text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: cannot read the attribute file ({exc})") from None
    fields = [f for f in _SPLIT.split(text.strip()) if f]
    if len(fields) != len(ATTRIBUTES) or any(f not in ("0", "1") for f in fields):
        raise DataError(f"{path}: expected {len(ATTRIBUTES)} flags of 0 or 1 "
                        f"({', '.join(code for code, _ in ATTRIBUTES)}), got {text.strip()[:80]!r}")
    return frozenset(code for (code, _), flag in zip(ATTRIBUTES, fields) if flag == "1")


def read_attributes(folder, sequence_names) -> tuple[dict, list]:
    """The attributes of each named sequence from an attribute folder.

    Parameters
    ----------
    folder : path
    sequence_names : list of str

    Returns
    -------
    attributes : dict of sequence name -> frozenset of codes
        Only the sequences that have a file.
    notes : list of str
        The sequences without a file (left out of every attribute).

    Raises
    ------
    DataError
        The folder is missing; a file is malformed, a broken link, a FIFO or a folder; two files
        name one sequence.
    InputTooLarge
        A file of more than :data:`MAX_ATTRIBUTE_BYTES`.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise DataError(f"{folder}: attribute folder {'is not a folder' if folder.exists() else 'not found'}")
    files: dict = {}
    # Whatever the entry is: reading it refuses a link to nothing or a FIFO by name, where skipping
    # it would leave its sequence out of every attribute.
    for path in sorted(folder.iterdir()):
        if has_suffix(path, ATTRIBUTE_SUFFIX):
            files.setdefault(sequence_key(path.stem), []).append(path)
    attributes, absent = {}, []
    for name in sequence_names:
        key = sequence_key(name)
        base = _TARGET.match(key)
        paths = files.get(key) or (files.get(base.group(1)) if base else None)
        if not paths:
            absent.append(name)
            continue
        if len(paths) > 1:
            raise DataError(f"{paths[0]} and {paths[1]} both name sequence {name}; keep one")
        attributes[name] = read_attribute_file(paths[0])
    notes = [f"--attributes: no attribute file in {folder} for {', '.join(absent)} (left out of the attributes)"] \
        if absent else []
    return attributes, notes


@dataclass
class AttributeScores:
    """Every tracker's scores on the sequences with one attribute.

    Attributes
    ----------
    code, name : str
    sequences : list of str
        The scored sequences with the attribute.
    success_auc, precision_20 : dict of tracker name -> float
        Empty when no scored sequence has the attribute.
    """

    code: str
    name: str
    sequences: list = field(default_factory=list)
    success_auc: dict = field(default_factory=dict)
    precision_20: dict = field(default_factory=dict)


def attribute_scores(comparison, attributes: dict) -> list[AttributeScores]:
    """Per attribute, each tracker's success AUC and precision@20 (means over seeds and sequences).

    Parameters
    ----------
    comparison : nrmlc.workbench.score.Comparison
    attributes : dict of sequence name -> set of codes (:func:`read_attributes`)

    Returns
    -------
    list of AttributeScores, in the order of :data:`ATTRIBUTES`
    """
    from nrmlc.workbench.metrics import PRECISION_AT, PRECISION_THRESHOLDS

    at = int(np.flatnonzero(PRECISION_THRESHOLDS == PRECISION_AT)[0])
    scores = []
    for code, name in ATTRIBUTES:
        chosen = [s for s in comparison.sequences if code in attributes.get(s, ())]
        entry = AttributeScores(code, name, chosen)
        for tracker in comparison.trackers:
            if not chosen:
                continue
            success = np.mean([[run[s].success for s in chosen] for run in tracker.runs], axis=(0, 1))
            precision = np.mean([[run[s].precision for s in chosen] for run in tracker.runs], axis=(0, 1))
            entry.success_auc[tracker.name] = float(np.mean(success))
            entry.precision_20[tracker.name] = float(precision[at])
        scores.append(entry)
    return scores


def format_attribute_table(comparison, scores: list[AttributeScores]) -> str:
    """Two tables, success AUC then precision@20: one row per tracker, one column per attribute."""
    names = [t.name for t in sorted(comparison.trackers, key=lambda t: -t.summary()["success_auc"])]
    width = max(8, *(len(n) for n in names))
    headers = [f"{s.code}({len(s.sequences)})" for s in scores]
    cell = max(6, *(len(h) for h in headers))
    lines = []
    for title, key in (("success AUC", "success_auc"), ("precision@20", "precision_20")):
        lines.append(f"{title} per attribute (in brackets: the scored sequences with it)")
        lines.append(f"{'tracker':{width}s} " + " ".join(f"{h:>{cell}s}" for h in headers))
        for name in names:
            values = [getattr(s, key).get(name) for s in scores]
            lines.append(f"{name:{width}s} " + " ".join(
                f"{'-' if v is None else format(v, '.3f'):>{cell}s}" for v in values))
        lines.append("")
    lines.append("(" + ", ".join(f"{code} {name}" for code, name in ATTRIBUTES) + ")")
    return "\n".join(lines)


def attribute_csv_rows(scores: list[AttributeScores]) -> list[dict]:
    """Rows for :func:`nrmlc.workbench.report.write_csv`: sequence ``ALL``, ``attribute`` and ``sequences`` set."""
    rows = []
    for entry in scores:
        for tracker, auc in entry.success_auc.items():
            rows.append({"tracker": tracker, "sequence": "ALL", "attribute": entry.code,
                         "sequences": len(entry.sequences), "success_auc": auc,
                         "precision_20": entry.precision_20[tracker]})
    return rows


def plot_attributes(comparison, scores: list[AttributeScores], path) -> Path:
    """Heatmaps tracker x attribute, written atomically: success AUC, and AUC minus the tracker's overall AUC.

    The second panel shows at a glance where a tracker loses (red) or gains (blue) against its
    own overall score, e.g. a loss on scale variation.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    trackers = sorted(comparison.trackers, key=lambda t: -t.summary()["success_auc"])
    overall = np.array([t.summary()["success_auc"] for t in trackers])
    auc = np.array([[s.success_auc.get(t.name, np.nan) for s in scores] for t in trackers])
    labels = [f"{s.code}\n({len(s.sequences)})" for s in scores]
    height = 1.6 + 0.38 * len(trackers)
    figure, axes = plt.subplots(1, 2, figsize=(15, height))
    spread = np.nanmax(np.abs(auc - overall[:, None])) if np.isfinite(auc).any() else 0.1
    panels = ((auc, "viridis", 0.0, max(0.8, float(np.nanmax(auc)) if np.isfinite(auc).any() else 0.8),
               "success AUC per attribute"),
              (auc - overall[:, None], "RdBu", -max(spread, 0.05), max(spread, 0.05),
               "AUC on the attribute minus the tracker's overall AUC"))
    for axis, (values, colours, low, high, title) in zip(axes, panels):
        image = axis.imshow(np.ma.masked_invalid(values), cmap=colours, vmin=low, vmax=high, aspect="auto")
        axis.set_xticks(range(len(scores)), labels, fontsize=8)
        axis.set_yticks(range(len(trackers)), [t.name for t in trackers], fontsize=8)
        axis.set_title(title, fontsize=10)
        for i in range(values.shape[0]):
            for j in range(values.shape[1]):
                if np.isfinite(values[i, j]):
                    axis.text(j, i, f"{values[i, j]:+.2f}" if colours == "RdBu" else f"{values[i, j]:.2f}",
                              ha="center", va="center", fontsize=7,
                              color="white" if colours == "viridis" and values[i, j] < 0.45 * high else "black")
        figure.colorbar(image, ax=axis, fraction=0.03, pad=0.02)
    n = len(comparison.sequences)
    figure.suptitle(f"OPE per attribute ({n} sequence{'s' if n != 1 else ''}; in brackets: those with the "
                    f"attribute)", fontsize=10)
    figure.tight_layout()
    return io.write_figure(figure, path)
