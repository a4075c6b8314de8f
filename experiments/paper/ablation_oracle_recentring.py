"""Gap evidence: is accuracy lost within a frame, or over many frames?

Every ``R`` frames the tracker's estimate is moved to the ground truth
(:func:`experiments.instrumented.move_to`); its templates, its random draws and its
template updates are its own. The box scored for each frame is still the
tracker's estimate, made from particles drawn around the previous state.

- ``R = 1``: every frame starts from the true box of the frame before, so the
  score measures the per-frame model alone (particle sampling, patches,
  coding, confidence) with no accumulated error;
- ``R = 10, 50``: errors may accumulate for at most that many frames;
- free: the ordinary default runs (Table II's, shared through the cache).

If ``R = 1`` is near the paper's Table II while the free runs are far below
it, the per-frame model is not what misses the paper's numbers: the loss comes
from errors that accumulate (drift, then loss of lock with no recovery). This
is diagnostic evidence only. The ground truth is used to place the estimate,
never to choose a parameter, and no default comes from it.

Outputs ``figures/ablation_oracle_recentring.{png,csv,json}``.
"""
from __future__ import annotations


import numpy as np

from experiments import paper_numbers as paper
from experiments.grid import script_entry, section
from experiments.instrumented import DiagnosticRun
from experiments.sequence_sets import paper_name
from experiments.tables import fmt, mean_std, save_figure, write_csv
from nrmlc import io

STEM = "ablation_oracle_recentring"
TITLE = "Re-centring on the ground truth every R frames: per-frame model vs accumulated error"

#: Re-centring periods in frames; 0 is the free (ordinary) run.
PERIODS = (1, 10, 50, 0)


def period_label(period: int) -> str:
    return "free" if period == 0 else f"R = {period}"


def _specs(context, sequences, period: int) -> list:
    specs = context.specs(sequences, context.base_params, context.ablation_seeds,
                          label=f"re-centring: {period_label(period)}")
    return [DiagnosticRun.of(spec, recentre_every=period) for spec in specs]


def runs(context) -> list:
    """Every period on every given sequence, sweep seeds (the free runs are Table II's)."""
    return [spec for period in PERIODS for spec in _specs(context, context.paper_sequences(), period)]


def collect(context) -> dict:
    rows = []
    for sequence in context.paper_sequences():
        row = {"sequence": sequence.name, "paper_name": paper_name(sequence.name)}
        for period in PERIODS:
            specs = _specs(context, [sequence], period)
            evaluations = context.evaluate(specs)
            key = period_label(period)
            row[key], row[f"{key} std"] = mean_std(e.mean_overlap for e in evaluations)
            row[f"{key} cle"] = mean_std(e.mean_center_error for e in evaluations)[0]
        row["paper"] = paper.OVERLAP.get(row["paper_name"], {}).get("Ours")
        rows.append(row)
    groups = {"paper's sequences": [r for r in rows if r["paper_name"] is not None],
              "other sequences": [r for r in rows if r["paper_name"] is None]}
    averages = {}
    for group, members in groups.items():
        if members:
            averages[group] = {key: float(np.mean([r[key] for r in members])) for key in map(period_label, PERIODS)}
            papers = [r["paper"] for r in members if r["paper"] is not None]
            averages[group]["paper"] = float(np.mean(papers)) if papers and len(papers) == len(members) else None
    return {"rows": rows, "averages": averages, "periods": list(PERIODS), "seeds": list(context.ablation_seeds)}


def plot(data: dict, path) -> None:
    """One labelled line per sequence over R = 1, 10, 50 and free, the paper's Table II value
    beside it (a star), and the averages in black."""
    import matplotlib.pyplot as plt

    labels = [period_label(p) for p in data["periods"]]
    positions = np.arange(len(labels))
    fig, ax = plt.subplots(figsize=(8.6, 4.2))
    colours = plt.get_cmap("tab10")
    for i, row in enumerate(data["rows"]):
        colour = colours(i % 10)
        name = row["sequence"] if row["paper_name"] in (None, row["sequence"]) else \
            f"{row['sequence']} ({row['paper_name']})"
        ax.plot(positions, [row[k] for k in labels], marker="o", ms=4, lw=1.2, color=colour, label=name)
        if row["paper"] is not None:
            ax.plot([len(labels)], [row["paper"]], marker="*", ms=9, ls="", color=colour)
    for group, style in (("paper's sequences", "k-"), ("other sequences", "k:")):
        if group in data["averages"]:
            average = data["averages"][group]
            ax.plot(positions, [average[k] for k in labels], style, lw=2.6, label=f"average, {group}")
            if average.get("paper") is not None:
                ax.plot([len(labels)], [average["paper"]], marker="*", ms=13, ls="", color="black")
    has_paper = any(row["paper"] is not None for row in data["rows"])
    ticks = labels + (["paper\n(Table II)"] if has_paper else [])
    ax.set_xticks(np.arange(len(ticks)))
    ax.set_xticklabels(ticks)
    ax.set_xlim(-0.3, len(ticks) - 0.7)
    ax.set_xlabel("estimate moved to the ground truth every R frames (free: never)")
    ax.set_ylabel("mean overlap")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    seeds = data["seeds"]
    ax.set_title("Per-frame model vs accumulated error"
                 + (f", seed {seeds[0]}" if len(seeds) == 1 else f", mean over seeds {seeds}"), fontsize=9)
    save_figure(fig, path, dpi=100)


def report(context, data: dict) -> dict:
    """Write the numbers (CSV/JSON); returns the report section (``title``, ``figures``, ``markdown``)."""
    labels = [period_label(p) for p in data["periods"]]
    header = ["sequence"] + labels + [f"{k} std" for k in labels] + [f"{k} cle" for k in labels] + ["paper"]
    write_csv(context.output(STEM, ".csv"), header, [[r[k] for k in header] for r in data["rows"]])
    io.write_json(context.output(STEM, ".json"), dict(data, title=TITLE))

    text = [f"Mean overlap (± std over seeds {data['seeds']}) when the estimate is moved to the ground truth "
            "every R frames; free = the ordinary default runs. Diagnostic only."
            + (f" First {context.max_frames} frames of each sequence only." if context.max_frames else ""), "",
            "| sequence | " + " | ".join(labels) + f" | paper{' (full seq.)' if context.max_frames else ''} |",
            "|---" * (len(labels) + 2) + "|"]
    for r in data["rows"]:
        cells = [fmt(r[k], 2, r[f"{k} std"]) for k in labels]
        text.append(f"| {r['sequence']} | " + " | ".join(cells) + f" | {fmt(r['paper'], 2)} |")
    for group, values in data["averages"].items():
        text.append(f"| average, {group} | " + " | ".join(fmt(values[k], 3) for k in labels)
                    + f" | {fmt(values['paper'], 3)} |")
    return section(TITLE, STEM, text)


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
