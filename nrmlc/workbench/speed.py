"""Speed beside accuracy (``nrmlc evaluate ... --speed-plot OUT.png``): success AUC against fps.

The fps of a tracker is what its results record, over the scored sequences that record it
(:attr:`nrmlc.workbench.score.TrackerScores.fps`: total frames over total time): the ``fps`` of the OTB
toolkit's ``.mat`` files (measured by each tracker's authors, on their machines) or the
``fps`` of each run in a ``nrmlc benchmark`` folder's ``benchmark.json``. Plain ``<Seq>.txt``
folders record none: such a tracker is left out of the plot, with a note.
"""
from __future__ import annotations

import math
from pathlib import Path

from nrmlc import io
from nrmlc.errors import DataError


def fps_tick_mantissas(low: float, high: float) -> tuple[float, ...]:
    """The mantissas of the labelled fps ticks between ``low`` and ``high`` (> 0): each decade's
    1, 2, 5 over up to 2.5 decades, only the decades over more, every 1-9 within 0.6 of a decade.

    Matplotlib's own log labels switch to labelling minor ticks (``3x10^1``, ``4x10^1``) over about
    1.5 decades, where they run into each other; these keep one plain number every 0.3 decades at least.
    """
    decades = math.log10(high / low)
    if decades > 2.5:
        return (1.0,)
    if decades > 0.6:
        return (1.0, 2.0, 5.0)
    return tuple(float(m) for m in range(1, 10))


def _label_fps_axis(axis) -> None:
    """Plain-number labels (``0.5``, ``2``, ``50``) on :func:`fps_tick_mantissas`, unlabelled minor ticks."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    low, high = axis.get_xlim()
    axis.xaxis.set_major_locator(LogLocator(base=10, subs=fps_tick_mantissas(low, high)))
    axis.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.xaxis.set_minor_locator(LogLocator(base=10, subs=tuple(range(1, 10))))
    axis.xaxis.set_minor_formatter(NullFormatter())


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
    _label_fps_axis(axis)
    n = len(comparison.sequences)
    axis.set(xlabel="frames per second (log scale; as recorded with each tracker's results)",
             ylabel="success AUC", title=f"Accuracy and speed ({n} sequence{'s' if n != 1 else ''})")
    axis.grid(True, which="both", alpha=0.3)
    low = min(s["success_auc"] for _, s in timed)
    axis.set_ylim(max(0.0, low - 0.05), min(1.0, max(s["success_auc"] for _, s in timed) + 0.05))
    if untimed:
        figure.text(0.01, 0.01, f"no fps recorded: {', '.join(untimed)}", fontsize=7, color="0.4")
    figure.tight_layout()
    notes = [f"--speed-plot: left out {', '.join(untimed)} (no fps recorded)"] if untimed else []
    return io.write_figure(figure, path), notes
