"""Development evaluation: one configuration beside a baseline and OpenCV trackers.

Every default of :class:`nrmlc.TrackerParams` is chosen with this command, on the
development sequences only (:data:`experiments.sequence_sets.DEVELOPMENT_SEQUENCES`,
plus the synthetic suite with ``--synthetic N``); the paper's sequences are never
used for a choice. Runs go through the shared run cache, so a rerun only computes
what changed.

Examples
--------
::

    python -m experiments.devset --seeds 0-4
    python -m experiments.devset --seeds 0-2 --param propagation=best
    python -m experiments.devset --param alpha=10 --baseline-param alpha=2.5 --no-peers
    python -m experiments.devset --preset paper --baseline-preset default

It prints, per sequence, the mean overlap (over seeds) of the configuration, the
baseline and each OpenCV tracker (MIL; KCF and CSRT with opencv-contrib), and the
means over the sequences; then the paired difference configuration - baseline with its
standard error over seeds (:func:`paired_difference`), for the real sequences and the
synthetic suite apart: the numbers the adoption rule reads (docs/FINDINGS.md), with the
three single runs that changed most (:func:`largest_run_changes`). ``--json PATH`` writes
the same numbers.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from experiments.grid import score, specs_for
from experiments.sequence_sets import DEVELOPMENT_SEQUENCES
from nrmlc import io
from nrmlc.config import data_root_from_env
from nrmlc.data.synthetic import SyntheticSequence
from nrmlc.errors import NrmlcError
from nrmlc.benchmark import parse_seeds
from nrmlc.runner import DEFAULT_CACHE, RunCache
from nrmlc.tracker.params import TrackerParams, parse_param_assignment

DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "sequences"


def configuration(preset: str, assignments: list[str]) -> TrackerParams:
    """A preset with ``name=value`` changes."""
    changes = dict(parse_param_assignment(text) for text in assignments)
    return TrackerParams.preset(preset, **changes)


def development_sequences(data: Path | None, names, n_synthetic: int, max_frames: int | None) -> list:
    from nrmlc.data import list_sequences, synthetic_suite

    sequences = []
    if data is not None and names:
        by_name = {s.name: s for s in list_sequences(data)}
        missing = [n for n in names if n not in by_name]
        if missing:
            raise NrmlcError(f"{data}: development sequence(s) not found: {', '.join(missing)}")
        sequences += [by_name[n] for n in names]
    if n_synthetic:
        sequences += synthetic_suite(n_frames=300, n_sequences=n_synthetic)
    return sequences


def mean_overlaps(cache: RunCache, params: TrackerParams, sequences, seeds, max_frames, jobs) -> dict:
    """{sequence name: (mean over seeds of the mean overlap, per-seed list)}."""
    specs = specs_for(sequences, params, seeds, n_frames=max_frames)
    results = cache.run(specs, jobs=jobs)
    table: dict = {}
    for spec, result in zip(specs, results):
        table.setdefault(spec.sequence.name, []).append(float(score(result.boxes, spec.sequence).mean_overlap))
    return table


def peer_overlaps(cache: RunCache, sequences, max_frames, jobs) -> dict:
    """{tracker: {sequence name: mean overlap}} for the live OpenCV trackers (cached)."""
    from experiments.peers import LiveSpec, live_trackers

    specs = [LiveSpec(s, name, max_frames) for name in live_trackers() for s in sequences]
    results = cache.run(specs, jobs=jobs)
    table: dict = {}
    for spec, result in zip(specs, results):
        table.setdefault(spec.tracker, {})[spec.sequence.name] = float(score(result.boxes, spec.sequence).mean_overlap)
    return table


def paired_difference(config_runs: dict, baseline_runs: dict, names) -> dict:
    """Configuration minus baseline, paired by seed, over the sequences ``names``.

    Parameters
    ----------
    config_runs, baseline_runs : dict of str -> list of float
        Per sequence, the mean overlap of each seed (the same seeds, in the same order).
    names : sequence of str
        The sequences to average over.

    Returns
    -------
    dict
        ``per_seed`` (n_seeds,): the difference of the across-sequence means for each seed;
        ``mean`` and ``standard_error`` (its std over seeds / sqrt(n_seeds); NaN with one seed);
        ``up`` / ``down``: sequences whose mean over seeds rose / fell; ``n``: sequences.
    """
    config = np.array([config_runs[n] for n in names], dtype=np.float64)      # (n_sequences, n_seeds)
    baseline = np.array([baseline_runs[n] for n in names], dtype=np.float64)
    per_seed = (config - baseline).mean(axis=0)
    error = float(per_seed.std(ddof=1) / np.sqrt(per_seed.size)) if per_seed.size > 1 else float("nan")
    change = (config - baseline).mean(axis=1)
    return {"per_seed": per_seed.tolist(), "mean": float(per_seed.mean()), "standard_error": error,
            "up": int(np.sum(change > 0)), "down": int(np.sum(change < 0)), "n": len(names)}


def largest_run_changes(config_runs: dict, baseline_runs: dict, names, seeds, count: int = 3) -> list:
    """The ``count`` single runs (sequence, seed) whose overlap changed most, largest magnitude
    first: a mean difference carried by one or two of them (a target kept or lost in one run)
    is not a change of the tracker's behaviour.

    Returns
    -------
    list of (sequence, seed, config - baseline) tuples
    """
    changes = [(name, seed, config_runs[name][i] - baseline_runs[name][i])
               for name in names for i, seed in enumerate(seeds)]
    return sorted(changes, key=lambda change: -abs(change[2]))[:count]


def format_table(names, columns: dict) -> str:
    """Markdown table: one row per sequence plus the mean; ``columns`` maps a header to
    {sequence: value}."""
    headers = ["sequence"] + list(columns)
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    for name in names:
        lines.append("| " + " | ".join([name] + [f"{columns[c][name]:.3f}" for c in columns]) + " |")
    means = [f"**{np.mean([columns[c][n] for n in names]):.3f}**" for c in columns]
    lines.append("| **mean** | " + " | ".join(means) + " |")
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=None,
                        help="data root (default: $NRMLC_DATA, else ../shared/data/sequences)")
    parser.add_argument("--seeds", default="0-4", help="seeds, e.g. 0-4 or 0,2 (default 0-4)")
    parser.add_argument("--preset", default="default", help="preset of the configuration (default: default)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="change a parameter of the configuration (repeatable)")
    parser.add_argument("--baseline-preset", default="default", help="preset of the baseline")
    parser.add_argument("--baseline-param", action="append", default=[], metavar="NAME=VALUE",
                        help="change a parameter of the baseline (repeatable)")
    parser.add_argument("--no-baseline", action="store_true", help="skip the baseline column")
    parser.add_argument("--sequences", default=None,
                        help="comma-separated subset of the development sequences")
    parser.add_argument("--synthetic", type=int, default=0, metavar="N",
                        help="add N synthetic sequences of 300 frames (the synthetic development suite)")
    parser.add_argument("--max-frames", type=int, default=None, help="track only the first N frames")
    parser.add_argument("--no-peers", action="store_true", help="skip the OpenCV trackers")
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    parser.add_argument("--cache", default=str(DEFAULT_CACHE), help="run cache folder (default .cache/runs)")
    parser.add_argument("--json", default=None, metavar="PATH", help="also write the numbers as JSON")
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
        config = configuration(args.preset, args.param)
        baseline = configuration(args.baseline_preset, args.baseline_param)
        data = args.data or data_root_from_env() or (str(DEFAULT_DATA) if DEFAULT_DATA.is_dir() else None)
        names = (DEVELOPMENT_SEQUENCES if args.sequences is None
                 else tuple(n for n in args.sequences.split(",") if n.strip()))  # "" = the synthetic suite only
        unknown = [n for n in names if n not in DEVELOPMENT_SEQUENCES]
        if unknown:
            raise NrmlcError(f"--sequences: not development sequences: {', '.join(unknown)}")
        sequences = development_sequences(Path(data) if data else None, names, args.synthetic, args.max_frames)
        if not sequences:
            raise NrmlcError("no development sequences: give --data or --synthetic N")
    except NrmlcError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    cache = RunCache(args.cache)
    order = [s.name for s in sequences]
    config_runs = mean_overlaps(cache, config, sequences, seeds, args.max_frames, args.jobs)
    columns = {"config": {n: float(np.mean(v)) for n, v in config_runs.items()}}
    baseline_runs, differences = None, {}
    if baseline != config and not args.no_baseline:
        baseline_runs = mean_overlaps(cache, baseline, sequences, seeds, args.max_frames, args.jobs)
        columns["baseline"] = {n: float(np.mean(v)) for n, v in baseline_runs.items()}
        synthetic = {s.name for s in sequences if isinstance(s, SyntheticSequence)}
        for label, group in (("development sequences", [n for n in order if n not in synthetic]),
                             ("synthetic suite", [n for n in order if n in synthetic])):
            if group:
                differences[label] = dict(paired_difference(config_runs, baseline_runs, group),
                                          largest_runs=largest_run_changes(config_runs, baseline_runs, group, seeds))
    if not args.no_peers:
        for tracker, values in peer_overlaps(cache, sequences, args.max_frames, args.jobs).items():
            columns[f"{tracker} (OpenCV)"] = values
    changed = {k: v for k, v in config.as_dict().items() if TrackerParams().as_dict()[k] != v}
    print(f"config: preset {args.preset} {changed or ''}; baseline: preset {args.baseline_preset} "
          f"{args.baseline_param or ''}; seeds {','.join(map(str, seeds))}; mean overlap")
    print(format_table(order, columns))
    for label, d in differences.items():
        spread = (f"± {d['standard_error']:.3f} (paired by seed; standard error over {len(seeds)} seeds)"
                  if len(seeds) > 1 else "(one seed: no standard error)")
        print(f"config - baseline on the {label}: {d['mean']:+.3f} {spread}; {d['up']} of {d['n']} up, "
              f"{d['down']} down; the runs that changed most: "
              + ", ".join(f"{name} seed {seed} {change:+.3f}" for name, seed, change in d["largest_runs"]))
    if args.json:
        io.write_json(args.json, {"config": config.as_dict(), "baseline": baseline.as_dict(), "seeds": seeds,
                                  "per_seed": config_runs, "baseline_per_seed": baseline_runs, "columns": columns,
                                  "differences": differences})
    return 0


if __name__ == "__main__":
    sys.exit(main())
