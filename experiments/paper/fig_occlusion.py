"""The occlusion figure of the paper (Sec. 3.5): an occluded target coded on positive
and negative templates, and LEN(neg*) over time.

Sequence: Occlusion1 (the sparse-tracker FaceOcc1) near frame #528, the paper's
example ("six positive templates and four negative templates"), when given; else
a synthetic sequence, whose occlusion episode is annotated
(``SyntheticSequence.occluded``). On synthetic data we also measure how often the
occlusion flag (LEN(neg*) > occlusion_max_negative) fires on annotated-occlusion
frames vs the other frames. Runs go through the shared run cache.
"""
from __future__ import annotations


import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Patch, Rectangle

from experiments.grid import json_report, script_entry
from experiments.grid import describe_params
from experiments.internals import Budget, budget_for, tracker_params
from experiments.tables import save_figure
from nrmlc.workbench.jobs import RunSpec

STEM = "fig_occlusion"
#: ``report(context, data)``: writes ``<STEM>.json``, returns the report section.
report = json_report(STEM)
PAPER_FRAME = 528  # 1-based, as printed
SYNTHETIC_BUDGET = Budget(max_frames=None)
REAL_BUDGET = Budget(max_frames=None, seeds=(0,))


def pick_sequence(context):
    """(sequence, is the paper's Occlusion1)."""
    sequence = context.sequence("Occlusion1", "FaceOcc1")
    if sequence is not None:
        return sequence, True
    annotated = [s for s in context.sequences() if getattr(s, "occluded", None) is not None]
    if annotated:
        return annotated[0], False
    from nrmlc.data import synthetic_suite

    return synthetic_suite(n_sequences=1)[0], False


def synthetic_sequences(context):
    if context.is_synthetic:
        return [s for s in context.sequences() if getattr(s, "occluded", None) is not None]
    from nrmlc.data import synthetic_suite

    return synthetic_suite(n_sequences=getattr(context, "n_synthetic", 3))


def code_parts(diagnostics: dict, frame: int) -> tuple[np.ndarray, int]:
    n_templates = int(diagnostics["n_templates"][frame])
    d = np.zeros(n_templates)
    d[diagnostics["template_indices"][frame].astype(int)] = diagnostics["codes"][frame]
    return d, int(diagnostics["n_positive_templates"][frame])


def _positive_used(diagnostics: dict, tolerance: float) -> np.ndarray:
    """Per frame: positive templates with a non-zero code in the best candidate's d."""
    indices = np.asarray(diagnostics["template_indices"])
    codes = np.nan_to_num(np.asarray(diagnostics["codes"]))
    n_pos = np.asarray(diagnostics["n_positive_templates"])[:, None]
    return ((indices < n_pos) & (np.abs(codes) > tolerance)).sum(axis=1)


def flag_statistics(runs: list) -> dict:
    """How often the flag fires on annotated-occlusion frames vs other frames (frame 0 excluded)."""
    per_sequence = {}
    on_occ, n_occ, on_other, n_other = 0, 0, 0, 0
    len_occ, len_other = [], []
    for sequence, run in runs:
        n = len(run.boxes)
        truth = np.asarray(sequence.occluded[:n], dtype=bool)[1:]
        flag = np.asarray(run.diagnostics["occluded"], dtype=bool)[1:n]
        lengths = np.asarray(run.diagnostics["n_negative_used"])[1:n]
        entry = per_sequence.setdefault(sequence.name, {"occ_flagged": 0, "occ_frames": 0, "other_flagged": 0,
                                                        "other_frames": 0})
        entry["occ_flagged"] += int(flag[truth].sum())
        entry["occ_frames"] += int(truth.sum())
        entry["other_flagged"] += int(flag[~truth].sum())
        entry["other_frames"] += int((~truth).sum())
        on_occ += int(flag[truth].sum())
        n_occ += int(truth.sum())
        on_other += int(flag[~truth].sum())
        n_other += int((~truth).sum())
        len_occ.append(lengths[truth])
        len_other.append(lengths[~truth])
    len_occ = np.concatenate(len_occ) if len_occ else np.zeros(0)
    len_other = np.concatenate(len_other) if len_other else np.zeros(0)
    return {
        "sequences": sorted({s.name for s, _ in runs}),
        "flag_rate_occluded_frames": on_occ / n_occ if n_occ else None,
        "flag_rate_other_frames": on_other / n_other if n_other else None,
        "occluded_frames": n_occ, "other_frames": n_other,
        "mean_len_neg_occluded": float(len_occ.mean()) if len_occ.size else None,
        "mean_len_neg_other": float(len_other.mean()) if len_other.size else None,
        "per_sequence": per_sequence,
    }


def _plan(context, budget: Budget) -> dict:
    params = tracker_params(budget, context)
    seeds = tuple(int(s) for s in (budget.seeds or context.seeds))
    sequence, is_paper = pick_sequence(context)
    main_spec = RunSpec(sequence=sequence, params=params, seed=seeds[0], n_frames=budget.max_frames,
                        label="occlusion")
    synthetic = synthetic_sequences(context)
    synthetic_seeds = seeds if context.is_synthetic else seeds[:1]
    flag_specs = [RunSpec(sequence=s, params=params, seed=seed, n_frames=budget.max_frames, label="occlusion flags")
                  for s in synthetic for seed in synthetic_seeds]
    return dict(params=params, seeds=seeds, sequence=sequence, is_paper=is_paper, synthetic=synthetic,
                synthetic_seeds=synthetic_seeds, specs=[main_spec] + flag_specs)


def runs(context) -> list:
    """The tracking runs :func:`main` needs (run_all schedules them in its shared grid)."""
    return _plan(context, budget_for(context, SYNTHETIC_BUDGET, REAL_BUDGET))["specs"]


def collect(context) -> dict:
    """The numbers and what the figure needs (the JSON, the plot's inputs, the report section)."""
    budget = budget_for(context, SYNTHETIC_BUDGET, REAL_BUDGET)
    plan = _plan(context, budget)
    params, seeds, sequence, is_paper = plan["params"], plan["seeds"], plan["sequence"], plan["is_paper"]
    synthetic, synthetic_seeds = plan["synthetic"], plan["synthetic_seeds"]
    results = context.run(plan["specs"])
    run, flag_runs = results[0], results[1:]
    diagnostics = run.diagnostics
    n = len(run.boxes)
    lengths = np.asarray(diagnostics["n_negative_used"])
    flags = np.asarray(diagnostics["occluded"], dtype=bool)
    truth = getattr(sequence, "occluded", None)

    if is_paper and PAPER_FRAME - 1 < n:
        frame, why = PAPER_FRAME - 1, f"the paper's frame #{PAPER_FRAME}"
    else:
        window = np.arange(1, n)
        if truth is not None and np.asarray(truth[:n])[1:].any():
            window = np.flatnonzero(np.asarray(truth[:n], dtype=bool))
            window = window[window >= 1]
            scope = "annotated occlusion frames"
        else:
            scope = "tracked frames"
        positive_used = _positive_used(diagnostics, params.coefficient_tolerance)
        mixed = window[positive_used[window] > 0]
        if mixed.size:
            frame = int(mixed[np.argmax(lengths[mixed])])
            why = (f"the frame with the largest LEN(neg*) among the {scope} whose best candidate still uses "
                   "a positive template, i.e. a mixed representation as in the paper's figure")
        else:
            frame = int(window[np.argmax(lengths[window])])
            why = f"the frame with the largest LEN(neg*) among the {scope}"
        if is_paper:
            why += f" (frame #{PAPER_FRAME} is beyond the {n} frames tracked)"
    d, n_pos = code_parts(diagnostics, frame)
    used = np.abs(d) > params.coefficient_tolerance
    stats = flag_statistics(list(zip([s for s in synthetic for _ in synthetic_seeds], flag_runs)))
    result = {
        "sequence": sequence.name, "is_paper_sequence": is_paper, "seed": seeds[0], "n_frames": n,
        "frame": frame, "frame_rule": why, "params_description": describe_params(params),
        "params": {"occlusion_max_negative": params.occlusion_max_negative,
                   "coefficient_tolerance": params.coefficient_tolerance},
        "at_frame": {
            "positive_templates_used": int(used[:n_pos].sum()), "negative_templates_used": int(used[n_pos:].sum()),
            "len_neg": int(lengths[frame]), "occluded_flag": bool(flags[frame]),
            "sum_positive": float(d[:n_pos].sum()), "sum_negative": float(d[n_pos:].sum()),
            "n_positive_templates": n_pos, "n_templates": len(d),
        },
        "whole_run": {"share_frames_flagged": float(flags[1:].mean()) if n > 1 else 0.0,
                      "mean_len_neg": float(lengths[1:].mean()) if n > 1 else 0.0,
                      "max_len_neg": int(lengths[1:].max()) if n > 1 else 0,
                      "max_len_neg_frame": int(np.argmax(lengths[1:]) + 1) if n > 1 else 0},
        "synthetic_flag_statistics": {**stats, "seeds": list(synthetic_seeds)},
    }
    title = f"Occlusion detection: template contributions and LEN(neg*) ({sequence.name})"
    section = {"title": title, "figures": [f"{STEM}.png"], "markdown": _markdown(result, title)}
    return {"result": result, "section": section,
            "plot": (sequence, run, frame, d, n_pos, lengths, flags, truth, params.occlusion_max_negative)}


def plot(data: dict, path) -> None:
    sequence, run, frame, d, n_pos, lengths, flags, truth, threshold = data["plot"]
    fig = plt.figure(figsize=(12, 7))
    grid = fig.add_gridspec(2, 3, height_ratios=[1.1, 1])
    ax = fig.add_subplot(grid[0, 0])
    image = sequence.color_frame(frame)[:, :, ::-1]
    x, y, w, h = run.boxes[frame]
    height, width = image.shape[:2]
    ax.imshow(image)
    ax.add_patch(Rectangle((x - 1, y - 1), w, h, fill=False, color="red", lw=2))
    gt = sequence.groundtruth[frame]
    if np.isfinite(gt).all():
        ax.add_patch(Rectangle((gt[0] - 1, gt[1] - 1), gt[2], gt[3], fill=False, color="yellow", lw=1, ls="--"))
    margin = 0.6 * max(w, h)
    ax.set_xlim(max(x - 1 - margin, -0.5), min(x - 1 + w + margin, width - 0.5))
    ax.set_ylim(min(y - 1 + h + margin, height - 0.5), max(y - 1 - margin, -0.5))
    ax.set_title(f"{sequence.name} #{frame + 1} (red: tracked, yellow: GT)", fontsize=9)
    ax.axis("off")

    ax = fig.add_subplot(grid[0, 1:])
    index = np.arange(1, len(d) + 1)
    positive = index <= n_pos
    used = np.abs(d) > 0
    ax.bar(index[positive & used], d[positive & used], width=1.5, color="tab:blue")
    ax.bar(index[~positive & used], d[~positive & used], width=1.5, color="tab:red")
    handles = [Patch(color="tab:blue", label=f"positive templates ({int((positive & used).sum())} used)"),
               Patch(color="tab:red", label=f"negative templates ({int((~positive & used).sum())} used)")]
    ax.axvline(n_pos + 0.5, color="0.5", ls=":", lw=1)
    ax.axhline(0, color="0.6", lw=0.8)
    ax.set_xlim(0.5, len(d) + 0.5)
    ax.set_xlabel(f"template index (#1-#{n_pos} positive, #{n_pos + 1}-#{len(d)} negative)")
    ax.set_ylabel("coefficient $d$ of the best candidate")
    ax.legend(handles=handles, fontsize=8)
    ax.grid(alpha=0.3)

    ax = fig.add_subplot(grid[1, :])
    frames = np.arange(1, len(lengths))
    ax.plot(frames + 1, lengths[1:], color="k", lw=0.8, label="LEN(neg*)")
    flagged = np.flatnonzero(flags[1:]) + 2
    ax.plot(flagged, lengths[flagged - 1], "r.", ms=3, label="occlusion flag (LEN > threshold)")
    ax.axhline(threshold + 0.5, color="red", ls="--", lw=1, label=f"threshold: LEN > {threshold}")
    if truth is not None:
        occluded = np.asarray(truth[: len(lengths)], dtype=bool)
        ax.fill_between(np.arange(1, len(lengths) + 1), 0, 1, where=occluded, transform=ax.get_xaxis_transform(),
                        color="0.7", alpha=0.4, step="mid", label="annotated occlusion")
    ax.axvline(frame + 1, color="tab:blue", lw=1, label=f"shown frame #{frame + 1}")
    ax.set_xlabel("frame")
    ax.set_ylabel("negative templates used")
    ax.set_ylim(-0.3, max(float(lengths[1:].max()) if len(lengths) > 1 else 0.0, threshold + 1) * 1.4 + 0.5)
    ax.legend(fontsize=7, ncol=5, loc="upper left")
    ax.grid(alpha=0.3)
    save_figure(fig, path, dpi=120)


def _markdown(result, title) -> str:
    at, whole, stats = result["at_frame"], result["whole_run"], result["synthetic_flag_statistics"]
    threshold = result["params"]["occlusion_max_negative"]

    def rate(value):
        return "n/a" if value is None else f"{value:.1%}"

    lines = [
        f"### {title}",
        "",
        f"Sequence {result['sequence']}, seed {result['seed']}, {result['params_description']}, {result['n_frames']} frames "
        f"tracked; shown frame #{result['frame'] + 1} ({result['frame_rule']}). A template counts as used when "
        f"|d| > {result['params']['coefficient_tolerance']:g}; the flag fires when LEN(neg*) > {threshold} "
        "(Algorithm 2 updates positives iff LEN(neg*) <= 2; the text says 'more than one', i.e. LEN >= 2).",
        "",
        "| | paper (Occlusion1 #528) | measured |",
        "|---|---|---|",
        f"| positive templates used by the best candidate | 6 | {at['positive_templates_used']} |",
        f"| negative templates used, LEN(neg*) | 4 | {at['negative_templates_used']} |",
        f"| occlusion flag at that frame | yes (heavily occluded) | {'yes' if at['occluded_flag'] else 'no'} |",
        f"| sum of d on positive / negative templates | - | {at['sum_positive']:.3f} / {at['sum_negative']:.3f} |",
        f"| share of frames flagged over the run | - | {whole['share_frames_flagged']:.1%} |",
        f"| mean LEN(neg*) over the run | - | {whole['mean_len_neg']:.2f} |",
        f"| max LEN(neg*) over the run | - | {whole['max_len_neg']} (frame #{whole['max_len_neg_frame'] + 1}) |",
        "",
        f"Flag vs annotated occlusion (synthetic suite: {', '.join(stats['sequences'])}; seeds {stats['seeds']}; "
        f"same parameters): the flag fires on {rate(stats['flag_rate_occluded_frames'])} of the "
        f"{stats['occluded_frames']} annotated-occlusion frames and on {rate(stats['flag_rate_other_frames'])} of the "
        f"{stats['other_frames']} other frames; mean LEN(neg*) {stats['mean_len_neg_occluded'] or 0:.2f} vs "
        f"{stats['mean_len_neg_other'] or 0:.2f}. Per sequence (occluded / other): "
        + "; ".join(f"{n}: {v['occ_flagged']}/{v['occ_frames']} vs {v['other_flagged']}/{v['other_frames']}"
                    for n, v in stats["per_sequence"].items())
        + ". No real sequence here has per-frame occlusion labels, so this is measured on synthetic data only.",
    ]
    return "\n".join(lines) + "\n"


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
