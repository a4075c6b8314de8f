"""Fig. 1 of the paper: coding coefficients without and with the l2 term.

Two trackers, same seed, same sequence (Singer1 in the paper; here Singer1 if
given, else Caviar1, else the first paper sequence, else the first sequence):

* green: no l2 term, lambda = beta = 0 (approximated LLC with only 1'c = 1);
* red: lambda = 1, beta = 0.1 (the paper's setting).

At a representative frame (the first frame where the two boxes overlap by less
than IoU 0.3, i.e. where the results part; if they never part, the frame 1/3 into
the run) we plot each tracker's best-candidate code d against template index
(positives #1..#p first, then negatives, as in the paper) and show the frame with
both boxes. We also count negative coefficients at that frame and over all frames.
Runs go through the shared run cache (``context.run``).
"""
from __future__ import annotations


import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Rectangle

from experiments.grid import json_report, script_entry
from experiments.grid import describe_params
from experiments.internals import Budget, budget_for, tracker_params
from experiments.tables import save_figure
from nrmlc.workbench.metrics import overlaps
from nrmlc.workbench.jobs import RunSpec

STEM = "fig1_coefficients"
#: ``report(context, data)``: writes ``<STEM>.json``, returns the report section.
report = json_report(STEM)
PART_IOU = 0.3
TOLERANCE = 1e-9  # a coefficient below -TOLERANCE counts as negative

SYNTHETIC_BUDGET = Budget(max_frames=None)
REAL_BUDGET = Budget(max_frames=None)


def pick_sequence(context):
    sequence = context.sequence("Singer1", "Caviar1")
    if sequence is None:
        paper = context.paper_sequences()
        sequence = paper[0] if paper else context.sequences()[0]
    return sequence


def dense_code(diagnostics: dict, frame: int) -> tuple[np.ndarray, int]:
    """The best candidate's d over all templates at ``frame`` (zeros off its support)."""
    n_templates = int(diagnostics["n_templates"][frame])
    d = np.zeros(n_templates)
    d[diagnostics["template_indices"][frame].astype(int)] = diagnostics["codes"][frame]
    return d, int(diagnostics["n_positive_templates"][frame])


def representative_frame(boxes_a: np.ndarray, boxes_b: np.ndarray) -> tuple[int, str]:
    iou = overlaps(boxes_a, boxes_b)
    parted = np.flatnonzero(iou[1:] < PART_IOU)
    if parted.size:
        return int(parted[0] + 1), f"first frame where the two boxes overlap by IoU < {PART_IOU}"
    frame = max(1, len(boxes_a) // 3)
    return frame, f"the two boxes never part (IoU >= {PART_IOU} throughout), so the frame 1/3 into the run"


def negative_counts(diagnostics: dict) -> np.ndarray:
    """Per frame: negative entries of the best candidate's d (frame 0 has none)."""
    counts = (diagnostics["codes"] < -TOLERANCE).sum(axis=1)
    counts[0] = 0
    return counts


def _plan(context, budget: Budget):
    """(sequence, seed, {setup name: params}, [RunSpec per setup])."""
    sequence = pick_sequence(context)
    seed = int((budget.seeds or context.seeds)[0])
    setups = {"no_l2": tracker_params(budget, context, coding="regularized", lam=0.0, beta=0.0),
              "l2": tracker_params(budget, context, coding="regularized", lam=1.0, beta=0.1)}
    specs = [RunSpec(sequence=sequence, params=p, seed=seed, n_frames=budget.max_frames, label=f"fig1 {name}")
             for name, p in setups.items()]
    return sequence, seed, setups, specs


def runs(context) -> list:
    """The tracking runs :func:`main` needs (run_all schedules them in its shared grid)."""
    return _plan(context, budget_for(context, SYNTHETIC_BUDGET, REAL_BUDGET))[3]


def collect(context) -> dict:
    """The numbers and what the figure needs (the JSON, the plot's inputs, the report section)."""
    budget = budget_for(context, SYNTHETIC_BUDGET, REAL_BUDGET)
    sequence, seed, setups, specs = _plan(context, budget)
    runs = dict(zip(setups, context.run(specs)))

    frame, why = representative_frame(runs["no_l2"].boxes, runs["l2"].boxes)
    result = {"sequence": sequence.name, "seed": seed, "n_frames": len(runs["l2"].boxes), "frame": frame,
              "params_description": describe_params(setups["l2"]),
              "frame_rule": why, "trackers": {}}
    gt = sequence.groundtruth[: len(runs["l2"].boxes)]
    for name, run in runs.items():
        d, n_pos = dense_code(run.diagnostics, frame)
        counts = negative_counts(run.diagnostics)
        used = np.flatnonzero(np.abs(d) > 1e-6)
        iou = overlaps(run.boxes[1:], gt[1:])
        result["trackers"][name] = {
            "lam": setups[name].lam, "beta": setups[name].beta,
            "box": run.boxes[frame].tolist(),
            "templates_used_1based": (used + 1).tolist(),
            "coefficients_used": d[used].tolist(),
            "n_positive_templates": n_pos,
            "n_negative_coefficients": int((d < -TOLERANCE).sum()),
            "n_negative_on_positive_templates": int((d[:n_pos] < -TOLERANCE).sum()),
            "n_negative_templates_used": int((np.abs(d[n_pos:]) > 1e-6).sum()),
            "mean_negative_coefficients_per_frame": float(counts[1:].mean()) if len(counts) > 1 else 0.0,
            "share_frames_with_negative_coefficient": float((counts[1:] > 0).mean()) if len(counts) > 1 else 0.0,
            "mean_overlap_with_groundtruth": float(np.nanmean(iou)) if np.isfinite(iou).any() else None,
        }
    section = {"title": f"Fig. 1: coding coefficients without / with the l2 term ({sequence.name})",
               "figures": [f"{STEM}.png"], "markdown": _markdown(result)}
    return {"result": result, "plot": (sequence, runs, frame, result), "section": section}


def label_groups(indices, values, span: float) -> list[tuple[float, float, str]]:
    """One label per cluster of nearby templates, so that labels never overlap.

    Parameters
    ----------
    indices : sorted 0-based template indices with a non-zero code
    values : their codes
    span : indices closer than this share a label

    Returns
    -------
    list of (x, y, text): 1-based x of the cluster's middle, the cluster's code of largest
    magnitude, and ``#i`` names (``#i-#j (n)`` for more than three).
    """
    groups: list[list[int]] = []
    for position, index in enumerate(indices):
        if groups and index - indices[groups[-1][-1]] < span:
            groups[-1].append(position)
        else:
            groups.append([position])
    out = []
    for group in groups:
        names = [int(indices[p]) + 1 for p in group]
        peak = max(group, key=lambda p: abs(values[p]))
        text = ", ".join(f"#{n}" for n in names) if len(names) <= 3 else f"#{names[0]}-#{names[-1]} ({len(names)})"
        out.append((float(np.mean(names)), float(values[peak]), text))
    return out


def plot(data: dict, path) -> None:
    sequence, runs, frame, result = data["plot"]
    fig = plt.figure(figsize=(13, 4.2))
    grid = fig.add_gridspec(1, 3, width_ratios=[1.2, 1.2, 1])
    colours = {"no_l2": "green", "l2": "red"}
    labels = {"no_l2": r"no $\ell_2$ ($\lambda=\beta=0$)", "l2": r"$\lambda=1$, $\beta=0.1$"}
    for column, (name, run) in enumerate(runs.items()):
        ax = fig.add_subplot(grid[0, column])  # own y scale: the codes differ by an order of magnitude
        d, n_pos = dense_code(run.diagnostics, frame)
        index = np.arange(1, len(d) + 1)
        used = np.abs(d) > 1e-6
        ax.axhline(0, color="0.6", lw=0.8)
        ax.axvspan(0.5, n_pos + 0.5, color="tab:blue", alpha=0.06, label=f"positive #1-#{n_pos}")
        ax.vlines(index[used], 0, d[used], color=colours[name], lw=2)
        ax.plot(index[used], d[used], "o", color=colours[name], ms=4)
        picked = np.flatnonzero(used)
        for x, y, text in label_groups(picked, d[picked], span=len(d) / 12):
            ax.annotate(text, (x, y), fontsize=6, ha="center", va="bottom" if y >= 0 else "top",
                        xytext=(0, 3 if y >= 0 else -3), textcoords="offset points")
        low, high = min(d.min(), 0.0), max(d.max(), 0.0)
        pad = 0.35 * (high - low or 1.0)
        ax.set_ylim(low - (pad if low < 0 else 0.05 * pad), high + pad)
        ax.set_xlim(0.5, len(d) + 0.5)
        ax.set_xlabel(f"template index (#1-#{n_pos} positive, #{n_pos + 1}-#{len(d)} negative)")
        ax.set_ylabel("coefficient $d$")
        info = result["trackers"][name]
        ax.set_title(f"{labels[name]}: {info['n_negative_coefficients']} negative", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
        ax.grid(alpha=0.3)
    ax = fig.add_subplot(grid[0, 2])
    image = sequence.color_frame(frame)[:, :, ::-1]
    ax.imshow(image)
    for name, run in runs.items():
        x, y, w, h = run.boxes[frame]
        ax.add_patch(Rectangle((x - 1, y - 1), w, h, fill=False, color=colours[name], lw=2))
    gt = sequence.groundtruth[frame]
    if np.isfinite(gt).all():
        ax.add_patch(Rectangle((gt[0] - 1, gt[1] - 1), gt[2], gt[3], fill=False, color="yellow", lw=1, ls="--"))
    corners = [run.boxes[frame] for run in runs.values()] + ([gt] if np.isfinite(gt).all() else [])
    left = min(b[0] - 1 for b in corners)
    top = min(b[1] - 1 for b in corners)
    right = max(b[0] - 1 + b[2] for b in corners)
    bottom = max(b[1] - 1 + b[3] for b in corners)
    margin = max(right - left, bottom - top)
    height, width = image.shape[:2]
    ax.set_xlim(max(left - margin, -0.5), min(right + margin, width - 0.5))
    ax.set_ylim(min(bottom + margin, height - 0.5), max(top - margin, -0.5))
    ax.set_title(f"{sequence.name} #{frame + 1} (green: no l2, red: l2, yellow: GT)", fontsize=8)
    ax.axis("off")
    save_figure(fig, path, dpi=120)


def _markdown(result) -> str:
    a, b = result["trackers"]["no_l2"], result["trackers"]["l2"]

    def overlap(info):
        return "n/a" if info["mean_overlap_with_groundtruth"] is None else f"{info['mean_overlap_with_groundtruth']:.2f}"

    def templates(info):
        return ", ".join(f"#{i} ({c:+.3f})" for i, c in zip(info["templates_used_1based"], info["coefficients_used"]))

    lines = [
        f"### Fig. 1: coding coefficients without / with the l2 term ({result['sequence']})",
        "",
        f"Sequence {result['sequence']} (the paper uses Singer1), seed {result['seed']}, {result['n_frames']} frames "
        f"tracked by each tracker; other parameters: {result['params_description']}. "
        f"Shown frame: #{result['frame'] + 1} ({result['frame_rule']}). "
        "Template numbering as in the paper: positives first, then negatives.",
        "",
        "| | paper (Singer1) | no l2 (lambda = beta = 0) | lambda = 1, beta = 0.1 |",
        "|---|---|---|---|",
        f"| templates used by the best candidate at the shown frame | 8 / 8 | {len(a['templates_used_1based'])} | "
        f"{len(b['templates_used_1based'])} |",
        f"| negative coefficients at the shown frame | 3 (#6, #32, #47) / 0 | {a['n_negative_coefficients']} | "
        f"{b['n_negative_coefficients']} |",
        f"| ... of which on positive templates | 3 / 0 | {a['n_negative_on_positive_templates']} | "
        f"{b['n_negative_on_positive_templates']} |",
        f"| negative templates used at the shown frame | 0 / 0 | {a['n_negative_templates_used']} | "
        f"{b['n_negative_templates_used']} |",
        f"| mean negative coefficients per frame (best candidate) | - | {a['mean_negative_coefficients_per_frame']:.2f} | "
        f"{b['mean_negative_coefficients_per_frame']:.2f} |",
        f"| share of frames with a negative coefficient | - | {a['share_frames_with_negative_coefficient']:.1%} | "
        f"{b['share_frames_with_negative_coefficient']:.1%} |",
        f"| mean overlap with ground truth over the run | bad / good | {overlap(a)} | {overlap(b)} |",
        "",
        f"Codes at the shown frame. No l2: {templates(a)}. With l2: {templates(b)}.",
    ]
    return "\n".join(lines) + "\n"


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
