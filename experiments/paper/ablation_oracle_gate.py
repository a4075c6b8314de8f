"""Gap evidence: would a better update rule close the gap? The positive update gated by the truth.

At every template update the tracker's rule (the result joins the positives when eps_pos* is
below ``update_error_threshold`` and the frame is not judged occluded) is replaced or combined
with a ground-truth oracle, "on the target" = the box overlaps the truth by at least
:data:`ORACLE_IOU`:

- **rule**: the ordinary default runs (shared with the other scripts through the cache);
- **rule and truth**: the oracle only refuses (no result off the target joins: no contamination);
- **rule or truth**: the oracle only adds (every result on the target joins: no starvation);
- **truth**: the oracle alone.

Frames without ground truth keep the rule. The negatives, the particles and everything else are
the tracker's own. If even the oracle gate leaves the overlap where it is, the update rule is
not what loses the target: the appearance model and the likelihood are. Diagnostic only: the
ground truth decides the updates, never a parameter.

Sequences: the development ones and the paper's that are given (the synthetic suite without
data), the ablation seeds. Outputs ``ablation_oracle_gate.{png,csv,json}``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from experiments.grid import score, script_entry
from experiments.shared import blocks
from experiments.tables import fmt, mean_std, save_figure, write_csv
from nrmlc import io
from nrmlc.geometry import usable_boxes
from nrmlc.workbench.metrics import overlaps
from nrmlc.workbench.jobs import TrackerJob
from nrmlc.tracker.algorithm import NRMLCTracker
from nrmlc.tracker.experts import ExpertPair
from nrmlc.tracker.loop import track_sequence

STEM = "ablation_oracle_gate"
TITLE = "The positive update gated by the ground truth: does a better update rule close the gap?"

#: A result is "on the target" when its box overlaps the ground truth by at least this.
ORACLE_IOU = 0.5
#: The gates, the tracker's own first.
GATES = ("rule", "rule and truth", "rule or truth", "truth")
#: Bump when the job's output changes for the same inputs.
ORACLE_VERSION = 2  # 2: a second expert learns under the same gate


class OracleGateTracker(NRMLCTracker):
    """:class:`NRMLCTracker` whose positive update follows ``gate`` (module docstring), given the
    ground truth ``truth`` (n_frames, 4) of the frames it tracks."""

    def __init__(self, truth: np.ndarray, gate: str, **kwargs) -> None:
        super().__init__(**kwargs)
        self.truth = np.asarray(truth, dtype=np.float64)
        self.gate = gate

    def update_templates(self, frame, result, estimate_patch) -> None:
        index = self.frame_index
        if self.gate == "rule" or index >= len(self.truth) or not usable_boxes(self.truth[index]):
            super().update_templates(frame, result, estimate_patch)
            return
        p = self.params
        rule = not (p.occlusion_detection and result.occluded) and result.error_positive < p.update_error_threshold
        on_target = bool(overlaps(result.box[None, :], self.truth[index][None, :])[0] >= ORACLE_IOU)
        accept = {"truth": on_target, "rule and truth": rule and on_target, "rule or truth": rule or on_target}[self.gate]
        # The update reads only these two fields; they are restored after it (it sets
        # ``updated_positive``), so the frame's diagnostics stay the tracker's own.
        kept = result.occluded, result.error_positive
        result.occluded, result.error_positive = not accept, (0.0 if accept else np.inf)
        try:
            super().update_templates(frame, result, estimate_patch)
        finally:
            result.occluded, result.error_positive = kept


def oracle_gate_tracker(truth: np.ndarray, gate: str, seed: int, params):
    """The tracker ``params`` describe with every expert's update under ``gate`` (a pair's second
    expert learns under the same gate)."""
    if params.second_expert == "off":
        return OracleGateTracker(truth, gate, seed=seed, params=params)
    pair = ExpertPair(seed, params)
    pair.experts = tuple(OracleGateTracker(truth, gate, seed=seed, params=expert.params) for expert in pair.experts)
    return pair


@dataclass(frozen=True)
class OracleGateRun(TrackerJob):
    """One run of :class:`OracleGateTracker`: a job of :class:`nrmlc.workbench.run_cache.RunCache`, stored under
    ``<cache>/oracle_gate/``."""

    gate: str
    n_frames: int | None = None

    folder: ClassVar[str] = "oracle_gate"
    label_template: ClassVar[str] = "oracle gate ({job.gate}) on {job.sequence.name}"

    def description(self, version: str) -> dict:
        return self.tracker_description(version, gate=self.gate, oracle_iou=ORACLE_IOU, n_frames=self.n_frames,
                                        oracle_version=ORACLE_VERSION)

    def execute(self) -> dict:
        n = self.frames()
        truth = np.asarray(self.sequence.groundtruth, dtype=np.float64)[:n]
        tracker = oracle_gate_tracker(truth, self.gate, self.seed, self.params)
        run = track_sequence(self.sequence, n_frames=n, tracker=tracker)
        updates = np.asarray(run.diagnostics.get("updated_positive", np.zeros(n)), dtype=bool)
        updates[0] = False
        return {"boxes": run.boxes, "updated_positive": updates, "seconds": np.float64(run.seconds_total)}


def _jobs(context, sequences, gate: str) -> list:
    seeds = context.ablation_seeds
    if gate == "rule":
        return context.specs(sequences, context.base_params, seeds, label="oracle gate: rule")
    return [OracleGateRun(s, context.base_params, int(seed), gate, context.max_frames)
            for s in sequences for seed in seeds]


def runs(context) -> list:
    """Every gate on every block's sequences, ablation seeds (the rule's runs are the grid's)."""
    return [job for _, sequences in blocks(context) for gate in GATES for job in _jobs(context, sequences, gate)]


def collect(context) -> dict:
    rows = []
    block_list = blocks(context)
    for block, sequences in block_list:
        for sequence in sequences:
            row = {"block": block, "sequence": sequence.name}
            for gate in GATES:
                results = context.cache.run(_jobs(context, [sequence], gate), executor=context.executor,
                                            jobs=context.jobs)
                boxes = [r.boxes if gate == "rule" else r["boxes"] for r in results]
                updated = [r.diagnostics["updated_positive"][1:] if gate == "rule" else r["updated_positive"][1:]
                           for r in results]
                row[gate], row[f"{gate} std"] = mean_std(score(b, sequence, context.max_frames).mean_overlap
                                                         for b in boxes)
                row[f"{gate} updates"] = float(np.mean([100.0 * np.mean(u) for u in updated]))
            rows.append(row)
    averages = {block: {gate: float(np.mean([r[gate] for r in rows if r["block"] == block])) for gate in GATES}
                for block, _ in block_list}
    return {"rows": rows, "averages": averages, "gates": list(GATES), "seeds": list(context.ablation_seeds),
            "oracle_iou": ORACLE_IOU}


def plot(data: dict, path) -> None:
    """Per block, each sequence's mean overlap under the four gates (one marker per gate)."""
    import matplotlib.pyplot as plt

    blocks_ = list(data["averages"])
    fig, axes = plt.subplots(1, len(blocks_), figsize=(5.2 * len(blocks_), 4.2), squeeze=False)
    markers = ("o", "v", "^", "s")
    for ax, block in zip(axes[0], blocks_):
        rows = [r for r in data["rows"] if r["block"] == block]
        x = np.arange(len(rows) + 1)
        for gate, marker in zip(data["gates"], markers):
            values = [r[gate] for r in rows] + [data["averages"][block][gate]]
            ax.plot(x, values, marker=marker, ls="", ms=6, label=gate)
        ax.set_xticks(x)
        ax.set_xticklabels([r["sequence"] for r in rows] + ["average"], rotation=60, ha="right", fontsize=7)
        ax.set_ylim(0, 1)
        ax.set_ylabel("mean overlap")
        ax.set_title(block, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7, title=f"positive update (truth: IoU >= {data['oracle_iou']:g})",
                      title_fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)


def report(context, data: dict) -> dict:
    """Write the numbers (CSV/JSON); returns the report section."""
    gates = data["gates"]
    header = ["block", "sequence"] + gates + [f"{g} std" for g in gates] + [f"{g} updates" for g in gates]
    write_csv(context.output(STEM, ".csv"), header, [[r[k] for k in header] for r in data["rows"]])
    io.write_json(context.output(STEM, ".json"), dict(data, title=TITLE))
    text = [f"Mean overlap (± std over seeds {data['seeds']}) of the default tracker when its positive update "
            f"follows its rule, the rule and the truth (the box at IoU >= {data['oracle_iou']:g}), the rule or the "
            "truth, or the truth alone; in brackets, positive updates per 100 frames. Diagnostic only."
            + (f" First {context.max_frames} frames of each sequence only." if context.max_frames else ""), "",
            "| sequence | " + " | ".join(gates) + " |", "|---" * (len(gates) + 1) + "|"]
    for block, average in data["averages"].items():
        text.append(f"| *{block}* |" + " |" * len(gates))
        for r in (r for r in data["rows"] if r["block"] == block):
            text.append(f"| {r['sequence']} | " + " | ".join(
                f"{fmt(r[g], 2, r[f'{g} std'])} ({fmt(r[f'{g} updates'], 0)})" for g in gates) + " |")
        text.append("| **average** | " + " | ".join(fmt(average[g], 3) for g in gates) + " |")
    text.append("")
    for block, average in data["averages"].items():
        best = max(gates, key=lambda g: average[g])
        text.append(f"- {block}: the rule {fmt(average['rule'], 3)}, the truth alone {fmt(average['truth'], 3)} "
                    f"({average['truth'] - average['rule']:+.3f}); the best gate is '{best}', "
                    f"{average[best] - average['rule']:+.3f} over the rule.")
    return {"title": TITLE, "figures": [f"{STEM}.png"], "markdown": "\n".join(text)}


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
