"""Gap evidence: the paper-era protocol of per-sequence motion parameters.

The trackers of the paper's lineage (IVT, L1, SCM, ASLA, LSK: the codebases
whose particle filter, 32x32 patches and positive/negative sampling the paper
reuses) ship a ``trackparam.m`` with one ``affsig`` (motion standard
deviations) per sequence; IVT's own notes tell the user to change them for a
new sequence. The paper states none of its motion parameters. nrmlc runs one
default set on every sequence (the project's rule), so part of the gap to the
paper's Table II may be this protocol, not the method.

This script measures how much. It reruns the paper's sequences with the
``affsig`` values of a public ``trackparam.m`` of that lineage, converted to
nrmlc's state convention, and shows them beside the default runs (the Table
II runs, from the cache) and the paper's numbers. It is diagnostic evidence
only: these are not nrmlc's defaults, and nothing here was chosen by looking
at our results.

Conversion. IVT's ``affsig = [x, y, scale, rotation, aspect, skew]`` is
additive on a state whose scale is ``width / 32`` and whose aspect is
``height / width``, in the pixels of the video the lineage used. nrmlc's
scale and aspect noise is multiplicative (relative), so

- scale sigma = affsig scale / (lineage box width / 32);
- aspect sigma = affsig aspect / (lineage box height / lineage box width);
- x, y sigmas are rescaled by (our box width / lineage box width), which is 1
  except for Car4, whose lineage frames are about twice ours;
- rotation and skew are angles and are kept.

Outputs ``figures/ablation_per_sequence_motion.{png,csv,json}``.
"""
from __future__ import annotations


import numpy as np

from experiments import paper_numbers as paper
from experiments.grid import script_entry, section
from experiments.sequence_sets import paper_name
from experiments.tables import fmt, mean_std, save_figure, write_csv
from nrmlc import io

STEM = "ablation_per_sequence_motion"
TITLE = "Per-sequence motion parameters (the paper-era protocol) vs one default set"

#: ``affsig`` and the initial box ``(width, height)`` of a public ``trackparam.m`` of the
#: IVT/L1/SCM lineage, for the sequences it shares with the paper (our names).
CLASSIC_MOTION = {
    "Car4": {"affsig": (4.0, 4.0, 0.02, 0.0, 0.0, 0.0), "box": (200.0, 150.0)},
    "Caviar1": {"affsig": (4.0, 4.0, 0.005, 0.0, 0.0, 0.0), "box": (30.0, 79.0)},
    "Occlusion1": {"affsig": (4.0, 4.0, 0.005, 0.0, 0.0, 0.0), "box": (115.0, 145.0)},
    "Occlusion2": {"affsig": (4.0, 4.0, 0.005, 0.015, 0.0, 0.0), "box": (74.0, 100.0)},
}


def converted_sigmas(affsig, lineage_box, our_box, template_side: int) -> tuple:
    """nrmlc ``motion_sigmas`` equivalent to an IVT ``affsig`` (see the module docstring).

    Parameters
    ----------
    affsig : 6 floats, IVT ``[x, y, scale, rotation, aspect, skew]`` standard deviations
    lineage_box : (width, height) of the initial box in the lineage's video
    our_box : (4,) our initial 1-based ``(x, y, w, h)`` box
    template_side : int, the side the state's scale refers to (32 in both conventions)

    Returns
    -------
    tuple of 6 float
    """
    width, height = (float(v) for v in lineage_box)
    pixel_ratio = float(our_box[2]) / width
    scale = width / template_side
    aspect = height / width
    x, y, s, r, a, k = (float(v) for v in affsig)
    return (x * pixel_ratio, y * pixel_ratio, s / scale, r, a / aspect, k)


def configurations(context) -> list[tuple[object, object, object]]:
    """(sequence, default params, per-sequence params) for every given sequence with classic values."""
    out = []
    for sequence in context.paper_sequences():
        classic = CLASSIC_MOTION.get(sequence.name)
        if classic is None:
            continue
        base = context.base_params
        sigmas = converted_sigmas(classic["affsig"], classic["box"], sequence.init_box, base.patch_size)
        classic = base.replace(motion_sigmas=sigmas)
        if "translation_noise" in base.as_dict():  # affsig's x, y are image pixels
            classic = classic.replace(translation_noise="pixels")
        out.append((sequence, base, classic))
    return out


def applies(context) -> str | None:
    """None when a given sequence has the lineage's motion parameters; else why not."""
    if configurations(context):
        return None
    return (f"none of the given sequences is in the lineage's `trackparam.m` ({', '.join(CLASSIC_MOTION)}), "
            "so there is nothing to compare.")


def runs(context) -> list:
    """The per-sequence runs and the default ones (the latter are Table II's, shared through the cache)."""
    return [spec for sequence, base, classic in configurations(context)
            for params, label in ((base, "per-sequence motion: default"), (classic, "per-sequence motion: classic"))
            for spec in context.specs([sequence], params, context.sweep_seeds, label=label)]


def collect(context) -> dict:
    rows = []
    for sequence, base, classic in configurations(context):
        row = {"sequence": sequence.name, "paper_name": paper_name(sequence.name),
               "motion_sigmas_default": list(base.motion_sigmas), "motion_sigmas_classic": list(classic.motion_sigmas),
               "affsig": list(CLASSIC_MOTION[sequence.name]["affsig"])}
        for key, params in (("default", base), ("classic", classic)):
            specs = context.specs([sequence], params, context.sweep_seeds)
            evaluations = context.evaluate(specs)
            overlaps = [e.mean_overlap for e in evaluations]
            row[f"overlap_{key}"], row[f"overlap_{key}_std"] = mean_std(overlaps)
            row[f"cle_{key}"], row[f"cle_{key}_std"] = mean_std(e.mean_center_error for e in evaluations)
            row[f"overlap_{key}_by_seed"] = overlaps
        name = paper_name(sequence.name)
        row["overlap_paper"] = paper.OVERLAP.get(name, {}).get("Ours")
        row["cle_paper"] = paper.CLE.get(name, {}).get("Ours")
        rows.append(row)
    return {"rows": rows, "seeds": list(context.sweep_seeds)}


def plot(data: dict, path) -> None:
    import matplotlib.pyplot as plt

    rows = data["rows"]
    fig, ax = plt.subplots(figsize=(max(1.9 * len(rows) + 2.0, 7.0), 3.6))
    if not rows:
        ax.text(0.5, 0.5, "None of the given sequences has motion parameters in the lineage's trackparam.m\n"
                          f"({', '.join(CLASSIC_MOTION)}): nothing to compare.", ha="center", va="center",
                fontsize=10, wrap=True)
        ax.set_axis_off()
    else:
        positions = np.arange(len(rows))
        bars = (("default", "one default set (nrmlc)", "tab:blue"),
                ("classic", "per-sequence affsig (lineage)", "tab:orange"))
        for offset, (key, label, colour) in zip((-0.27, 0.0), bars):
            ax.bar(positions + offset, [r[f"overlap_{key}"] for r in rows], width=0.27, label=label, color=colour,
                   yerr=np.nan_to_num([np.nan if r[f"overlap_{key}_std"] is None else r[f"overlap_{key}_std"]
                                       for r in rows]), capsize=3)
        ax.bar(positions + 0.27, [np.nan if r["overlap_paper"] is None else r["overlap_paper"] for r in rows],
               width=0.27, label="paper (Table II)", color="tab:gray")
        ax.set_xticks(positions)
        ax.set_xticklabels([r["sequence"] for r in rows])
        ax.set_ylim(0, 1.18)
        ax.set_yticks(np.linspace(0, 1, 6))
        ax.set_ylabel("mean overlap")
        ax.grid(axis="y", alpha=0.3)
        ax.legend(fontsize=8, loc="upper center", ncol=3)
    seeds = data["seeds"]
    ax.set_title("Motion parameters: one set for all sequences vs the lineage's per-sequence affsig\n"
                 + (f"seed {seeds[0]}" if len(seeds) == 1 else f"mean ± std over seeds {seeds}"), fontsize=9)
    save_figure(fig, path, dpi=100)


def report(context, data: dict) -> dict:
    """Write the numbers (CSV/JSON); returns the report section (``title``, ``figures``, ``markdown``)."""
    header = ["sequence", "motion_sigmas_classic", "overlap_default", "overlap_default_std", "overlap_classic",
              "overlap_classic_std", "overlap_paper", "cle_default", "cle_classic", "cle_paper"]
    write_csv(context.output(STEM, ".csv"), header,
              [[r["sequence"], " ".join(f"{v:g}" for v in r["motion_sigmas_classic"])] + [r[k] for k in header[2:]]
               for r in data["rows"]])
    io.write_json(context.output(STEM, ".json"), dict(data, title=TITLE, classic_motion=CLASSIC_MOTION))

    if not data["rows"]:
        return {"title": TITLE, "figures": [f"{STEM}.png"],
                "markdown": "None of the given sequences is in the lineage's `trackparam.m` "
                            "(Car4, Caviar1, Occlusion1, Occlusion2); nothing to compare."}
    text = [f"Mean overlap (± std over seeds {data['seeds']}) with nrmlc's one default motion model and with the "
            "per-sequence `affsig` of the paper's lineage, converted to our convention (diagnostic only; "
            "not a default)." + (f" First {context.max_frames} frames of each sequence only." if context.max_frames else ""),
            "",
            "| sequence | motion sigmas (classic, ours) | default | per-sequence | "
            f"paper{' (full seq.)' if context.max_frames else ''} |", "|---|---|---|---|---|"]
    for r in data["rows"]:
        sigmas = ", ".join(f"{v:g}" for v in r["motion_sigmas_classic"])
        text.append(f"| {r['sequence']} | {sigmas} | {fmt(r['overlap_default'], 2, r['overlap_default_std'])} | "
                    f"{fmt(r['overlap_classic'], 2, r['overlap_classic_std'])} | {fmt(r['overlap_paper'], 2)} |")
    default = float(np.mean([r["overlap_default"] for r in data["rows"]]))
    classic = float(np.mean([r["overlap_classic"] for r in data["rows"]]))
    papers = [r["overlap_paper"] for r in data["rows"] if r["overlap_paper"] is not None]
    text.append(f"| average | | {default:.3f} | {classic:.3f} | "
                f"{fmt(float(np.mean(papers)), 3) if len(papers) == len(data['rows']) else '–'} |")
    return section(TITLE, STEM, text)


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
