"""Development evaluation: one configuration beside a baseline and OpenCV trackers.

Every default of :class:`nrmlc.TrackerParams` is chosen with this command, on the
development sequences only (:data:`experiments.sequence_sets.DEVELOPMENT_SEQUENCES`,
plus the synthetic suite with ``--synthetic N``); the paper's sequences are never
used for a choice. Runs go through the shared run cache, so a rerun only computes
what changed.

Examples
--------
::

    python -m experiments.development.devset --seeds 0-4
    python -m experiments.development.devset --seeds 0-2 --param propagation=best
    python -m experiments.development.devset --param alpha=10 --baseline-param alpha=2.5 --no-peers
    python -m experiments.development.devset --preset paper --baseline-preset default

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
import math
import sys
from pathlib import Path

import numpy as np

from experiments.grid import score, specs_for
from experiments.sequence_sets import (ADOPTION_RULE, DEVELOPMENT_A, DEVELOPMENT_B, DEVELOPMENT_SEQUENCES, MIN_GAIN,
                                      MIN_SEEDS)
from nrmlc import io
from nrmlc.config import data_root_from_env
from nrmlc.data.synthetic import SyntheticSequence
from nrmlc.errors import NrmlcError
from nrmlc.workbench.benchmark import parse_seeds
from nrmlc.workbench.run_cache import DEFAULT_CACHE, RunCache
from nrmlc.tracker.params import TrackerParams, parse_param_assignment

REPO_ROOT = Path(__file__).resolve().parents[2]

#: Where the 12 first development targets are (the shared data root).
DEFAULT_DATA = REPO_ROOT.parent / "shared" / "data" / "sequences"

#: Where ``lay_sequences.py`` is told to lay out the 24 more (``$NRMLC_MORE_DATA`` overrides it);
#: the OTB benchmark's result files it lays out are in ``otb_results/`` beside it.
MORE_DATA_ENV = "NRMLC_MORE_DATA"
DEFAULT_MORE_DATA = REPO_ROOT.parent / "devdata" / "sequences"

#: The lineage's benchmark results shown beside NRMLC (the OTB benchmark's own files).
LINEAGE_TRACKERS = ("ASLA", "IVT")

HALVES = {"A": DEVELOPMENT_A, "B": DEVELOPMENT_B}


def configuration(preset: str, assignments: list[str]) -> TrackerParams:
    """A preset with ``name=value`` changes."""
    changes = dict(parse_param_assignment(text) for text in assignments)
    return TrackerParams.preset(preset, **changes)


def default_roots() -> list[Path]:
    """The data roots used when ``--data`` is not given: ``$NRMLC_DATA`` (else the shared
    sequences) and ``$NRMLC_MORE_DATA`` (else ``../devdata/sequences``), those that exist; one
    warning line when none does."""
    import os

    first = data_root_from_env() or str(DEFAULT_DATA)
    more = os.environ.get(MORE_DATA_ENV, "").strip() or str(DEFAULT_MORE_DATA)
    candidates = list(dict.fromkeys((first, more)))
    roots = [Path(p) for p in candidates if Path(p).is_dir()]
    if not roots:
        print(f"warning: no development data at {' or '.join(candidates)} (give --data, $NRMLC_DATA or "
              f"${MORE_DATA_ENV}); only the synthetic suite runs", file=sys.stderr)
    return roots


def parse_roots(text: str | None) -> list[Path]:
    """``--data``: one or more data roots joined by ``os.pathsep`` (default :func:`default_roots`)."""
    import os

    if text is None:
        return default_roots()
    roots = [Path(p) for p in text.split(os.pathsep) if p.strip()]
    for root in roots:
        if not root.is_dir():
            raise NrmlcError(f"--data: {root} is not a folder")
    return roots


def development_sequences(roots, names, n_synthetic: int, max_frames: int | None = None) -> list:
    """The named development sequences, each from the first root that has it, then the
    synthetic suite's first ``n_synthetic``.

    Parameters
    ----------
    roots : path or list of paths
        Data roots (a single path is one root).
    """
    from nrmlc.data import list_sequences, synthetic_suite

    if roots is not None and not isinstance(roots, (list, tuple)):
        roots = [roots]
    sequences = []
    if roots and names:
        by_name: dict = {}
        for root in roots:
            for sequence in list_sequences(root):
                by_name.setdefault(sequence.name, sequence)
        missing = [n for n in names if n not in by_name]
        if missing:
            where = ", ".join(str(r) for r in roots)
            raise NrmlcError(f"{where}: development sequence(s) not found: {', '.join(missing)} (the 24 more "
                             f"are laid out by ../shared/tools/lay_sequences.py; give their folder in "
                             f"${MORE_DATA_ENV} or --data)")
        sequences += [by_name[n] for n in names]
    if n_synthetic:
        sequences += synthetic_suite(n_frames=300, n_sequences=n_synthetic)
    return sequences


def run_measures(results, specs) -> dict:
    """Per target, the measures of each run (in the order of ``specs``, one per seed).

    Returns
    -------
    dict of target -> {"overlap": [mean overlap], "scale": [:func:`tracked_scale`],
    "lost_at": [share of its frames before the loss of lock, or None],
    "shrunk_at": [share of its frames before the scale first stays below :data:`COLLAPSED_BELOW`
    for as many frames as a loss of lock takes, or None]}
    """
    from experiments.shared import first_run_below, lock_lost_at

    table: dict = {}
    for spec, result in zip(specs, results):
        evaluation = score(result.boxes, spec.sequence)
        lost = lock_lost_at(evaluation.overlaps, evaluation.frames)
        frames, ratios = scale_ratios(result.boxes, spec.sequence, evaluation.frames)
        shrunk = first_run_below(ratios, frames, COLLAPSED_BELOW)
        entry = table.setdefault(spec.sequence.name, {"overlap": [], "scale": [], "lost_at": [], "shrunk_at": []})
        entry["overlap"].append(float(evaluation.mean_overlap))
        entry["scale"].append(tail_scale(ratios))
        entry["lost_at"].append(None if lost is None else lost / len(result.boxes))
        entry["shrunk_at"].append(None if shrunk is None else shrunk / len(result.boxes))
    return table


def configuration_runs(cache: RunCache, params: TrackerParams, sequences, seeds, max_frames, jobs) -> dict:
    """:func:`run_measures` of ``params`` on ``sequences`` (computed where the cache lacks them)."""
    specs = specs_for(sequences, params, seeds, n_frames=max_frames)
    return run_measures(cache.run(specs, jobs=jobs), specs)


def overlaps_of(measures: dict) -> dict:
    """{target: [mean overlap of each seed]} of :func:`run_measures`."""
    return {name: entry["overlap"] for name, entry in measures.items()}


def scales_of(measures: dict) -> dict:
    """{target: [tracked scale of each seed]} of :func:`run_measures`."""
    return {name: entry["scale"] for name, entry in measures.items()}


#: The share of the annotated frames at the end over which :func:`tracked_scale` is taken, and
#: the scale below which a target counts as collapsed there.
SCALE_SHARE, COLLAPSED_BELOW = 0.25, 0.7


def scale_ratios(boxes, sequence, frames=None) -> tuple[np.ndarray, np.ndarray]:
    """(frames (n,), sqrt(box area / true area) (n,)) on the annotated frames (frame 0 excluded):
    below 1 the box is smaller than the target.

    Parameters
    ----------
    boxes : (n_frames, 4) float
        1-based OTB boxes from frame 0.
    frames : (n,) int, optional
        The annotated frames, where the caller has scored the boxes already (else scored here).
    """
    if frames is None:
        frames = score(boxes, sequence).frames
    frames = np.asarray(frames, dtype=np.int64)
    truth = np.asarray(sequence.groundtruth, dtype=np.float64)[frames]
    predicted = np.asarray(boxes, dtype=np.float64)[frames]
    with np.errstate(invalid="ignore", divide="ignore"):
        return frames, np.sqrt(np.abs(predicted[:, 2] * predicted[:, 3]) / (truth[:, 2] * truth[:, 3]))


def tracked_scale(boxes, sequence, share: float = SCALE_SHARE) -> float:
    """The median of :func:`scale_ratios` over the last ``share`` of the annotated frames."""
    return tail_scale(scale_ratios(boxes, sequence)[1], share)


def tail_scale(ratio: np.ndarray, share: float = SCALE_SHARE) -> float:
    """The median of the last ``share`` of ``ratio`` (n,) (:func:`scale_ratios`); NaN if none is finite."""
    if ratio.size == 0:
        return math.nan
    tail = last_share(ratio, share)
    return float(np.nanmedian(tail)) if np.isfinite(tail).any() else math.nan


def last_share(rows: np.ndarray, share: float = SCALE_SHARE) -> np.ndarray:
    """The last ``share`` of ``rows`` (n, ...): at least one row, ``ceil(share * n)`` in all."""
    return rows[-max(1, math.ceil(share * len(rows))):]


def collapsed(scales: dict, names) -> list[str]:
    """The targets among ``names`` whose median over seeds of :func:`tracked_scale` is below
    :data:`COLLAPSED_BELOW`; ``scales`` maps a target to its per-seed scales."""
    return [n for n in names if n in scales and np.nanmedian(scales[n]) < COLLAPSED_BELOW]


def collapse_after_loss(measures: dict, names) -> dict:
    """{collapsed target (:func:`collapsed`): (runs whose scale fell only after the loss of lock,
    runs whose tracked scale is below :data:`COLLAPSED_BELOW`)}.

    A run's scale fell after the loss when its lock was lost (``lost_at``) no later than its
    scale first stayed low (``shrunk_at``): the box shrank on whatever it followed once off the
    target. The other collapsed runs shrank while they held it.
    """
    found = {}
    for name in collapsed(scales_of(measures), names):
        entry = measures[name]
        low = [i for i, s in enumerate(entry["scale"]) if s < COLLAPSED_BELOW]
        after = [i for i in low if entry["lost_at"][i] is not None
                 and (entry["shrunk_at"][i] is None or entry["lost_at"][i] <= entry["shrunk_at"][i])]
        found[name] = (len(after), len(low))
    return found


#: A run "lost early" when lock is lost (:func:`experiments.shared.lock_lost_at`)
#: within this share of its frames.
EARLY_SHARE = 0.05


def early_losses(measures: dict, names, share: float = EARLY_SHARE) -> list[str]:
    """Targets lost within ``share`` of their frames in most seeds."""
    return [n for n in names if n in measures and
            2 * sum(at is not None and at <= share for at in measures[n]["lost_at"]) > len(measures[n]["lost_at"])]


def attribute_means(columns: dict, names, attributes: dict) -> dict:
    """{attribute code: {column: mean over the targets of ``names`` that have it}, plus "n"}."""
    from nrmlc.workbench.attributes import ATTRIBUTES

    table = {}
    for code, _ in ATTRIBUTES:
        having = [n for n in names if code in attributes.get(n, ())]
        if having:
            table[code] = {"n": len(having), **{c: float(np.mean([v[n] for n in having if n in v]))
                                                 for c, v in columns.items() if any(n in v for n in having)}}
    return table


def format_attribute_means(table: dict, columns) -> str:
    """Markdown: one row per attribute, a column per tracker."""
    lines = ["| attribute (targets) | " + " | ".join(columns) + " |", "|---|" + "---|" * len(columns)]
    for code, row in table.items():
        lines.append(f"| {code} ({row['n']}) | " + " | ".join(f"{row[c]:.3f}" if c in row else "-" for c in columns)
                     + " |")
    return "\n".join(lines)


def peer_measures(cache: RunCache, sequences, max_frames, jobs) -> tuple[dict, dict, dict]:
    """({tracker: {sequence name: mean overlap}}, {tracker: {sequence name: :func:`tracked_scale`}},
    {tracker: {sequence name: :func:`frame_edge_share`}}) for the live OpenCV trackers (cached)."""
    from experiments.peers import LiveSpec, live_trackers

    specs = [LiveSpec(s, name, max_frames) for name in live_trackers() for s in sequences]
    results = cache.run(specs, jobs=jobs)
    measures: tuple = ({}, {}, {})
    for spec, result in zip(specs, results):
        for found, value in zip(measures, _peer_tail_measures(result.boxes, spec.sequence)):
            found.setdefault(spec.tracker, {})[spec.sequence.name] = value
    return measures


def _peer_tail_measures(boxes, sequence, n_frames: int | None = None) -> tuple[float, float, float]:
    """(mean overlap, :func:`tracked_scale`, :func:`frame_edge_share`) of a peer's ``boxes``
    (n_frames, 4), scored once."""
    evaluation = score(boxes, sequence, n_frames)
    return (float(evaluation.mean_overlap), tail_scale(scale_ratios(boxes, sequence, evaluation.frames)[1]),
            frame_edge_share(boxes, sequence, evaluation.frames))


def frame_edge_share(boxes, sequence, frames, share: float = SCALE_SHARE) -> float:
    """The share of the last ``share`` of the annotated ``frames`` (n,) whose box in ``boxes``
    (n_frames, 4; 1-based) lies within 1 px of the frame's border; NaN if none there is finite.

    A box driven out of the frame and clipped to it shrinks while the target does not (OpenCV
    clips KCF's and CSRT's boxes, down to zero width). NRMLC keeps only its boxes' centres inside
    the frame and never clips a box, so its boxes never shrink that way.
    """
    height, width = sequence.frame_size
    box = last_share(np.asarray(boxes, dtype=np.float64)[np.asarray(frames, dtype=np.int64)], share)
    box = box[np.all(np.isfinite(box), axis=1)]
    if not len(box):
        return math.nan
    at_edge = ((box[:, 0] <= 2) | (box[:, 1] <= 2) | (box[:, 0] + box[:, 2] >= width)
               | (box[:, 1] + box[:, 3] >= height))
    return float(at_edge.mean())


def peer_collapses(scales: dict, names, edges: dict | None = None) -> dict:
    """{peer column: the targets among ``names`` it scores, those collapsed, and those of them whose
    box lies at the frame's border on at least half of the last quarter's frames}, from {column:
    {sequence name: tracked scale}} and {column: {sequence name: :func:`frame_edge_share`}}: the
    same measure as NRMLC's (:func:`collapsed`), so that a target that grows while a fixed-size
    tracker keeps its first box counts for it too."""
    edges = edges or {}
    found = {}
    for column, values in scales.items():
        fallen = [n for n in names if values.get(n, math.nan) < COLLAPSED_BELOW]
        found[column] = {"scored": [n for n in names if np.isfinite(values.get(n, math.nan))], "collapsed": fallen,
                         "at_frame_edge": [n for n in fallen if edges.get(column, {}).get(n, math.nan) >= 0.5]}
    return found


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


def adopted(differences: dict) -> tuple[bool, str]:
    """The adoption rule (:data:`experiments.sequence_sets.ADOPTION_RULE`) on the paired
    differences of half A, half B and the synthetic suite (:func:`paired_difference`).

    Returns
    -------
    (bool, str): whether the change is adopted, and why (the first clause that fails).
    """
    a, b, synthetic = (differences.get(k) for k in ("A", "B", "synthetic suite"))
    if a is None or b is None:
        return False, "needs both halves"
    if len(a["per_seed"]) < MIN_SEEDS:
        return False, f"needs at least {MIN_SEEDS} seeds (has {len(a['per_seed'])})"
    if not a["mean"] >= MIN_GAIN:
        return False, f"A: {a['mean']:+.3f} is under the least gain worth a change, {MIN_GAIN}"
    if not a["mean"] > a["standard_error"]:
        return False, f"A: {a['mean']:+.3f} is not beyond its error {a['standard_error']:.3f}"
    if not b["mean"] > 0:
        return False, f"B: {b['mean']:+.3f} is not a gain"
    if synthetic is not None and synthetic["mean"] < -synthetic["standard_error"]:
        return False, f"synthetic suite: {synthetic['mean']:+.3f} ± {synthetic['standard_error']:.3f} loses"
    return True, "passes on A, B" + (" and the synthetic suite" if synthetic is not None else "")


def groups_of(sequences) -> dict:
    """{group label: names} for the tables: half A, half B, other real targets, the synthetic suite."""
    order = [s.name for s in sequences]
    synthetic_names = {s.name for s in sequences if isinstance(s, SyntheticSequence)}
    real = [n for n in order if n not in synthetic_names]
    groups = {"A": [n for n in real if n in DEVELOPMENT_A], "B": [n for n in real if n in DEVELOPMENT_B]}
    groups["other"] = [n for n in real if n not in DEVELOPMENT_A and n not in DEVELOPMENT_B]
    groups["synthetic suite"] = [n for n in order if n in synthetic_names]
    return {label: names for label, names in groups.items() if names}


def format_table(groups: dict, columns: dict) -> str:
    """Markdown table: one row per sequence, a mean row after each group and over the real
    targets; ``columns`` maps a header to {sequence: value} (a missing value is '-').

    A column without a value on every target of a group gets its mean over the targets it
    has and, in brackets, the first column's mean over the same targets: like with like.
    """
    headers = ["sequence"] + list(columns)
    first = next(iter(columns))
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]

    def mean_cell(column: str, names) -> str:
        have = [n for n in names if n in columns[column]]
        if not have:
            return "-"
        cell = f"**{np.mean([columns[column][n] for n in have]):.3f}**"
        if len(have) < len(names):
            cell += f" ({len(have)}; {first} {np.mean([columns[first][n] for n in have]):.3f})"
        return cell

    real = [n for label, names in groups.items() if label != "synthetic suite" for n in names]
    for label, names in groups.items():
        for name in names:
            lines.append("| " + " | ".join([name] + [f"{columns[c][name]:.3f}" if name in columns[c] else "-"
                                                     for c in columns]) + " |")
        title = f"half {label}" if label in HALVES else label
        lines.append(f"| **mean, {title} ({len(names)})** | " + " | ".join(mean_cell(c, names) for c in columns)
                     + " |")
    if len([g for g in groups if g != "synthetic suite"]) > 1:
        lines.append(f"| **mean, all real ({len(real)})** | " + " | ".join(mean_cell(c, real) for c in columns)
                     + " |")
    return "\n".join(lines)


def lineage_measures(folder, sequences, trackers=LINEAGE_TRACKERS) -> tuple[dict, dict, dict, list]:
    """({tracker: {sequence name: mean overlap}}, {tracker: {sequence name: :func:`tracked_scale`}},
    {tracker: {sequence name: :func:`frame_edge_share`}}) of the OTB benchmark's own result files in
    ``folder`` (:mod:`nrmlc.workbench.otb_results`), scored like NRMLC, and the notes of files not used."""
    from nrmlc.workbench.otb_results import otb_result_boxes

    measures: tuple = ({}, {}, {})
    notes: list = []
    for tracker in trackers:
        for sequence in sequences:
            boxes, _, found_notes = otb_result_boxes(folder, tracker, sequence)
            notes += found_notes
            if boxes is not None:
                for found, value in zip(measures, _peer_tail_measures(boxes, sequence, len(sequence))):
                    found.setdefault(tracker, {})[sequence.name] = value
    return (*measures, notes)


def default_beside(roots, name: str) -> Path | None:
    """A folder ``name`` laid out beside a data root (``<root>/../otb_results``, ``../otb_attributes``)."""
    for root in roots:
        candidate = Path(root).parent / name
        if candidate.is_dir():
            return candidate
    return None


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default=None,
                        help="data root(s), joined by ':' (default: $NRMLC_DATA, else ../shared/data/sequences, "
                             "and $NRMLC_MORE_DATA, else ../devdata/sequences, where they exist)")
    parser.add_argument("--seeds", default="0-4", help="seeds, e.g. 0-4 or 0,2; a number alone is that one seed (default 0-4)")
    parser.add_argument("--preset", default="default", help="preset of the configuration (default: default)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="change a parameter of the configuration (repeatable)")
    parser.add_argument("--baseline-preset", default="default", help="preset of the baseline")
    parser.add_argument("--baseline-param", action="append", default=[], metavar="NAME=VALUE",
                        help="change a parameter of the baseline (repeatable)")
    parser.add_argument("--no-baseline", action="store_true", help="skip the baseline column")
    parser.add_argument("--half", choices=("A", "B", "all"), default="all",
                        help="the choosing half A, the confirming half B, or both (default)")
    parser.add_argument("--sequences", default=None,
                        help="comma-separated subset of the development sequences (overrides --half)")
    parser.add_argument("--synthetic", type=int, default=0, metavar="N",
                        help="add N synthetic sequences of 300 frames (the synthetic development suite)")
    parser.add_argument("--max-frames", type=int, default=None, help="track only the first N frames")
    parser.add_argument("--no-peers", action="store_true", help="skip the OpenCV trackers and the lineage")
    parser.add_argument("--otb-results", default=None, metavar="DIR",
                        help="the OTB benchmark's result files, for ASLA and IVT (default: otb_results/ "
                             "beside a data root)")
    parser.add_argument("--attributes", default=None, metavar="DIR",
                        help="the OTB attribute files: also the mean overlap per attribute (default: "
                             "otb_attributes/ beside a data root)")
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    parser.add_argument("--cache", default=str(DEFAULT_CACHE), help="run cache folder (default .cache/runs)")
    parser.add_argument("--json", default=None, metavar="PATH", help="also write the numbers as JSON")
    return parser


def selected_names(half: str, sequences_text: str | None) -> tuple:
    """The development targets ``--half`` / ``--sequences`` select."""
    if sequences_text is not None:
        names = tuple(n.strip() for n in sequences_text.split(",") if n.strip())  # "" = the synthetic suite only
        unknown = [n for n in names if n not in DEVELOPMENT_SEQUENCES]
        if unknown:
            raise NrmlcError(f"--sequences: not development sequences: {', '.join(unknown)}")
        return names
    return DEVELOPMENT_SEQUENCES if half == "all" else HALVES[half]


def differences_by_group(config_runs: dict, baseline_runs: dict, groups: dict, seeds) -> dict:
    """{group: paired difference with its largest single-run changes}."""
    return {label: dict(paired_difference(config_runs, baseline_runs, names),
                        largest_runs=largest_run_changes(config_runs, baseline_runs, names, seeds))
            for label, names in groups.items()}


def format_differences(differences: dict, seeds) -> list[str]:
    """One line per group: the paired difference, its error and the runs that moved most."""
    lines = []
    for label, d in differences.items():
        spread = (f"± {d['standard_error']:.3f} (paired by seed; standard error over {len(seeds)} seeds)"
                  if len(seeds) > 1 else "(one seed: no standard error)")
        title = f"half {label}" if label in HALVES else f"the {label}"
        lines.append(f"config - baseline on {title}: {d['mean']:+.3f} {spread}; {d['up']} of {d['n']} up, "
                     f"{d['down']} down; the runs that changed most: "
                     + ", ".join(f"{name} seed {seed} {change:+.3f}" for name, seed, change in d["largest_runs"]))
    return lines


def warn_few_seeds(text: str, seeds) -> None:
    """One warning line when ``--seeds`` names fewer seeds than :func:`adopted` needs: ``--seeds 3``
    is seed 3 alone, not three seeds."""
    if len(seeds) < MIN_SEEDS:
        print(f"warning: --seeds {text} is {len(seeds)} seed(s) ({', '.join(map(str, seeds))}); the adoption "
              f"rule needs at least {MIN_SEEDS} (a range such as --seeds 0-{MIN_SEEDS - 1})", file=sys.stderr)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
        warn_few_seeds(args.seeds, seeds)
        config = configuration(args.preset, args.param)
        baseline = configuration(args.baseline_preset, args.baseline_param)
        roots = parse_roots(args.data)
        names = selected_names(args.half, args.sequences)
        sequences = development_sequences(roots, names, args.synthetic, args.max_frames)
        if not sequences:
            raise NrmlcError("no development sequences: give --data or --synthetic N")
    except NrmlcError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    cache = RunCache(args.cache)
    groups = groups_of(sequences)
    measures = configuration_runs(cache, config, sequences, seeds, args.max_frames, args.jobs)
    config_runs = overlaps_of(measures)
    columns = {"config": {n: float(np.mean(v)) for n, v in config_runs.items()}}
    baseline_runs, differences, notes = None, {}, []
    if baseline != config and not args.no_baseline:
        baseline_runs = overlaps_of(configuration_runs(cache, baseline, sequences, seeds, args.max_frames,
                                                       args.jobs))
        columns["baseline"] = {n: float(np.mean(v)) for n, v in baseline_runs.items()}
        differences = differences_by_group(config_runs, baseline_runs, groups, seeds)
    real = [s for s in sequences if not isinstance(s, SyntheticSequence)]
    peer_scales: dict = {}
    peer_edges: dict = {}
    if not args.no_peers:
        live, live_scales, live_edges = peer_measures(cache, sequences, args.max_frames, args.jobs)
        for tracker, values in live.items():
            columns[f"{tracker} (OpenCV)"] = values
            peer_scales[f"{tracker} (OpenCV)"] = live_scales[tracker]
            peer_edges[f"{tracker} (OpenCV)"] = live_edges[tracker]
        otb_results = Path(args.otb_results) if args.otb_results else default_beside(roots, "otb_results")
        if otb_results is not None and real and args.max_frames is None:
            lineage, lineage_scales, lineage_edges, notes = lineage_measures(otb_results, real)
            for tracker in LINEAGE_TRACKERS:
                columns[f"{tracker} (OTB results)"] = lineage.get(tracker, {})
                peer_scales[f"{tracker} (OTB results)"] = lineage_scales.get(tracker, {})
                peer_edges[f"{tracker} (OTB results)"] = lineage_edges.get(tracker, {})
    attribute_folder = Path(args.attributes) if args.attributes else default_beside(roots, "otb_attributes")
    attribute_table, losses = None, None
    if real:
        losses = {label: {"collapsed": collapsed(scales_of(measures), names),
                          "collapse_after_loss": collapse_after_loss(measures, names),
                          "lost_early": early_losses(measures, names),
                          "peers_collapsed": peer_collapses(peer_scales, names, peer_edges)}
                  for label, names in groups.items() if label != "synthetic suite"}
        if attribute_folder is not None:
            from nrmlc.workbench.attributes import read_attributes

            attributes, _ = read_attributes(attribute_folder, [s.name for s in real])
            attribute_table = attribute_means(columns, [s.name for s in real], attributes)
    changed = {k: v for k, v in config.as_dict().items() if TrackerParams().as_dict()[k] != v}
    print(f"config: preset {args.preset} {changed or ''}; baseline: preset {args.baseline_preset} "
          f"{args.baseline_param or ''}; seeds {','.join(map(str, seeds))}; mean overlap")
    print(format_table(groups, columns))
    for line in format_differences(differences, seeds):
        print(line)
    for label, found in (losses or {}).items():
        title = f"half {label}" if label in HALVES else label
        print(f"config on {title}: tracked scale below {COLLAPSED_BELOW} over the last quarter on "
              f"{len(found['collapsed'])} ({', '.join(found['collapsed']) or 'none'}); lock lost within the first "
              f"{EARLY_SHARE:.0%} on {len(found['lost_early'])} ({', '.join(found['lost_early']) or 'none'})")
        if found["peers_collapsed"]:
            print("  the peers' tracked scale below the same bound: " + "; ".join(
                f"{column} {len(entry['collapsed'])} of {len(entry['scored'])} ({', '.join(entry['collapsed']) or 'none'}"
                + (f"; at the frame's edge: {', '.join(entry['at_frame_edge'])}" if entry["at_frame_edge"] else "")
                + ")" for column, entry in found["peers_collapsed"].items()))
        if found["collapse_after_loss"]:
            order = found["collapse_after_loss"]
            print(f"  collapsed runs whose scale fell only after the lock was lost: "
                  f"{sum(a for a, _ in order.values())} of {sum(n for _, n in order.values())} ("
                  + ", ".join(f"{name} {a}/{n}" for name, (a, n) in order.items()) + ")")
    if attribute_table:
        print(f"mean overlap by OTB attribute ({attribute_folder}):")
        print(format_attribute_means(attribute_table, list(columns)))
    verdict = adopted(differences) if differences else None
    if verdict is not None and "A" in differences and "B" in differences:
        print(f"adoption rule ({ADOPTION_RULE}): {'ADOPTED' if verdict[0] else 'not adopted'}: {verdict[1]}")
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    if args.json:
        io.write_json(args.json, {"config": config.as_dict(), "baseline": baseline.as_dict(), "seeds": seeds,
                                  "per_seed": config_runs, "baseline_per_seed": baseline_runs, "columns": columns,
                                  "groups": groups, "differences": differences, "losses": losses,
                                  "attributes": attribute_table,
                                  "adopted": None if verdict is None else {"adopted": verdict[0],
                                                                           "why": verdict[1]}})
    return 0


if __name__ == "__main__":
    sys.exit(main())
