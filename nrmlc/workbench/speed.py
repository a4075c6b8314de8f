"""Speed beside accuracy (``nrmlc evaluate ... --speed-plot OUT.png``): success AUC against fps.

The fps of a tracker is what its results record, over the scored sequences that record it
(:attr:`nrmlc.workbench.compare.TrackerScores.fps`: total frames over total time): the ``fps`` of the OTB
toolkit's ``.mat`` files (measured by each tracker's authors, on their machines) or the
``fps`` of each run in a ``nrmlc benchmark`` folder's ``benchmark.json``. Plain ``<Seq>.txt``
folders record none: such a tracker is left out of the plot, with a note.
"""
from __future__ import annotations

import io as text_io
from pathlib import Path

from nrmlc import io
from nrmlc.errors import DataError


def plot_speed(comparison, path) -> tuple[Path, list[str]]:
    """Success AUC against fps (log x axis), one labelled point per tracker with a known fps.

    Returns
    -------
    path : Path
    notes : list of str
        The trackers left out (no recorded fps).

    Raises
    ------
    DataError
        When no tracker records its speed.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    timed = [(t, t.summary()) for t in comparison.trackers if t.fps is not None]
    untimed = [t.name for t in comparison.trackers if t.fps is None]
    if not timed:
        raise DataError(f"--speed-plot {path}: no tracker's results record their speed (fps is known for "
                        f"OTB .mat results and 'nrmlc benchmark' folders)")
    figure, axis = plt.subplots(figsize=(7.5, 5))
    for i, (tracker, summary) in enumerate(sorted(timed, key=lambda p: -p[1]["success_auc"])):
        axis.scatter(tracker.fps, summary["success_auc"], s=40, color=f"C{i % 10}", zorder=3)
        label = tracker.name
        if summary["fps_sequences"] < summary["sequences"]:
            label += f" (fps of {summary['fps_sequences']}/{summary['sequences']})"
        # Alternate above and below: trackers of one family often sit side by side.
        axis.annotate(label, (tracker.fps, summary["success_auc"]), textcoords="offset points",
                      xytext=(5, 4 if i % 2 == 0 else -11), fontsize=8)
    axis.set_xscale("log")
    n = len(comparison.sequences)
    axis.set(xlabel="frames per second (log scale; as recorded with each tracker's results)",
             ylabel="success AUC", title=f"Accuracy and speed ({n} sequence{'s' if n != 1 else ''})")
    axis.grid(True, which="both", alpha=0.3)
    low = min(s["success_auc"] for _, s in timed)
    axis.set_ylim(max(0.0, low - 0.05), min(1.0, max(s["success_auc"] for _, s in timed) + 0.05))
    if untimed:
        figure.text(0.01, 0.01, f"no fps recorded: {', '.join(untimed)}", fontsize=7, color="0.4")
    figure.tight_layout()
    buffer = text_io.BytesIO()
    figure.savefig(buffer, format=Path(path).suffix.lstrip(".").lower(), dpi=130)
    plt.close(figure)
    notes = [f"--speed-plot: left out {', '.join(untimed)} (no fps recorded)"] if untimed else []
    return io.write_bytes(path, buffer.getvalue()), notes
