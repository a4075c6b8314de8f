"""What a comparison shows: the text table, the CSV file and the OTB success and precision plots."""
from __future__ import annotations

import csv
import io as text_io
from pathlib import Path

from nrmlc import io
from nrmlc.errors import ParameterError
from nrmlc.workbench.find import primary_seed
from nrmlc.workbench.score import MEANS_RULE, SCORE_NAMES, Comparison, TrackerScores, format_scope


def format_table(comparison: Comparison, per_sequence: bool = True) -> str:
    """What was scored (first line), per-sequence AUC (one column per tracker), the overall scores, as text."""
    lines = [format_scope(comparison), ""]
    names = [t.name for t in comparison.trackers]
    width = max(8, *(len(n) for n in names))
    if per_sequence:
        lines.append("success AUC per sequence ('-': no result file, scored as all frames missing)"
                     + (" (mean over seeds)" if any(len(t.runs) > 1 for t in comparison.trackers) else ""))
        lines.append(f"{'sequence':16s} " + " ".join(f"{n:>{width}s}" for n in names))
        for sequence in comparison.sequences:
            cells = []
            for tracker in comparison.trackers:
                value = tracker.sequence_auc(sequence)
                cells.append(f"{'-' if tracker.files[sequence] is None else format(value, '.3f'):>{width}s}")
            lines.append(f"{sequence:16s} " + " ".join(cells))
        lines.append("")
    several = any(len(t.runs) > 1 for t in comparison.trackers)
    timed = any(t.fps is not None for t in comparison.trackers)
    seeds_header = f" {'seeds':>5s} {'AUC sd':>6s}" if several else ""
    lines.append(f"{'tracker':{width}s} {'seqs':>7s}{seeds_header} {'AUC':>6s} {'P@20':>6s} {'overlap':>8s} "
                 f"{'CLE px':>8s} {'missing frames':>15s}" + (f" {'fps':>8s}" if timed else ""))
    for tracker in sorted(comparison.trackers, key=lambda t: -t.summary()["success_auc"]):
        s = tracker.summary()
        cle = "-" if s["mean_center_error"] is None else f"{s['mean_center_error']:.1f}"
        spread = s["success_auc_std_over_seeds"]
        seeds = f" {s['seeds']:>5d} {'-' if spread is None else format(spread, '.3f'):>6s}" if several else ""
        fps = (f" {'-' if s['fps'] is None else format(s['fps'], '.1f'):>8s}") if timed else ""
        lines.append(f"{s['tracker']:{width}s} {s['sequences_with_results']:>3d}/{s['sequences']:<3d}{seeds} "
                     f"{s['success_auc']:6.3f} {s['precision_20']:6.3f} {s['mean_overlap']:8.3f} {cle:>8s} "
                     f"{s['missing_frames']:>7d}/{s['frames']:<7d}{fps}")
    n = len(comparison.sequences)
    lines.append(f"('seqs': with a result / scored; {MEANS_RULE.replace('every scored sequence', f'the {n} scored')}"
                 + ("; fps: as each tracker's results record it, total frames over total time, on the "
                    "authors' machines for published results" if timed else "") + ")")
    if several:
        lines.append("(scores are means over seeds and sequences; 'AUC sd': standard deviation over seeds)")
    return "\n".join(lines)


def check_plot_path(path, option: str = "--plot") -> None:
    """Refuse a plot file name whose ending matplotlib cannot write (before any work is done)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    formats = FigureCanvasAgg(Figure()).get_supported_filetypes()
    suffix = Path(path).suffix.lstrip(".").lower()
    if suffix not in formats:
        raise ParameterError(f"{option} {path}: cannot write a '{suffix}' file; use one of {', '.join(sorted(formats))}")


def _legend_name(tracker: TrackerScores) -> str:
    return tracker.name if len(tracker.runs) == 1 else f"{tracker.name} ({len(tracker.runs)} seeds)"


#: Columns of the legends below the success and precision plots.
LEGEND_COLUMNS = 3


def plot_comparison(comparison: Comparison, path, title: str = "") -> Path:
    """OTB success and precision plots of every tracker side by side, written atomically to ``path``.

    Legends, below each plot, give AUC (success) and precision@20 (precision), trackers sorted by them.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from nrmlc.workbench.metrics import PRECISION_AT, PRECISION_THRESHOLDS, SUCCESS_THRESHOLDS

    styles = ["-", "--", "-.", ":"]
    legend_rows = -(-len(comparison.trackers) // LEGEND_COLUMNS)
    # Taller by the legends' rows, so that many trackers do not squeeze the plots.
    figure, (left, right) = plt.subplots(1, 2, figsize=(11, 4.6 + 0.2 * legend_rows))
    summaries = {t.name: t.summary() for t in comparison.trackers}
    by_auc = sorted(comparison.trackers, key=lambda t: -summaries[t.name]["success_auc"])
    by_precision = sorted(comparison.trackers, key=lambda t: -summaries[t.name]["precision_20"])
    colours = {t.name: f"C{i % 10}" for i, t in enumerate(comparison.trackers)}
    for i, tracker in enumerate(by_auc):
        left.plot(SUCCESS_THRESHOLDS, tracker.success, styles[(i // 10) % 4], color=colours[tracker.name], lw=1.8,
                  label=f"{_legend_name(tracker)} [{summaries[tracker.name]['success_auc']:.3f}]")
    for i, tracker in enumerate(by_precision):
        right.plot(PRECISION_THRESHOLDS, tracker.precision, styles[(i // 10) % 4], color=colours[tracker.name],
                   lw=1.8, label=f"{_legend_name(tracker)} [{summaries[tracker.name]['precision_20']:.3f}]")
    n = len(comparison.sequences)
    scope = f"{n} sequence{'s' if n != 1 else ''}"
    if comparison.max_frames is not None:
        scope += f", first {comparison.max_frames} frames"
    left.set(xlabel="Overlap threshold", ylabel="Success rate", xlim=(0, 1), ylim=(0, 1.02),
             title=f"Success plots of OPE ({scope})")
    right.set(xlabel="Location error threshold (px)", ylabel="Precision", xlim=(0, PRECISION_THRESHOLDS[-1]),
              ylim=(0, 1.02), title=f"Precision plots of OPE ({scope})")
    right.axvline(PRECISION_AT, color="0.6", lw=0.8, ls=":")
    for axis in (left, right):
        axis.grid(True, alpha=0.4)
        # Below the axes: inside, any corner covers some tracker's curve (a weak tracker's lies low,
        # a strong one's high).
        axis.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=LEGEND_COLUMNS, fontsize=8,
                    title="AUC" if axis is left else f"precision@{PRECISION_AT:g}", title_fontsize=8,
                    frameon=False)
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    return io.write_figure(figure, path)


CSV_COLUMNS = ("tracker", "seed", "sequence", "file", "frames", "missing_frames", *SCORE_NAMES, "fps",
               "sequences", "attribute")


def write_csv(comparison: Comparison, path, attribute_rows=()) -> Path:
    """One row per (tracker, seed, sequence), one ``ALL`` row per tracker (means over seeds and
    sequences, ``sequences`` the count), and the ``attribute_rows`` (dicts of :data:`CSV_COLUMNS`), atomically.

    A sequence without a result file has empty score cells (its frames all count as missing
    in the ``ALL`` row).
    """
    buffer = text_io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n", restval="")
    writer.writeheader()
    for tracker in comparison.trackers:
        labels = tracker.seed_labels or [primary_seed(tracker.folder)]
        for label, run in zip(labels, tracker.runs):
            for name, evaluation in run.items():
                d = evaluation.as_dict()
                file = tracker.files[name] if run is tracker.evaluations else None
                absent = run is tracker.evaluations and file is None
                speed = tracker.speeds.get(name, (None, 0))[0] if run is tracker.evaluations else None
                writer.writerow({"tracker": tracker.name, "seed": label, "sequence": name, "file": file or "",
                                 "frames": d["n_frames"], "missing_frames": d["n_missing"],
                                 **{k: "" if d[k] is None or absent else d[k] for k in SCORE_NAMES},
                                 "fps": "" if speed is None else speed})
        s = tracker.summary()
        writer.writerow({"tracker": tracker.name, "seed": "", "sequence": "ALL", "file": "", "frames": s["frames"],
                         "missing_frames": s["missing_frames"],
                         **{k: "" if s[k] is None else s[k] for k in SCORE_NAMES},
                         "fps": "" if s["fps"] is None else s["fps"], "sequences": s["sequences"]})
    for row in attribute_rows:
        writer.writerow(row)
    return io.write_text(path, buffer.getvalue())
