"""Does NRMLC beat its lineage? NRMLC (the default and the ``paper`` preset) against the live IVT,
ASLA, L1 and L1-APG of :mod:`nrmlc.lineage`, on the same targets, in the same harness, with the same
seeds. MTT is not run here yet (its departure holds on development video, docs/DEVIATIONS.md; its
runs join with the next real-data grid).

The paper's central claim is that NRMLC beats the sparse and subspace trackers it comes from; its
Tables I and II print those trackers' numbers, some of them doubtful (Table II's ASLA on Deer is
0.60 where the OTB benchmark's own ASLA file gives 0.03). Here every tracker runs live, seeds 0-4
by default, through the run cache, and is scored as the benchmark scores (mean overlap, OTB one-pass,
frame 0 skipped, :func:`experiments.grid.score`).

Targets: the 36 development targets, as halves A and B (:mod:`experiments.sequence_sets`), and the
paper's nine apart (reported, never chosen on). Seeds are not shared between trackers (one seed of
NRMLC has nothing to do with the same seed of IVT), so the comparison is per target: the mean over
seeds of one tracker against the mean over seeds of the other, and over a group of targets the mean
of those differences with its standard error over targets, and the targets won and lost.

Writes ``<out>/lineage_versus.csv`` (one row per target: each tracker's mean overlap over seeds),
``.json`` (the same with each seed's overlap, the group means and the differences) and ``.png``.

    python -m experiments.lineage.versus --out figures/lineage
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from experiments.development.devset import configuration_runs, development_sequences, overlaps_of, parse_roots
from experiments.grid import score
from experiments.sequence_sets import DEVELOPMENT_A, DEVELOPMENT_B, PAPER_SEQUENCES
from experiments.tables import save_figure, write_csv
from nrmlc.errors import NrmlcError
from nrmlc.io import write_json
from nrmlc.tracker.params import TrackerParams
from nrmlc.workbench.benchmark import parse_seeds
from nrmlc.workbench.run_cache import RunCache
from nrmlc.workbench.trackers import ImportedTracker

STEM = "lineage_versus"
NRMLC_CONFIGURATIONS = {"NRMLC": "default", "NRMLC (paper preset)": "paper"}
LINEAGE = {"IVT": "ivt", "ASLA": "asla", "L1": "l1", "L1APG": "l1apg"}
#: Differences of per-target means smaller than this are ties (rounding of equal scores).
TIE = 1e-9
GROUPS = {"A": DEVELOPMENT_A, "B": DEVELOPMENT_B, "paper's nine": PAPER_SEQUENCES}


def lineage_overlaps(cache: RunCache, short_name: str, sequences, seeds, max_frames, jobs) -> dict:
    """{target: [mean overlap of each seed]} of a live lineage tracker (computed where the cache lacks them)."""
    entry = ImportedTracker(short_name)
    jobs_of = [entry.job(sequence, seed, max_frames) for sequence in sequences for seed in seeds]
    results = iter(cache.run(jobs_of, jobs=jobs))
    return {sequence.name: [float(score(next(results).boxes, sequence, max_frames).mean_overlap) for _ in seeds]
            for sequence in sequences}


def lineage_columns_from(path, names, seeds, max_frames) -> dict:
    """{lineage tracker: {target: [mean overlap of each seed]}} from an earlier ``lineage_versus.json``
    written at the same seeds and frame cap, for the targets ``names``; a one-line error where it
    does not hold them."""
    path = Path(path)
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
        per_seed = stored["per_seed"]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise NrmlcError(f"--lineage-from {path}: not a lineage_versus.json ({error})") from None
    if stored.get("seeds") != list(seeds) or stored.get("max_frames") != max_frames:
        raise NrmlcError(f"--lineage-from {path}: seeds {stored.get('seeds')} and frame cap {stored.get('max_frames')}, "
                         f"not {list(seeds)} and {max_frames}")
    missing = [f"{label} on {name}" for label in LINEAGE for name in names if name not in per_seed.get(label, {})]
    if missing:
        raise NrmlcError(f"--lineage-from {path}: no runs of {', '.join(missing[:3])}"
                         + (f" and {len(missing) - 3} more" if len(missing) > 3 else ""))
    return {label: {name: per_seed[label][name] for name in names} for label in LINEAGE}


def compare(ours: dict, theirs: dict, names) -> dict:
    """``ours`` minus ``theirs`` over the targets ``names``, per target on the means over seeds.

    Parameters
    ----------
    ours, theirs : dict of str -> list of float
        Per target, the mean overlap of each seed (any number of seeds each).

    Returns
    -------
    dict
        ``mean``: the mean of the per-target differences; ``standard_error``: their standard
        deviation over targets / sqrt(targets) (NaN with one target); ``won`` / ``lost``: targets
        where ours is higher / lower by more than :data:`TIE`; ``n``: targets.
    """
    difference = np.array([np.mean(ours[n]) - np.mean(theirs[n]) for n in names], dtype=np.float64)
    error = float(difference.std(ddof=1) / math.sqrt(difference.size)) if difference.size > 1 else math.nan
    return {"mean": float(difference.mean()), "standard_error": error, "won": int(np.sum(difference > TIE)),
            "lost": int(np.sum(difference < -TIE)), "n": int(difference.size)}


def verdict(difference: dict) -> str:
    """One phrase for a :func:`compare` result: a gain beyond two standard errors is a win."""
    mean, error = difference["mean"], difference["standard_error"]
    if not math.isfinite(error):
        return "one target: no verdict"
    if mean > 2 * error:
        return "beats it"
    if mean < -2 * error:
        return "is beaten"
    return "level (within two standard errors)"


def run(roots, out, seeds=(0, 1, 2, 3, 4), groups=None, cache=None, jobs=None, max_frames=None,
        lineage_from=None) -> dict:
    """Run (or read from the cache) every tracker on every target of ``groups`` and write the table.

    Parameters
    ----------
    roots : list of paths
        Data roots holding the targets.
    groups : dict of str -> tuple of str, optional
        Group name -> target names (default :data:`GROUPS`).
    max_frames : int, optional
        Track only the first frames (for quick checks).
    lineage_from : path, optional
        An earlier ``lineage_versus.json`` whose lineage columns are taken as they are, not run
        (:func:`lineage_columns_from`): NRMLC's code does not move the lineage's runs.
    """
    groups = groups or GROUPS
    names = list(dict.fromkeys(n for members in groups.values() for n in members))
    sequences = development_sequences(roots, names, 0, max_frames)
    cache = RunCache(cache)
    columns: dict = {}
    for label, preset in NRMLC_CONFIGURATIONS.items():
        measures = configuration_runs(cache, TrackerParams.preset(preset), sequences, seeds, max_frames, jobs)
        columns[label] = overlaps_of(measures)
    if lineage_from is not None:
        columns.update(lineage_columns_from(lineage_from, names, seeds, max_frames))
    else:
        for label, short_name in LINEAGE.items():
            columns[label] = lineage_overlaps(cache, short_name, sequences, seeds, max_frames, jobs)
    summary = {}
    for group, members in groups.items():
        summary[group] = {"n": len(members), "means": {c: float(np.mean([np.mean(v[n]) for n in members]))
                                                       for c, v in columns.items()}}
        differences = {f"{ours} - {theirs}": compare(columns[ours], columns[theirs], members)
                       for ours in NRMLC_CONFIGURATIONS for theirs in LINEAGE}
        summary[group]["differences"] = {pair: {**d, "verdict": verdict(d)} for pair, d in differences.items()}
    group_of = {n: g for g, members in groups.items() for n in members}
    rows = [[n, group_of[n]] + [float(np.mean(columns[c][n])) for c in columns] for n in names]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / f"{STEM}.csv", ["target", "group"] + list(columns), rows)
    write_json(out / f"{STEM}.json", {"seeds": list(seeds), "max_frames": max_frames, "groups": summary,
                                      "per_seed": columns})
    plot(summary, out / f"{STEM}.png")
    return {"columns": columns, "groups": summary}


def plot(summary: dict, path) -> None:
    """Each group's mean overlap per tracker, as grouped bars."""
    import matplotlib.pyplot as plt

    groups = list(summary)
    trackers = list(next(iter(summary.values()))["means"])
    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    width = 0.8 / len(trackers)
    for i, tracker in enumerate(trackers):
        x = np.arange(len(groups)) + (i - (len(trackers) - 1) / 2) * width
        ax.bar(x, [summary[g]["means"][tracker] for g in groups], width, label=tracker)
    ax.set_xticks(np.arange(len(groups)), [f"{g} ({summary[g]['n']})" for g in groups])
    ax.set_ylabel("mean overlap (mean over targets and seeds)")
    ax.set_ylim(0, 1)
    ax.legend(fontsize=8, loc="upper right", ncol=2)
    ax.set_title("NRMLC against its lineage, live", fontsize=10)
    save_figure(fig, path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", help="data roots joined by ':' (default: ../shared/data/sequences and "
                                       "../devdata/sequences)")
    parser.add_argument("--out", default="out/figures", help="output folder (default out/figures)")
    parser.add_argument("--seeds", default="0-4", help="seeds of every tracker (default 0-4)")
    parser.add_argument("--cache", help="run cache (default .cache/runs)")
    parser.add_argument("--jobs", type=int, help="worker processes (default: the cores)")
    parser.add_argument("--lineage-from", metavar="JSON",
                        help="take the lineage's columns from an earlier lineage_versus.json at the same seeds "
                             "instead of running them (NRMLC's code does not move them)")
    args = parser.parse_args(argv)
    try:
        result = run(parse_roots(args.data), args.out, parse_seeds(args.seeds), cache=args.cache, jobs=args.jobs,
                     lineage_from=args.lineage_from)
    except NrmlcError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    for group, entry in result["groups"].items():
        means = ", ".join(f"{c} {m:.3f}" for c, m in entry["means"].items())
        print(f"{group} ({entry['n']} targets): {means}")
        for pair, d in entry["differences"].items():
            print(f"  {pair}: {d['mean']:+.3f} +- {d['standard_error']:.3f} (won {d['won']}, lost {d['lost']}): "
                  f"{d['verdict']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
