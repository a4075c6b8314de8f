"""The likelihood across scale at the ground truth's centre: why boxes drift in scale.

The failure measures (:mod:`experiments.paper.failure_mechanisms`) find boxes that end far from
the target's size (Occlusion2 at a fifth of the face's area, Basketball, MotorRolling).
This script asks the likelihood itself. While the default tracker runs (seed 0), at every
annotated frame and before that frame's update, the ground-truth box is coded at
:data:`SCALES` times its size, same centre and aspect, on the templates the frame's own
candidates are coded on. Per candidate the margin ``m = eps_neg - eps_pos`` is the log
confidence over alpha (``log h = alpha m``), so ``m(s) - m(1)`` says by how much the
likelihood prefers the box scaled by ``s`` to the true one (in units of 1/alpha of log
weight). Frames are counted while the tracker holds the target (IoU >= ``ON_TARGET_IOU`` of
:mod:`experiments.paper.failure_mechanisms`), the first
:data:`EARLY_FRAMES` frames apart from the rest, because the positives are then still the
first frame's. The probing never changes the tracker's boxes (tested).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import matplotlib.pyplot as plt
import numpy as np

from experiments.grid import describe_params, json_report, script_entry
from experiments.shared import ON_TARGET_IOU, blocks
from experiments.tables import save_figure
from nrmlc.workbench.jobs import TrackerJob, frames_tracked

STEM = "scale_likelihood"
TITLE = "Scale drift: the likelihood across scale at the ground truth's centre"
#: ``report(context, data)``: writes ``<STEM>.json``, returns the report section.
report = json_report(STEM)

#: Scale factors of the probed boxes (1 = the ground truth's size).
SCALES = (0.7, 0.8, 0.9, 1.0, 1.1, 1.25, 1.4)
#: Frames before this one count as early (the positives are still mostly the first frame's).
EARLY_FRAMES = 30
#: Sequences with fewer frames counted in a period stay out of that period's correlation (:func:`summary`).
MIN_PERIOD_FRAMES = 20
#: Bump when the recorded content changes (invalidates the cached profiles).
PROFILE_VERSION = 1


@dataclass(frozen=True)
class ScaleProfile(TrackerJob):
    """Track a sequence and, at each annotated frame, code the ground truth at :data:`SCALES`.

    A job of :class:`nrmlc.workbench.run_cache.RunCache` (stored under ``<cache>/analysis/``), keyed by
    the sequence, the parameters, the seed, the frame cap, the profile version and the
    code version.
    """

    max_frames: int | None = None

    folder: ClassVar[str] = "analysis"
    label_template: ClassVar[str] = "scale profile of {job.sequence.name}"

    def frame_cap(self) -> int | None:
        return self.max_frames

    def description(self, version: str) -> dict:
        return self.tracker_description(version, max_frames=self.max_frames, scales=list(SCALES),
                                        profile=PROFILE_VERSION)

    def execute(self) -> dict:
        from nrmlc.geometry import box_to_state, usable_boxes
        from nrmlc.data.image import as_gray_frame
        from experiments.instrumented import track_instrumented

        sequence, params = self.sequence, self.params
        groundtruth = sequence.groundtruth
        usable = usable_boxes(groundtruth)
        frames, error_positive, error_negative = [], [], []

        def code_scales(index, tracker, image):
            if usable[index]:
                states = np.repeat(box_to_state(groundtruth[index][None, :], params.patch_size), len(SCALES), axis=0)
                states[:, 2] *= np.asarray(SCALES)
                # encode() reads the templates and draws nothing: the run's boxes are unchanged.
                coding = tracker.encode(tracker.patches(as_gray_frame(image), states))
                frames.append(index)
                error_positive.append(coding.error_positive)
                error_negative.append(coding.error_negative)

        run = track_instrumented(sequence, params, seed=self.seed, n_frames=self.frames(), probe=code_scales)
        boxes = run.boxes
        empty = np.empty((0, len(SCALES)))
        return {"boxes": boxes, "frames": np.array(frames, dtype=np.int64),
                "error_positive": np.array(error_positive) if frames else empty,
                "error_negative": np.array(error_negative) if frames else empty,
                "seconds": np.float64(run.seconds_total)}

    def result(self, arrays: dict) -> dict:
        return dict(arrays, name=self.sequence.name)


def _jobs(context) -> list[tuple[str, ScaleProfile]]:
    return [(label, ScaleProfile(s, context.base_params, 0, context.max_frames))
            for label, sequences in blocks(context) for s in sequences]


def runs(context) -> list:
    """One profile (seed 0, the default parameters) per sequence of the failure measures' blocks."""
    return [job for _, job in _jobs(context)]


def profile_measures(profile: dict, groundtruth: np.ndarray) -> dict:
    """The measures of one profiled run.

    Parameters
    ----------
    profile : dict
        ``boxes`` (n_frames, 4), ``frames`` (n,), ``error_positive`` and ``error_negative``
        (n, len(SCALES)), as :meth:`ScaleProfile.execute` returns them.
    groundtruth : (n_frames or more, 4) array

    Returns
    -------
    dict
        Per period (``early``, ``later``): ``frames`` counted, ``margin`` (len(SCALES),) the
        mean of m(s) - m(1), ``error_positive`` and ``error_negative`` (len(SCALES),) the means
        of eps(s) - eps(1) of each term (m's change is the second minus the first),
        ``best_share`` (len(SCALES),) how often each scale has the largest margin,
        ``smaller``/``truth``/``larger`` those shares summed; and
        ``tracked_scale``, the median over the counted frames of sqrt(box area / truth area).
    """
    from nrmlc.workbench.metrics import overlaps

    frames = np.asarray(profile["frames"], dtype=np.int64)
    margin = np.asarray(profile["error_negative"]) - np.asarray(profile["error_positive"])
    unit = SCALES.index(1.0)
    boxes, truth = np.asarray(profile["boxes"])[frames], np.asarray(groundtruth)[frames]
    held = overlaps(boxes, truth) >= ON_TARGET_IOU
    out = {}
    for period, chosen in (("early", frames < EARLY_FRAMES), ("later", frames >= EARLY_FRAMES)):
        counted = held & chosen
        n = int(counted.sum())
        if not n:
            out[period] = {"frames": 0}
            continue
        relative = margin[counted] - margin[counted, unit][:, None]
        share = np.bincount(np.argmax(margin[counted], axis=1), minlength=len(SCALES)) / n
        terms = {name: (errors[counted] - errors[counted, unit][:, None]).mean(axis=0).tolist()
                 for name, errors in (("positive", np.asarray(profile["error_positive"])),
                                      ("negative", np.asarray(profile["error_negative"])))}
        out[period] = {"frames": n, "margin": relative.mean(axis=0).tolist(), "best_share": share.tolist(),
                       "error_positive": terms["positive"], "error_negative": terms["negative"],
                       "smaller": float(share[:unit].sum()), "truth": float(share[unit]),
                       "larger": float(share[unit + 1:].sum())}
    ratio = np.sqrt(boxes[held, 2] * boxes[held, 3] / (truth[held, 2] * truth[held, 3]))
    out["tracked_scale"] = float(np.median(ratio)) if ratio.size else None
    return out


def collect(context) -> dict:
    """The numbers and what the figure needs (the JSON, the plot's inputs, the report section)."""
    labelled = _jobs(context)
    profiles = context.run([job for _, job in labelled])
    rows = []
    for (label, job), profile in zip(labelled, profiles):
        n = frames_tracked(job.sequence, job.max_frames)
        rows.append({"sequence": job.sequence.name, "block": label,
                     **profile_measures(profile, job.sequence.groundtruth[:n])})
    result = {"data": {"label": context.data_label, "seed": 0, "params": describe_params(context.base_params),
                       "scales": list(SCALES), "early_frames": EARLY_FRAMES, "on_target_iou": ON_TARGET_IOU},
              "sequences": rows, "summary": summary(rows)}
    section = {"title": TITLE, "figures": [f"{STEM}.png"], "markdown": _markdown(result)}
    return {"result": result, "plot": rows, "section": section}


def summary(rows: list[dict]) -> dict:
    """Per period: the frame-weighted mean margin curve and shares over every counted frame, and
    on how many sequences a smaller scale wins more often than the ground truth's; and whether
    the boxes drift the way the likelihood leans: per period, the Pearson r, across the sequences
    with at least :data:`MIN_PERIOD_FRAMES` frames counted in it, between the share of larger
    minus smaller scales winning and the log of the tracked scale. The early lean comes from
    templates that are still mostly the first frame's: it is there before the positives fill
    with drifted results."""
    out = {}
    for period in ("early", "later"):
        counted = [r[period] for r in rows if r[period]["frames"]]
        if not counted:
            out[period] = {"frames": 0}
            continue
        weights = np.array([c["frames"] for c in counted], dtype=np.float64)

        def mean(name: str) -> np.ndarray:
            return np.array([c[name] for c in counted]).T @ weights / weights.sum()

        out[period] = {"frames": int(weights.sum()), "margin": mean("margin").tolist(),
                       "error_positive": mean("error_positive").tolist(),
                       "error_negative": mean("error_negative").tolist(),
                       "best_share": mean("best_share").tolist(),
                       "sequences": len(counted),
                       "smaller_beats_truth": sum(c["smaller"] > c["truth"] for c in counted)}
    out["lean_and_drift"] = {}
    for period in ("early", "later"):
        leaning = [(r[period]["larger"] - r[period]["smaller"], np.log(r["tracked_scale"])) for r in rows
                   if r[period]["frames"] >= MIN_PERIOD_FRAMES and r["tracked_scale"] is not None]
        spread = len(leaning) >= 3 and all(np.ptp(values) > 0 for values in zip(*leaning))
        out["lean_and_drift"][period] = {
            "sequences": len(leaning), "pearson_r": float(np.corrcoef(np.array(leaning).T)[0, 1]) if spread else None}
    return out


def plot(data: dict, path) -> None:
    rows = data["plot"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    styles = {}
    for ax, period in zip(axes, ("early", "later")):
        for row in rows:
            if not row[period]["frames"]:
                continue
            style = styles.setdefault(row["block"], ("-", ":", "--")[len(styles) % 3])
            ax.plot(SCALES, row[period]["margin"], style, lw=1, alpha=0.8, label=row["sequence"])
        ax.axhline(0, color="k", lw=0.8)
        ax.axvline(1, color="k", lw=0.8, ls="--")
        ax.set_xlabel("scale of the probed box / the ground truth's")
        ax.set_title(f"{period} frames ({'before' if period == 'early' else 'from'} frame {EARLY_FRAMES}), "
                     f"tracker on target", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("m(s) - m(1),  m = eps_neg - eps_pos  (log h = alpha m)")
    axes[1].legend(fontsize=6, ncol=2, loc="lower center")
    save_figure(fig, path, dpi=120)


def _shares(period: dict) -> str:
    if not period["frames"]:
        return "– | – | – | –"
    return f"{period['frames']} | {period['smaller']:.2f} | {period['truth']:.2f} | {period['larger']:.2f}"


def _markdown(result: dict) -> str:
    data, summary_ = result["data"], result["summary"]
    unit = SCALES.index(1.0)
    lines = [
        f"### {TITLE}",
        "",
        f"Data: {data['label']}; tracker seed 0, {data['params']}. At every annotated frame, before its update, the "
        f"ground-truth box scaled by {', '.join(f'{s:g}' for s in SCALES)} (same centre and aspect) is coded on the "
        "frame's templates; m = eps_neg - eps_pos is the log confidence over alpha. Counted: the frames on which "
        f"the tracker's own box has IoU >= {ON_TARGET_IOU}, early (before frame {EARLY_FRAMES}) and later. "
        "*Smaller / truth / larger*: the share of those frames on which the largest margin is at a scale below 1, "
        "at 1, above 1. *Tracked scale*: the median of sqrt(box area / truth area) over them.",
        "",
        "| sequence | early frames | smaller | truth | larger | later frames | smaller | truth | larger | "
        "m(0.9) - m(1), later | m(1.1) - m(1), later | tracked scale |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    block = None
    for row in result["sequences"]:
        if row["block"] != block:
            block = row["block"]
            lines.append(f"| *{block}* | | | | | | | | | | | |")
        later = row["later"]
        near = (f"{later['margin'][unit - 1]:+.3f} | {later['margin'][unit + 1]:+.3f}" if later["frames"]
                else "– | –")
        scale = "–" if row["tracked_scale"] is None else f"{row['tracked_scale']:.2f}"
        lines.append(f"| {row['sequence']} | {_shares(row['early'])} | {_shares(row['later'])} | {near} | {scale} |")
    lines.append("")
    for period in ("early", "later"):
        s = summary_[period]
        if not s["frames"]:
            continue
        curve = ", ".join(f"{scale:g}: {value:+.3f}" for scale, value in zip(SCALES, s["margin"]))
        lines.append(f"- **{period.capitalize()}** ({s['frames']} frames on {s['sequences']} sequences): mean "
                     f"m(s) - m(1) {curve}; the ground truth's scale has the largest margin on "
                     f"{s['best_share'][unit]:.2f} of the frames, a smaller one on "
                     f"{sum(s['best_share'][:unit]):.2f}; a smaller scale wins more often than the ground truth's "
                     f"on {s['smaller_beats_truth']} of {s['sequences']} sequences. At 0.9 / 1.1 times the size, "
                     f"eps_pos changes by {s['error_positive'][unit - 1]:+.3f} / {s['error_positive'][unit + 1]:+.3f} "
                     f"and eps_neg by {s['error_negative'][unit - 1]:+.3f} / {s['error_negative'][unit + 1]:+.3f}.")
    for period, lean in summary_["lean_and_drift"].items():
        if lean["pearson_r"] is not None:
            lines.append(f"- {period.capitalize()}: across the {lean['sequences']} sequences with at least "
                         f"{MIN_PERIOD_FRAMES} frames counted, the share of larger scales winning minus that of "
                         "smaller ones and the log of the tracked scale correlate with Pearson r = "
                         f"{lean['pearson_r']:.2f}.")
    lines += ["", "Diagnostic only: no default is chosen on these runs."]
    return "\n".join(lines) + "\n"


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
