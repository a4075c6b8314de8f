"""Fig. 3: representative frames with the boxes of NRMLC, the ground truth and the peers.

One row per given paper sequence (the synthetic ones without data), four evenly spaced frames per
row (frame 1 is left out: every tracker starts at the ground truth there).
Boxes: NRMLC seed 0 (the first main seed), the ground truth, OpenCV's
trackers run live, and the shipped peer results that fit the sequence.
The paper's Fig. 3 shows DavidOutdoor, ClifBar, Deer, Occlusion2, Skating1,
Caviar1, Human7 and CarScale; here every given sequence is shown.

Outputs ``figures/fig3_qualitative.{png,json}`` (the JSON holds the frame
numbers and every box drawn).
"""
from __future__ import annotations


import numpy as np

from experiments import peers
from experiments.grid import script_entry, section
from experiments.sequence_sets import paper_name
from experiments.tables import save_figure
from nrmlc import io

STEM = "fig3_qualitative"
TITLE = "Fig. 3: qualitative results on representative frames"

#: The paper's Fig. 3 sequences (its caption's names).
PAPER_FIG3 = ("DavidOutdoor", "ClifBar", "Deer", "Occlusion2", "Skating1", "Caviar1", "Human7", "CarScale")

FRAMES_PER_SEQUENCE = 4

#: Fixed colours so a tracker looks the same in every panel.
COLOURS = {"Ground truth": "#00ff00", "NRMLC (ours)": "#ff2020", "MIL (OpenCV)": "#1f77ff", "KCF (OpenCV)": "#ff9f1c",
           "CSRT (OpenCV)": "#8c8c8c", "L1": "#e6c000", "MIL": "#00c8e0", "IVT": "#ff66ff", "ASLA": "#a65628",
           "KCF": "#ff8c00"}


def _sequences(context) -> list:
    paper_seqs, others = context.ordered_sequences()
    return paper_seqs or others  # the paper's sequences; the synthetic suite without data


def _specs(context) -> list:
    return context.specs(_sequences(context), seeds=context.seeds[:1], label="fig3")


def runs(context) -> list:
    """NRMLC seed 0 (the first main seed; Tables I/II's run) and the live OpenCV runs (the tables')."""
    return _specs(context) + peers.live_specs(context, _sequences(context))


def frame_indices(n_frames: int, count: int = FRAMES_PER_SEQUENCE) -> list[int]:
    """``count`` evenly spaced 0-based frames, the last frame included and frame 0 left out."""
    if n_frames <= 1:
        return [0]
    picks = np.linspace(0, n_frames - 1, count + 1)[1:]
    return sorted({int(round(v)) for v in picks})


def collect(context) -> dict:
    """Boxes of every tracker at the chosen frames of each sequence."""
    sequences = _sequences(context)
    results = context.run(_specs(context))
    live = peers.live_results(context, sequences)
    shipped, notes = peers.shipped_for(context, sequences)
    rows = []
    for sequence, result in zip(sequences, results):
        n = context.n_frames(sequence)
        frames = frame_indices(n)
        tracks = {"Ground truth": sequence.groundtruth[:n], "NRMLC (ours)": result.boxes}
        for tracker, by_sequence in live.items():
            tracks[peers.live_label(tracker)] = by_sequence[sequence.name].boxes
        for tracker, by_sequence in shipped.items():
            if sequence.name in by_sequence:
                tracks[tracker] = by_sequence[sequence.name].boxes[:n]
        rows.append({"sequence": sequence, "frames": frames,
                     "boxes": {name: {f: boxes[f] for f in frames} for name, boxes in tracks.items()}})
    return {"rows": rows, "notes": notes, "seed": context.seeds[0]}


def plot(data: dict, path) -> None:
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Rectangle

    rows = data["rows"]
    n_cols = max(len(r["frames"]) for r in rows)
    images = [[row["sequence"].color_frame(frame)[:, :, ::-1] for frame in row["frames"]] for row in rows]
    # Each row as tall as its frames at the column's width: an image then fills its panel, and the
    # layout's room for the row label above it is room above the image (a row of frames narrower
    # than the panel left the label of the row below touching it).
    aspects = [max(image.shape[0] / image.shape[1] for image in row_images) for row_images in images]
    panel_width, label_height, legend_height = 2.9, 0.6, 0.6
    fig, axes = plt.subplots(len(rows), n_cols, squeeze=False, gridspec_kw={"height_ratios": aspects},
                             figsize=(panel_width * n_cols,
                                      sum(panel_width * aspect + label_height for aspect in aspects) + legend_height))
    used = []
    for r, row in enumerate(rows):
        sequence = row["sequence"]
        for c in range(n_cols):
            ax = axes[r, c]
            ax.set_axis_off()
            if c >= len(row["frames"]):
                continue
            frame = row["frames"][c]
            ax.imshow(images[r][c], interpolation="bilinear")
            for name, boxes in row["boxes"].items():
                box = boxes[frame]
                if not np.isfinite(box).all():
                    continue
                if name not in used:
                    used.append(name)
                x, y, w, h = box
                # Project convention: an OTB box (x, y, w, h) spans [x-1, x-1+w] in 0-based coordinates
                # whose pixel centres are integers, as in imshow.
                ax.add_patch(Rectangle((x - 1.0, y - 1.0), w, h, fill=False, lw=1.6 if name != "Ground truth" else 1.2,
                                       ls="--" if name == "Ground truth" else "-",
                                       edgecolor=COLOURS.get(name, "#cccccc")))
            ax.text(0.02, 0.97, f"#{frame + 1}", transform=ax.transAxes, va="top", ha="left", color="yellow",
                    fontsize=13, fontweight="bold", bbox=dict(facecolor="black", alpha=0.6, pad=1, lw=0))
            if c == 0:
                label = sequence.name if paper_name(sequence.name) in (None, sequence.name) else \
                    f"{sequence.name} ({paper_name(sequence.name)})"
                ax.set_title(label, loc="left", fontsize=13)
    handles = [Line2D([], [], color=COLOURS.get(n, "#cccccc"), lw=2, ls="--" if n == "Ground truth" else "-")
               for n in used]
    fig.legend(handles, used, loc="upper center", ncol=min(len(used), 6), fontsize=13, frameon=False,
               facecolor="black")
    # dpi 80: frame numbers and legend readable at full size (about 930 px wide), the file under 2 MiB.
    save_figure(fig, path, dpi=80, rect=(0, 0, 1, 1 - legend_height / fig.get_figheight()))


def report(context, data: dict) -> dict:
    """Write the numbers (CSV/JSON); returns the report section (``title``, ``figures``, ``markdown``)."""
    io.write_json(context.output(STEM, ".json"), {
        "seed": data["seed"],
        "sequences": [{"sequence": row["sequence"].name, "frames_1_based": [f + 1 for f in row["frames"]],
                       "boxes": {name: {str(f + 1): list(b) for f, b in boxes.items()}
                                 for name, boxes in row["boxes"].items()}} for row in data["rows"]],
        "notes": data["notes"]})
    names = [row["sequence"].name for row in data["rows"]]
    in_paper = [n for n in names if (paper_name(n) or n).lower() in {s.lower() for s in PAPER_FIG3}
                or n.lower() in {s.lower() for s in PAPER_FIG3}]
    absent = [s for s in PAPER_FIG3 if s.lower() not in {n.lower() for n in names}
              and s.lower() not in {(paper_name(n) or "").lower() for n in names}]
    per_row = ", ".join(f"{row['sequence'].name} #{'/'.join(str(f + 1) for f in row['frames'])}"
                        for row in data["rows"])
    text = [f"NRMLC seed {data['seed']} (red), ground truth (green dashed), OpenCV trackers run live and the "
            f"shipped peer results that fit each sequence, on {len(names)} sequences: {per_row}."]
    text.append(f"The paper's Fig. 3 shows {', '.join(PAPER_FIG3)}; of these, "
                f"{', '.join(in_paper) if in_paper else 'none'} {'is' if len(in_paper) == 1 else 'are'} given "
                f"here{'' if not absent else ' (' + ', '.join(absent) + ' are not in the data)'}; "
                "the other given sequences are shown as well.")
    return section(TITLE, STEM, text)


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
