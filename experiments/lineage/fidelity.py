"""Are the live lineage trackers the authors' trackers? Live runs against the OTB benchmark's own files.

For each tracker of :data:`nrmlc.lineage.TRACKERS` that the OTB benchmark shipped results for (IVT,
ASLA), on every sequence at hand whose benchmark file fits it (``otb_result_boxes``: one box per
frame, the same first box), the live tracker runs with 5 seeds through the run cache (the same
runs ``nrmlc benchmark --tracker NAME`` makes) and is scored as the file is: mean overlap and
success AUC, OTB one-pass, frame 0 skipped (speed is ``make bench``'s, not this table's). The benchmark ran each tracker once, with MATLAB's
``rand('state', 0)``; its number is one draw from the distribution our seeds sample, so a
sequence is *within the seeds' spread* when the file's overlap lies in the live runs' range.

Writes ``<out>/lineage_fidelity.csv`` (one row per tracker and sequence), ``.json`` (the same
with the means) and ``.png`` (live against file, per sequence).

    python -m experiments.lineage.fidelity --data ../shared/data/sequences ../devdata/sequences \\
        --otb-results ../devdata/otb_results --out figures/lineage
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from experiments.tables import save_figure, write_csv
from nrmlc.data import list_sequences
from nrmlc.io import write_json
from nrmlc.workbench.metrics import evaluate
from nrmlc.workbench.otb_results import otb_result_boxes, otb_trackers
from nrmlc.workbench.run_cache import RunCache
from nrmlc.workbench.trackers import ImportedTracker

STEM = "lineage_fidelity"
SEEDS = (0, 1, 2, 3, 4)
COLUMNS = ["tracker", "sequence", "frames", "file_overlap", "file_auc", "live_overlap_mean", "live_overlap_std",
           "live_overlap_min", "live_overlap_max", "live_auc_mean", "within_seed_range"]


def pairs(data_roots, otb_folder, trackers):
    """``(tracker, sequence, file boxes)`` for every sequence of ``data_roots`` with a fitting file."""
    found, seen = [], set()
    shipped = {name.lower(): name for name in otb_trackers(otb_folder)}
    for root in data_roots:
        for sequence in list_sequences(root):
            if sequence.name.lower() in seen:
                continue
            seen.add(sequence.name.lower())
            for tracker in trackers:
                if tracker not in shipped:
                    continue
                boxes, _, _ = otb_result_boxes(otb_folder, shipped[tracker], sequence)
                if boxes is not None:
                    found.append((tracker, sequence, boxes))
    return found


def run(data_roots, otb_folder, out, trackers=("ivt", "asla"), seeds=SEEDS, cache=None, jobs=None) -> dict:
    from nrmlc.lineage import TRACKERS

    trackers = [t for t in trackers if t in TRACKERS]
    found = pairs(data_roots, otb_folder, trackers)
    entries = {t: ImportedTracker(t) for t in trackers}
    jobs_of = [[entries[t].job(sequence, seed, None) for seed in seeds] for t, sequence, _ in found]
    cache = RunCache(cache)
    results = iter(cache.run([job for group in jobs_of for job in group], jobs=jobs))
    rows = []
    for tracker, sequence, file_boxes in found:
        runs = [next(results) for _ in seeds]
        live = [evaluate(r.boxes, sequence.groundtruth) for r in runs]
        shipped = evaluate(file_boxes, sequence.groundtruth)
        overlaps = np.array([e.mean_overlap for e in live])
        rows.append({
            "tracker": tracker.upper(), "sequence": sequence.name, "frames": len(sequence),
            "file_overlap": shipped.mean_overlap, "file_auc": shipped.success_auc,
            "live_overlap_mean": float(overlaps.mean()), "live_overlap_std": float(overlaps.std(ddof=1)),
            "live_overlap_min": float(overlaps.min()), "live_overlap_max": float(overlaps.max()),
            "live_auc_mean": float(np.mean([e.success_auc for e in live])),
            "within_seed_range": bool(overlaps.min() <= shipped.mean_overlap <= overlaps.max()),
            "_overlaps": overlaps,
        })
    summary = {}
    for tracker in sorted({row["tracker"] for row in rows}):
        mine = [row for row in rows if row["tracker"] == tracker]
        # the mean over sequences for each seed: their spread is the seeds' spread of the mean
        per_seed = np.mean([row.pop("_overlaps") for row in mine], axis=0)
        summary[tracker] = {
            "sequences": len(mine),
            "file_overlap": float(np.mean([row["file_overlap"] for row in mine])),
            "live_overlap": float(per_seed.mean()),
            "live_overlap_seed_std": float(per_seed.std(ddof=1)),
            "file_auc": float(np.mean([row["file_auc"] for row in mine])),
            "live_auc": float(np.mean([row["live_auc_mean"] for row in mine])),
            "within_seed_range": int(sum(row["within_seed_range"] for row in mine)),
        }
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / f"{STEM}.csv", COLUMNS, [[row[c] for c in COLUMNS] for row in rows])
    write_json(out / f"{STEM}.json", {"seeds": list(seeds), "data": [str(r) for r in data_roots],
                                      "otb_results": str(otb_folder), "summary": summary, "rows": rows})
    plot(rows, summary, out / f"{STEM}.png")
    return {"rows": rows, "summary": summary}


def plot(rows, summary, path) -> None:
    import matplotlib.pyplot as plt

    trackers = sorted(summary)
    fig, axes = plt.subplots(1, max(len(trackers), 1), figsize=(5 * max(len(trackers), 1), 4.6), squeeze=False)
    for ax, tracker in zip(axes[0], trackers):
        mine = [row for row in rows if row["tracker"] == tracker]
        x = np.array([row["file_overlap"] for row in mine])
        y = np.array([row["live_overlap_mean"] for row in mine])
        low = y - np.array([row["live_overlap_min"] for row in mine])
        high = np.array([row["live_overlap_max"] for row in mine]) - y
        ax.errorbar(x, y, yerr=[low, high], fmt="o", ms=4, capsize=2, color="tab:blue", ecolor="0.6")
        ax.plot([0, 1], [0, 1], color="0.3", lw=0.8, ls="--")
        s = summary[tracker]
        ax.set_title(f"{tracker}: {s['sequences']} sequences; mean overlap file {s['file_overlap']:.3f}, "
                     f"live {s['live_overlap']:.3f}", fontsize=9)
        ax.set_xlabel("OTB benchmark's file: mean overlap")
        ax.set_ylabel(f"live, {len(SEEDS)} seeds: mean (bars: range)")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_aspect("equal")
    save_figure(fig, path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", nargs="+", required=True, help="data roots (OTB layout)")
    parser.add_argument("--otb-results", required=True, help="the OTB benchmark's result files")
    parser.add_argument("--out", default="out/figures", help="output folder (default out/figures)")
    parser.add_argument("--trackers", default="ivt,asla")
    parser.add_argument("--cache", help="run cache (default .cache/runs)")
    parser.add_argument("--jobs", type=int)
    args = parser.parse_args(argv)
    result = run(args.data, args.otb_results, args.out, tuple(args.trackers.lower().split(",")),
                 cache=args.cache, jobs=args.jobs)
    for tracker, s in result["summary"].items():
        print(f"{tracker}: {s['sequences']} sequences, mean overlap file {s['file_overlap']:.3f}, live "
              f"{s['live_overlap']:.3f} +- {s['live_overlap_seed_std']:.3f} (seeds); AUC file {s['file_auc']:.3f}, "
              f"live {s['live_auc']:.3f}; file within the seeds' range on {s['within_seed_range']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
