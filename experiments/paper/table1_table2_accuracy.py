"""Tables I and II: centre location error and overlap per sequence, with OTB success/precision plots.

NRMLC runs with the context's base parameters (the 'default' preset) on every given sequence, one
run per seed (mean ± std over ``context.seeds``). Beside it:

- the paper's own NRMLC column ("Ours (paper)");
- the OpenCV trackers run live on the same frames (:mod:`experiments.peers`);
- the paper's lineage run live on the same frames, one run per seed as NRMLC ("IVT (live)",
  "ASLA (live)", "L1 (live)", "L1APG (live)", "MTT (live)": :data:`experiments.peers.LINEAGE_LIVE`;
  MTT on the first seed only, :data:`experiments.peers.LINEAGE_SEED_LIMIT`);
- the paper's eight peers: scored from the shipped per-frame results where
  they fit our frames, otherwise the paper's printed number, marked with a
  dagger (†).

Rows: the paper's sequences that are given (in the paper's order), then the
other given sequences in a separate block. Averages are over the rows shown;
the paper's printed average (all 12 sequences) is added for reference.

Outputs ``figures/table1_table2_accuracy.{png,csv,json}``; the PNG holds the
OTB success and precision plots (mean over sequences of the per-sequence
curves; legend with AUC and precision at 20 px).
"""
from __future__ import annotations

import math

import numpy as np

from experiments import paper_numbers as paper
from experiments import peers
from experiments.grid import params_differences, score, script_entry
from experiments.sequence_sets import paper_name
from experiments.tables import fmt, mean_std, save_figure, write_csv
from nrmlc import io
from nrmlc.workbench.metrics import PRECISION_THRESHOLDS, SUCCESS_THRESHOLDS
from nrmlc.tracker.params import TrackerParams

STEM = "table1_table2_accuracy"
TITLE = "Tables I and II: centre location error and overlap rate"

OURS = "Ours"
OURS_PAPER = "Ours (paper)"
DAGGER = "†"
MIXED = "‡"


def _specs(context) -> list:
    paper_seqs, other_seqs = context.ordered_sequences()
    return context.specs(paper_seqs + other_seqs, seeds=context.seeds, label="table")


def runs(context) -> list:
    """NRMLC with the base parameters on every given sequence, every main seed, the live
    OpenCV runs (every available tracker on every given sequence) and the live lineage's (every
    seed)."""
    sequences = context.sequences()
    return _specs(context) + peers.live_specs(context, sequences) + peers.lineage_specs(context, sequences)


def _columns(live: list[str]) -> list[str]:
    return ([OURS, OURS_PAPER] + [peers.live_label(name) for name in live]
            + [peers.lineage_label(name) for name in peers.LINEAGE_LIVE] + list(paper.PEERS))


def _measured_columns(data: dict) -> list[str]:
    """The columns run here on every sequence: the OpenCV trackers and the lineage, live."""
    return [peers.live_label(n) for n in data["live"]] + [peers.lineage_label(n) for n in peers.LINEAGE_LIVE]


def _cell(evaluations, source: str, fps=None) -> dict:
    """Scores of one (sequence, tracker) from one or more evaluations (seeds)."""
    overlap, overlap_std = mean_std(e.mean_overlap for e in evaluations)
    cle, cle_std = mean_std(e.mean_center_error for e in evaluations)
    auc, _ = mean_std(e.success_auc for e in evaluations)
    p20, _ = mean_std(e.precision_20 for e in evaluations)
    return {"source": source, "overlap": overlap, "overlap_std": overlap_std if len(evaluations) > 1 else None,
            "cle": cle, "cle_std": cle_std if len(evaluations) > 1 else None, "success_auc": auc,
            "precision_20": p20, "n_runs": len(evaluations), "n_frames": evaluations[0].n_frames + 1,
            "n_evaluated": evaluations[0].n_frames,
            "success": np.mean([e.success for e in evaluations], axis=0),
            "precision": np.mean([e.precision for e in evaluations], axis=0), "fps": fps}


def _paper_cell(name: str, tracker: str) -> dict:
    return {"source": "paper", "overlap": paper.OVERLAP[name][tracker], "cle": paper.CLE[name][tracker],
            "overlap_std": None, "cle_std": None}


def collect(context) -> dict:
    """Every number of the tables: ``cells[sequence][column]``, per-seed averages, fps, notes."""
    paper_seqs, other_seqs = context.ordered_sequences()
    sequences = paper_seqs + other_seqs
    specs = _specs(context)
    results = context.run(specs)
    live_names = peers.live_trackers()
    live = peers.live_results(context, sequences)
    lineage = peers.lineage_results(context, sequences)
    shipped, notes = peers.shipped_for(context, sequences)
    columns = _columns(live_names)

    cells: dict = {s.name: {} for s in sequences}
    per_seed: dict = {s.name: {} for s in sequences}  # sequence -> seed -> (overlap, cle)
    frames_total, seconds_total = 0, 0.0
    for sequence in sequences:
        mine = [(spec, r) for spec, r in zip(specs, results) if spec.sequence is sequence]
        evaluations = [score(r.boxes, sequence) for _, r in mine]
        frames = sum(len(r.boxes) - 1 for _, r in mine)
        seconds = sum(r.seconds_tracking for _, r in mine)
        frames_total += frames
        seconds_total += seconds
        cells[sequence.name][OURS] = _cell(evaluations, "measured", frames / seconds if seconds > 0 else None)
        cells[sequence.name][OURS]["seeds"] = [spec.seed for spec, _ in mine]
        for (spec, _), e in zip(mine, evaluations):
            per_seed[sequence.name][spec.seed] = (e.mean_overlap, e.mean_center_error)
        name = paper_name(sequence.name)
        if name is not None:
            cells[sequence.name][OURS_PAPER] = _paper_cell(name, "Ours")
        n = context.n_frames(sequence)
        for tracker in live_names:
            result = live[tracker][sequence.name]
            cells[sequence.name][peers.live_label(tracker)] = _cell([score(result.boxes, sequence, n)], "live",
                                                                   result.fps_tracking)
        for column, by_sequence in lineage.items():
            results_ = by_sequence[sequence.name]
            cells[sequence.name][column] = _cell([score(r.boxes, sequence, n) for r in results_], "live",
                                                 _fps(results_))
        for tracker in paper.PEERS:
            if sequence.name in shipped.get(tracker, {}):
                result = shipped[tracker][sequence.name]
                cell = _cell([score(result.boxes, sequence, n)], "shipped")
                cell["file"] = result.source
                cells[sequence.name][tracker] = cell
            elif name is not None:
                cells[sequence.name][tracker] = _paper_cell(name, tracker)

    fps = {OURS: frames_total / seconds_total if seconds_total > 0 else None, OURS_PAPER: paper.FPS["Ours"]}
    for tracker in live_names:
        runs_ = list(live[tracker].values())
        frames = sum(len(r.boxes) - 1 for r in runs_)
        seconds = sum(r.seconds_tracking for r in runs_)
        fps[peers.live_label(tracker)] = frames / seconds if seconds > 0 else None
    for column, by_sequence in lineage.items():
        fps[column] = _fps([r for results_ in by_sequence.values() for r in results_])
    for tracker in paper.PEERS:
        fps[tracker] = paper.FPS[tracker]

    blocks = []
    if paper_seqs:
        blocks.append(("paper", "the paper's sequences", paper_seqs))
    if other_seqs:
        label = "synthetic sequences" if context.is_synthetic else "other sequences (not in the paper)"
        blocks.append(("other", label, other_seqs))
    averages = {key: _averages(cells, per_seed, seqs, columns) for key, _, seqs in blocks}
    data = {"columns": columns, "live": live_names, "cells": cells, "per_seed": per_seed, "fps": fps,
            "blocks": [(key, label, [s.name for s in seqs]) for key, label, seqs in blocks],
            "averages": averages, "notes": notes, "paper_names": {s.name: paper_name(s.name) for s in sequences},
            "seeds": list(context.seeds),
            "frames": {s.name: context.n_frames(s) for s in sequences},
            "grid_frames": sum(s.frames() for s in specs), "max_frames": context.max_frames}
    data["curves"] = _panels(data)
    return data


def _fps(results) -> float | None:
    """Frames after the first over the tracking time, summed over ``results``."""
    seconds = sum(r.seconds_tracking for r in results)
    return sum(len(r.boxes) - 1 for r in results) / seconds if seconds > 0 else None


def _averages(cells, per_seed, sequences, columns) -> dict:
    """Average of each column over ``sequences``; marks whether paper numbers went into it."""
    out = {}
    names = [s.name for s in sequences]
    for column in columns:
        present = [cells[n][column] for n in names if column in cells[n]]
        if not present:
            continue
        sources = {c["source"] for c in present}
        entry = {"overlap": float(np.mean([c["overlap"] for c in present])),
                 "cle": float(np.nanmean([c["cle"] for c in present])) if any(
                     c["cle"] is not None and math.isfinite(c["cle"]) for c in present) else math.nan,
                 "n_sequences": len(present), "of": len(names), "sources": sorted(sources),
                 "overlap_std": None, "cle_std": None}
        if column == OURS:
            # Spread over seeds of the across-sequence average (what a rerun with another seed would move).
            seeds = sorted(set.intersection(*(set(per_seed[n]) for n in names)))
            by_seed_overlap = [np.mean([per_seed[n][s][0] for n in names]) for s in seeds]
            by_seed_cle = [np.nanmean([per_seed[n][s][1] for n in names]) for s in seeds]
            if len(seeds) > 1:
                entry["overlap_std"] = float(np.std(by_seed_overlap))
                entry["cle_std"] = float(np.std(by_seed_cle))
        out[column] = entry
    return out


#: Beside a paper number when our runs are cut to the first frames (``--max-frames``).
FULL = " (full seq.)"


def _marked(cell: dict, key: str, digits: int, capped: bool = False) -> str:
    if cell is None:
        return "–"
    text = fmt(cell.get(key), digits, cell.get(f"{key}_std"))
    sources = cell.get("sources", [cell.get("source")])
    if "paper" in sources:
        text += DAGGER if sources == ["paper"] else MIXED
        if capped:
            text += FULL
    if cell.get("of") and cell.get("n_sequences") != cell.get("of"):
        text += f" ({cell['n_sequences']}/{cell['of']})"
    return text


def markdown_table(data: dict, key: str, digits: int, title: str, with_fps: bool) -> str:
    columns = data["columns"]
    capped = bool(data.get("max_frames"))
    if capped:
        title += f" (ours: first {data['max_frames']} frames of each sequence only)"
    lines = [f"**{title}**", "", "| Sequence | " + " | ".join(columns) + " |",
             "|---" * (len(columns) + 1) + "|"]
    for block, label, names in data["blocks"]:
        lines.append(f"| *{label}* |" + " |" * len(columns))
        for name in names:
            shown = name if data["paper_names"].get(name) in (None, name) else f"{name} ({data['paper_names'][name]})"
            lines.append(f"| {shown} | " + " | ".join(_marked(data["cells"][name].get(c), key, digits, capped)
                                                   for c in columns) + " |")
        averages = data["averages"][block]
        lines.append(f"| **avg. ({len(names)} seq.)** | " + " | ".join(
            _marked(averages.get(c), key, digits, capped) for c in columns) + " |")
    table = paper.OVERLAP_AVERAGE if key == "overlap" else paper.CLE_AVERAGE
    row = ["–"] * len(columns)
    for i, c in enumerate(columns):
        tracker = "Ours" if c == OURS_PAPER else c
        if c != OURS and tracker in table:
            row[i] = fmt(table[tracker], digits) + DAGGER + (FULL if capped else "")
    lines.append("| paper avg. (all 12 seq.) | " + " | ".join(row) + " |")
    if with_fps:
        row = []
        for c in columns:
            value = data["fps"].get(c)
            mark = DAGGER if c in paper.PEERS or c == OURS_PAPER else ""
            row.append(fmt(value, 2) + mark if value is not None else "–")
        lines.append("| fps | " + " | ".join(row) + " |")
    return "\n".join(lines)


def _curves(data: dict, names: list[str], columns: list[str]) -> dict:
    """Mean success/precision curves over ``names`` for every column with at least one sequence."""
    curves = {}
    for column in columns:
        have = [n for n in names if "success" in data["cells"][n].get(column, {})]
        if not have:
            continue
        success = np.mean([data["cells"][n][column]["success"] for n in have], axis=0)
        precision = np.mean([data["cells"][n][column]["precision"] for n in have], axis=0)
        curves[column] = {"success": success, "precision": precision, "auc": float(success.mean()),
                          "precision_20": float(precision[20]), "sequences": have, "of": len(names)}
    return curves


def _panels(data: dict) -> dict:
    """{panel label: (sequence names, curves)}: all given sequences with NRMLC and the live
    trackers, and the paper's given sequences with every tracker that has a value there."""
    all_names = [n for _, _, names in data["blocks"] for n in names]
    live_cols = _measured_columns(data)
    panels = {"all given sequences": (all_names, _curves(data, all_names, [OURS] + live_cols))}
    paper_names = next((names for key, _, names in data["blocks"] if key == "paper"), [])
    if paper_names:
        panels["the paper's given sequences"] = (
            paper_names, _curves(data, paper_names, [OURS] + live_cols + list(paper.PEERS)))
    return panels


def plot(data: dict, path) -> None:
    """Success and precision plots: all given sequences (top), the paper's given sequences (bottom)."""
    import matplotlib.pyplot as plt

    live_cols = _measured_columns(data)
    columns = [OURS] + live_cols + list(paper.PEERS)
    panels = data["curves"]
    # Legends stand right of their panels: with a dozen trackers inside, they covered the curves.
    fig, axes = plt.subplots(len(panels), 2, figsize=(15, 4.6 * len(panels)), squeeze=False)
    # One colour per tracker: its live run solid, its shipped file or printed number dashed.
    families = list(dict.fromkeys(c.split(" (")[0] for c in columns))
    colours = plt.get_cmap("tab10" if len(families) <= 10 else "tab20")
    for row, (label, (names, curves)) in enumerate(panels.items()):
        order = sorted(curves, key=lambda c: -curves[c]["auc"])
        for column in order:
            curve = curves[column]
            style = dict(color=colours(families.index(column.split(" (")[0]) % colours.N), lw=2.4 if column == OURS else 1.5,
                         ls="-" if column == OURS or column in live_cols else "--")
            cover = "" if len(curve["sequences"]) == curve["of"] else f" [{len(curve['sequences'])}/{curve['of']} seq.]"
            axes[row, 0].plot(SUCCESS_THRESHOLDS, curve["success"], label=f"{column} [{curve['auc']:.3f}]{cover}",
                              **style)
            axes[row, 1].plot(PRECISION_THRESHOLDS, curve["precision"],
                              label=f"{column} [{curve['precision_20']:.3f}]{cover}", **style)
        axes[row, 0].set(xlabel="overlap threshold", ylabel="success rate", xlim=(0, 1), ylim=(0, 1.02),
                         title=f"Success plot, {label} ({len(names)})\nlegend: AUC")
        axes[row, 1].set(xlabel="location error threshold (px)", ylabel="precision", xlim=(0, 50), ylim=(0, 1.02),
                         title=f"Precision plot, {label} ({len(names)})\nlegend: precision at 20 px")
        for ax in axes[row]:
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    save_figure(fig, path, dpi=110)


def _csv_rows(data: dict) -> list:
    rows = []
    for block, _, names in data["blocks"]:
        for name in names:
            for column in data["columns"]:
                cell = data["cells"][name].get(column)
                if cell is None:
                    continue
                rows.append([block, name, data["paper_names"].get(name) or "", column, cell["source"],
                             cell.get("file", ""), cell["cle"], cell.get("cle_std"), cell["overlap"],
                             cell.get("overlap_std"), cell.get("success_auc"), cell.get("precision_20"),
                             cell.get("n_runs"), cell.get("n_frames"), cell.get("fps")])
        for column, avg in data["averages"][block].items():
            rows.append([block, "avg.", "", column, "+".join(avg["sources"]), "", avg["cle"], avg["cle_std"],
                         avg["overlap"], avg["overlap_std"], None, None, avg["n_sequences"], None, None])
    for column in data["columns"]:
        rows.append(["fps", "", "", column, "paper" if column in paper.PEERS or column == OURS_PAPER else "measured",
                     "", None, None, None, None, None, None, None, None, data["fps"].get(column)])
    return rows


def _json(data: dict) -> dict:
    curves = {label: cs for label, (_, cs) in data["curves"].items()}
    cells = {n: {c: {k: v for k, v in cell.items() if k not in ("success", "precision")} for c, cell in row.items()}
             for n, row in data["cells"].items()}
    return {"title": TITLE, "seeds": data["seeds"], "frames": data["frames"], "columns": data["columns"],
           "blocks": data["blocks"], "cells": cells, "averages": data["averages"], "fps": data["fps"],
           "per_seed": {n: {str(s): {"overlap": v[0], "cle": v[1]} for s, v in d.items()}
                        for n, d in data["per_seed"].items()},
           "curves": {label: {c: dict(v, success=list(v["success"]), precision=list(v["precision"]))
                              for c, v in cs.items()} for label, cs in curves.items()},
           "success_thresholds": list(SUCCESS_THRESHOLDS), "precision_thresholds": list(PRECISION_THRESHOLDS),
           "notes": data["notes"],
           "paper": {"cle": paper.CLE, "overlap": paper.OVERLAP, "cle_average": paper.CLE_AVERAGE,
                     "overlap_average": paper.OVERLAP_AVERAGE, "fps": paper.FPS}}


def report(context, data: dict) -> dict:
    """Write the tables' numbers (CSV, JSON); returns the report section."""
    curves = {label: cs for label, (_, cs) in data["curves"].items()}
    write_csv(context.output(STEM, ".csv"),
              ["block", "sequence", "paper_name", "tracker", "source", "file", "cle", "cle_std", "overlap",
               "overlap_std", "success_auc", "precision_20", "n_runs", "n_frames", "fps"], _csv_rows(data))
    io.write_json(context.output(STEM, ".json"), _json(data))

    names = ", ".join(f"{n} ({data['frames'][n]} frames)" for _, _, ns in data["blocks"] for n in ns)
    paper_block = next((names_ for key, _, names_ in data["blocks"] if key == "paper"), [])
    missing = [s for s in paper.SEQUENCES if s not in {data["paper_names"][n] for n in paper_block}]
    changed = params_differences(context.base_params, TrackerParams())
    setting = "the 'default' preset" + ("" if not changed else " except " + ", ".join(
        f"{k} = {v}" for k, v in sorted(changed.items())))
    text = [f"NRMLC with {setting}, mean ± std over seeds {data['seeds']} on: {names}."]
    if context.is_synthetic:
        text.append("Synthetic suite: none of the paper's sequences, so no per-sequence paper numbers; the "
                    "paper's averages over its 12 real sequences are shown for reference only.")
    elif missing:
        text.append(f"The paper's {', '.join(missing)} are not among the sequences run: their rows are left out; "
                    f"each average is over the rows shown, and the paper's own average over all 12 is added.")
    renamed = [f"{n} ({data['paper_names'][n]})" for n in paper_block if data["paper_names"][n] != n]
    if renamed:
        text.append(f"{', '.join(renamed)}: the sparse-tracker version of the paper's sequence (a few frames more, "
                    "keyframe ground truth), so the paper's numbers on its row are on a slightly different video.")
    live = ", ".join(peers.live_label(n) for n in data["live"])
    text.append(f"{live}: run live on the same frames (deterministic, one run; OpenCV {peers.opencv_version()}"
                f"{'' if len(data['live']) > 1 else '; TrackerKCF/TrackerCSRT need opencv-contrib-python'}). "
                "Paper peers: scored here from the shipped per-frame results where they fit our frames; "
                f"`{DAGGER}` = the paper's number (not measured here); `{MIXED}` = average mixing measured and "
                "paper numbers; `(n/N)` = average over the n of N sequences that have a value. "
                "Ours (paper) is the paper's NRMLC column. fps: tracking time only (frame decoding excluded), "
                "Python on this machine with runs in parallel workers; the paper's fps are MATLAB on a 2.13 GHz Xeon.")
    lineage = ", ".join(peers.lineage_label(n) for n in peers.LINEAGE_LIVE)
    text.append(f"{lineage}: the paper's lineage run live here as the OTB benchmark's MATLAB runs it "
                "(`nrmlc/lineage/`; how close to the benchmark's own files: docs/research/lineage-fidelity.md), "
                f"mean ± std over seeds {data['seeds']} as ours"
                + "".join(f" ({peers.lineage_label(name)}: its first {limit} seed{'s' if limit > 1 else ''} only, "
                          "for its cost)" for name, limit in peers.LINEAGE_SEED_LIMIT.items()
                          if limit < len(data["seeds"]))
                + "; the columns without '(live)' are the shipped files or the paper's numbers.")
    text.append("")
    text.append(markdown_table(data, "cle", 1, "Table I: centre location error (px, lower is better)", False))
    text.append("")
    text.append(markdown_table(data, "overlap", 2, "Table II: mean overlap rate (higher is better)", True))
    if data["notes"]:
        text.append("")
        text.append("Shipped peer results not used:")
        text += [f"- {note}" for note in data["notes"]]
    text.append("")
    for label, cs in curves.items():
        summary = "; ".join(f"{c} AUC {v['auc']:.3f}, P@20 {v['precision_20']:.3f}"
                            + ("" if len(v["sequences"]) == v["of"] else f" ({len(v['sequences'])}/{v['of']} seq.)")
                            for c, v in sorted(cs.items(), key=lambda kv: -kv[1]["auc"]))
        text.append(f"Success/precision over {label}: {summary}.")
    return {"title": TITLE, "figures": [f"{STEM}.png"], "markdown": "\n".join(text)}


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
