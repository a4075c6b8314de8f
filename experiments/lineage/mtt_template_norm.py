"""MTT's one departure, checked on development video: templates kept at unit norm against the L1
tracker's templates scaled to their weights (``MTTParams.template_norm``; docs/DEVIATIONS.md).

The departure was found on Car4, one of the paper's nine, which the protocol keeps for reporting.
Here both forms run live on the development targets of half A (the choosing half; B is not
spent on a faithfulness check), at the same seeds, through the run cache, and are scored as the
benchmark scores (mean overlap, frame 0 skipped). The verdict is per target and on the mean, with
its standard error over targets.

    python -m experiments.lineage.mtt_template_norm --seeds 0 --out figures/lineage

Writes ``<out>/mtt_template_norm.json`` and ``.md``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from experiments.development.devset import default_roots, development_sequences
from experiments.lineage.versus import lineage_overlaps
from experiments.sequence_sets import DEVELOPMENT_A
from nrmlc.io import write_json
from nrmlc.lineage.mtt import MTTParams, MTTTracker
from nrmlc.workbench.benchmark import parse_seeds
from nrmlc.workbench.run_cache import DEFAULT_CACHE, RunCache

STEM = "mtt_template_norm"
#: The two forms: the tracker as shipped, and the L1 tracker's weighted templates.
FORMS = {"unit norm (shipped)": "mtt", "scaled to the weights (the L1 tracker)": f"{__name__}:weighted_mtt"}


def weighted_mtt(seed: int = 0) -> MTTTracker:
    """MTT with the L1 tracker's weighted templates."""
    return MTTTracker(MTTParams(template_norm="weight"), seed=seed)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--max-frames", type=int, default=None)
    parser.add_argument("--jobs", type=int, default=None)
    parser.add_argument("--cache", default=str(DEFAULT_CACHE))
    parser.add_argument("--out", default="out/figures/lineage")
    args = parser.parse_args(argv)
    seeds = parse_seeds(args.seeds)
    sequences = development_sequences(default_roots(), DEVELOPMENT_A, 0)
    cache = RunCache(args.cache)
    overlaps = {form: lineage_overlaps(cache, spec, sequences, seeds, args.max_frames, args.jobs)
                for form, spec in FORMS.items()}
    unit, weight = (overlaps[form] for form in FORMS)
    names = [s.name for s in sequences]
    differences = np.array([np.mean(unit[n]) - np.mean(weight[n]) for n in names])
    lines = ["| target | " + " | ".join(FORMS) + " | unit minus weighted |", "|---|---:|---:|---:|"]
    for name, difference in zip(names, differences):
        lines.append(f"| {name} | {np.mean(unit[name]):.3f} | {np.mean(weight[name]):.3f} | {difference:+.3f} |")
    error = differences.std(ddof=1) / np.sqrt(len(differences))
    lines.append(f"| **mean of half A** | **{np.mean([np.mean(unit[n]) for n in names]):.3f}** | "
                 f"**{np.mean([np.mean(weight[n]) for n in names]):.3f}** | **{differences.mean():+.3f} ± {error:.3f}** |")
    summary = (f"MTT on half A's {len(names)} targets, seeds {args.seeds}"
               f"{'' if args.max_frames is None else f', first {args.max_frames} frames'}: unit-norm templates "
               f"minus weighted ones {differences.mean():+.3f} ± {error:.3f} mean overlap; unit norm better on "
               f"{int((differences > 0).sum())} targets, worse on {int((differences < 0).sum())}.")
    print("\n".join(lines) + "\n\n" + summary)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / f"{STEM}.json", {"seeds": seeds, "max_frames": args.max_frames, "overlaps": overlaps,
                                      "difference": float(differences.mean()), "standard_error": float(error),
                                      "summary": summary})
    (out / f"{STEM}.md").write_text(f"# {summary}\n\n" + "\n".join(lines) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
