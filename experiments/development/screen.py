"""Screen many configurations against one baseline on both development halves at once.

``python -m experiments.development.screen --seeds 0-2 --synthetic 6 --variant NAME PARAM=VALUE[,PARAM=VALUE...] ...``

The baseline's runs, then each variant's, go through the run cache (longest run first within
each, so both cores stay busy; a rerun computes only what is missing). For each variant
it prints the paired difference to the baseline (:func:`experiments.development.devset.paired_difference`)
on half A, half B and the synthetic suite, and the adoption rule's verdict
(:func:`experiments.development.devset.adopted`); ``--json`` writes the same with every run's overlap,
``--markdown`` the table.

``--baseline-version V`` pairs the variants with the baseline's runs stored at another code
version V (a variant that adds a switch changes the code version, but not the default's boxes):
the baseline's synthetic-suite runs are first computed at this version and must equal V's bit
for bit, and V's real-target runs must all be in the cache; otherwise the screen stops.

``--pool A.json,B.json`` runs nothing: it joins screens written by ``--json`` at disjoint seeds
(the same baseline and targets, e.g. a round's screen and its check, each maybe on a branch's
code version) and gives the paired differences and the verdict over all their seeds, for the
variants (by name) that every screen has.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from experiments.development.devset import (adopted, collapsed, development_sequences, differences_by_group, groups_of,
                                overlaps_of, parse_roots, run_measures, scales_of, selected_names, warn_few_seeds)
from experiments.grid import specs_for
from nrmlc import io
from nrmlc.workbench.benchmark import parse_seeds
from nrmlc.data.synthetic import SyntheticSequence
from nrmlc.errors import NrmlcError
from nrmlc.workbench.run_cache import DEFAULT_CACHE, RunCache
from nrmlc.tracker.params import TrackerParams, parse_param_assignment


def parse_variant(name: str, text: str, base_preset: str) -> TrackerParams:
    """``PARAM=VALUE,PARAM=VALUE`` (a tuple value keeps its commas inside brackets: ``motion_sigmas=[4,4,0.01,0,0.005,0]``)
    or ``preset:NAME`` -> the parameters of variant ``name``."""
    if text.startswith("preset:"):
        return TrackerParams.preset(text.split(":", 1)[1])
    parts, depth, current = [], 0, ""
    for char in text:
        depth += char == "["
        depth -= char == "]"
        if char == "," and depth == 0:
            parts.append(current)
            current = ""
        else:
            current += char
    parts.append(current)
    changes = dict(parse_param_assignment(part.replace("[", "").replace("]", "")) for part in parts if part.strip())
    try:
        return TrackerParams.preset(base_preset, **changes)
    except NrmlcError as error:
        raise NrmlcError(f"--variant {name}: {error}") from None


def baseline_at_version(cache: RunCache, specs: list, version: str, jobs) -> list:
    """The baseline's results as stored at code version ``version`` (see the module docstring).

    Raises
    ------
    NrmlcError
        When a synthetic run differs between the two versions, or a run is not stored at ``version``.
    """
    import numpy as np

    other = RunCache(cache.folder)
    other.version = version
    missing = [spec.label or f"{spec.sequence.name} seed {spec.seed}" for spec in specs
               if not other.has(spec)]
    if missing:
        raise NrmlcError(f"--baseline-version {version}: {len(missing)} baseline runs are not in {cache.folder} "
                         f"(e.g. {missing[0]})")
    checks = [spec for spec in specs if isinstance(spec.sequence, SyntheticSequence)]
    if not checks:
        raise NrmlcError("--baseline-version needs the synthetic suite (--synthetic N) to check the versions")
    here, there = cache.run(checks, jobs=jobs), other.run(checks, jobs=jobs)
    for spec, a, b in zip(checks, here, there):
        if not np.array_equal(a.boxes, b.boxes):
            raise NrmlcError(f"--baseline-version {version}: {spec.sequence.name} seed {spec.seed} gives other "
                             f"boxes at {cache.version}; the baseline cannot be carried over")
    print(f"baseline: {len(checks)} synthetic runs bit-identical at {cache.version} and {version}; "
          f"the other {len(specs) - len(checks)} runs read at {version}", file=sys.stderr)
    return other.run(specs, jobs=jobs)


def screen_groups(sequences) -> dict:
    """:func:`experiments.development.devset.groups_of` with the real targets of all groups together as
    ``"all real"`` (when there are any)."""
    groups = groups_of(sequences)
    real = [n for label, names in groups.items() if label != "synthetic suite" for n in names]
    if real:
        groups["all real"] = real
    return groups


def collapsed_by_half(scales: dict, groups: dict) -> dict:
    """{'A': [...], 'B': [...]}: the collapsed targets (:func:`experiments.development.devset.collapsed`) per half."""
    return {label: collapsed(scales, names) for label, names in groups.items() if label in ("A", "B")}


def screen_row(name: str, params: dict, runs: dict, scales: dict, baseline_runs: dict, groups: dict,
               seeds) -> dict:
    """One variant's row of a screen: its runs against the baseline's and the rule's verdict."""
    differences = differences_by_group(runs, baseline_runs, groups, seeds)
    verdict = adopted(differences)
    return {"name": name, "params": params, "differences": differences, "adopted": verdict[0],
            "why": verdict[1], "per_seed": runs, "scales": scales, "collapsed": collapsed_by_half(scales, groups)}


def screen_document(baseline: dict, baseline_runs: dict, baseline_scales: dict, seeds, groups: dict,
                    rows: list[dict]) -> dict:
    """What ``--json`` writes (and ``--pool`` reads)."""
    means = {label: float(np.mean([np.mean(baseline_runs[n]) for n in names])) for label, names in groups.items()}
    return {"baseline": baseline, "baseline_per_seed": baseline_runs, "baseline_scales": baseline_scales,
            "baseline_collapsed": collapsed_by_half(baseline_scales, groups), "seeds": list(seeds),
            "groups": groups, "baseline_means": means, "variants": rows}


def pool_screens(documents: list[dict], sources: list[str]) -> dict:
    """Screens (as ``--json`` writes them) at disjoint seeds joined into one, the verdicts
    recomputed over all seeds, for the variants (by name) that every screen has. ``sources``
    name the documents in errors.

    Raises
    ------
    NrmlcError
        When the screens share a seed, differ in baseline or targets, or share no variant.
    """
    first, seen = documents[0], {}
    for source, document in zip(sources, documents):
        for seed in document["seeds"]:
            if seed in seen:
                raise NrmlcError(f"--pool: seed {seed} is in both {seen[seed]} and {source}")
            seen[seed] = source
        for key, what in (("baseline", "baseline"), ("groups", "targets")):
            if document[key] != first[key]:
                raise NrmlcError(f"--pool: {source} has another {what} than {sources[0]}")
    names_in = [{v["name"] for v in document["variants"]} for document in documents]
    shared = [v["name"] for v in first["variants"] if all(v["name"] in names for names in names_in)]
    if not shared:
        raise NrmlcError(f"--pool: no variant is in every one of {', '.join(sources)}")

    def joined(key, where=lambda document: document):
        return {name: [x for document in documents for x in where(document)[key][name]]
                for name in where(first)[key]}

    seeds = [seed for document in documents for seed in document["seeds"]]
    groups = first["groups"]
    baseline_runs = joined("baseline_per_seed")
    rows = []
    for name in shared:
        def of_variant(document, name=name):
            return next(v for v in document["variants"] if v["name"] == name)
        rows.append(screen_row(name, of_variant(first)["params"], joined("per_seed", of_variant),
                               joined("scales", of_variant), baseline_runs, groups, seeds))
    return dict(screen_document(first["baseline"], baseline_runs, joined("baseline_scales"), seeds, groups, rows),
                pooled_from=sources)


def format_screen(rows: list[dict]) -> str:
    """Markdown: one row per variant, the paired differences on A, B, the synthetic suite, the verdict."""
    lines = ["| variant | half A | half B | synthetic suite | all real | collapsed (A, B) | verdict |",
             "|---|---|---|---|---|---|---|"]

    def cell(d):
        return "-" if d is None else f"{d['mean']:+.3f} ± {d['standard_error']:.3f} ({d['up']}↑ {d['down']}↓)"

    for row in rows:
        d = row["differences"]
        lines.append(f"| {row['name']} | {cell(d.get('A'))} | {cell(d.get('B'))} | "
                     f"{cell(d.get('synthetic suite'))} | {cell(d.get('all real'))} | "
                     f"{len(row['collapsed'].get('A', []))}, {len(row['collapsed'].get('B', []))} | "
                     f"{'ADOPT' if row['adopted'] else 'no'}: {row['why']} |")
    return "\n".join(lines)


def add_target_options(parser: argparse.ArgumentParser) -> None:
    """The options that pick the targets, seeds and frames (``screen``, ``expert_choice``)."""
    parser.add_argument("--data", default=None, help="data root(s) joined by ':' (as experiments.development.devset)")
    parser.add_argument("--seeds", default="0-2", help="seeds, e.g. 0-2 or 0,3,5; a number alone is that one seed")
    parser.add_argument("--synthetic", type=int, default=6, metavar="N")
    parser.add_argument("--half", choices=("A", "B", "all"), default="all")
    parser.add_argument("--sequences", default=None, help="a subset of the development targets ('': none)")
    parser.add_argument("--max-frames", type=int, default=None, help="track only the first N frames")


def add_run_options(parser: argparse.ArgumentParser) -> None:
    """The options for the runs and the report: workers, run cache, ``--json``, ``--markdown``."""
    parser.add_argument("--jobs", type=int, default=None)
    parser.add_argument("--cache", default=str(DEFAULT_CACHE))
    parser.add_argument("--json", default=None)
    parser.add_argument("--markdown", default=None)


def chosen_targets(args) -> tuple[list, list, dict]:
    """(seeds, sequences, their :func:`screen_groups`) that :func:`add_target_options`'s options
    name; raises NrmlcError."""
    seeds = parse_seeds(args.seeds)
    warn_few_seeds(args.seeds, seeds)
    names = selected_names(args.half, args.sequences)
    sequences = development_sequences(parse_roots(args.data) if names else None, names, args.synthetic)
    return seeds, sequences, screen_groups(sequences)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_target_options(parser)
    parser.add_argument("--baseline-preset", default="default")
    parser.add_argument("--baseline", default="", metavar="PARAM=VALUE,...", help="changes of the baseline")
    parser.add_argument("--variant", nargs=2, action="append", default=[], metavar=("NAME", "CHANGES"))
    parser.add_argument("--baseline-version", default=None, metavar="CODE_VERSION",
                        help="read the baseline's runs at this code version, after checking them bit for bit")
    parser.add_argument("--cached-only", action="store_true",
                        help="compute no variant: report those whose runs are all in the cache and skip the "
                             "rest (the baseline's missing runs are still computed)")
    add_run_options(parser)
    parser.add_argument("--pool", default=None, metavar="A.json,B.json",
                        help="run nothing: join these screens' JSONs (disjoint seeds) and judge over all seeds")
    args = parser.parse_args(argv)
    if args.pool:
        return _pool(args)
    try:
        baseline = parse_variant("baseline", args.baseline, args.baseline_preset)
        variants = [(name, parse_variant(name, text, args.baseline_preset)) for name, text in args.variant]
        seeds, sequences, groups = chosen_targets(args)
    except NrmlcError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    cache = RunCache(args.cache)
    batches = [specs_for(sequences, params, seeds, n_frames=args.max_frames) for _, params in [("baseline", baseline)] + variants]
    # One configuration at a time (the baseline first), so that an interrupted screen has
    # finished whole configurations, which a rerun reads from the cache.
    first = (baseline_at_version(cache, batches[0], args.baseline_version, args.jobs)
             if args.baseline_version else cache.run(batches[0], jobs=args.jobs))
    runs = [run_measures(first, batches[0])]
    if args.cached_only:
        complete = [all(cache.has(spec) for spec in batch) for batch in batches[1:]]
        skipped = [name for (name, _), done in zip(variants, complete) if not done]
        if skipped:
            print(f"not in the cache yet, skipped: {', '.join(skipped)}", file=sys.stderr)
        variants = [v for v, done in zip(variants, complete) if done]
        batches = batches[:1] + [b for b, done in zip(batches[1:], complete) if done]
    runs += [run_measures(cache.run(batch, jobs=args.jobs), batch) for batch in batches[1:]]
    base_overlaps, base_scales = overlaps_of(runs[0]), scales_of(runs[0])
    rows = [screen_row(name, params.as_dict(), overlaps_of(measures), scales_of(measures), base_overlaps, groups,
                       seeds)
            for (name, params), measures in zip(variants, runs[1:])]
    document = screen_document(baseline.as_dict(), base_overlaps, base_scales, seeds, groups, rows)
    print(f"baseline: preset {args.baseline_preset} {args.baseline or ''}; seeds {args.seeds}; mean overlap "
          + ", ".join(f"{label} {value:.3f}" for label, value in document["baseline_means"].items())
          + "; collapsed (scale < 0.7 over the last quarter): "
          + "; ".join(f"{label} {', '.join(names) or 'none'}" for label, names in document["baseline_collapsed"].items()))
    return _report(args, document)


def _report(args, document: dict) -> int:
    """Print a screen's table; write it (``--markdown``) and the document (``--json``)."""
    table = format_screen(document["variants"])
    print(table)
    if args.markdown:
        io.write_text(args.markdown, table + "\n")
    if args.json:
        io.write_json(args.json, document)
    return 0


def _pool(args) -> int:
    """``--pool``: print (and write) the pooled screen."""
    sources = [part for part in args.pool.split(",") if part]
    try:
        documents = [json.loads(Path(source).read_text()) for source in sources]
        pooled = pool_screens(documents, sources)
    except (NrmlcError, OSError, ValueError, KeyError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"pooled {len(sources)} screens: seeds {', '.join(map(str, pooled['seeds']))}")
    return _report(args, pooled)


if __name__ == "__main__":
    sys.exit(main())
