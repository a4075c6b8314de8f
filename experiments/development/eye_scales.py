"""The scale of each eye's reconstruction error, in the gray patch's units (:data:`nrmlc.tracker.eyes.ERROR_SCALE`).

``python -m experiments.development.eye_scales [--synthetic 6] [--frames 20] [--json PATH]``

An expert with other eyes codes its candidates in another space, where eps_pos* has another
scale; every threshold on eps_pos* was chosen in the gray patch's. For each eye, a tracker is
started on the first frame of a sequence and never updated; on every later frame the true box is
coded on those first templates. The scale of an eye is the median of its eps_pos* over the first
``--frames`` of each video of development half A stored in colour (the videos round 80 measured
its colour eye on), divided by the gray patch's median on the same frames: real appearance change. The ratio shrinks as the errors grow (6.8 for the gradient eye over 6
frames, 1.9 over 100), so it is read where the thresholds act: over 20 frames the gray patch's
median eps_pos* (0.088) is nearest the update gate (0.1). The synthetic suite's ratios
are printed beside them: its targets barely change, the errors are a tenth as large, and the
ratios are not those of real video. Nothing here depends on how a tracker follows the target.
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from experiments.development.devset import default_roots, development_sequences
from experiments.sequence_sets import DEVELOPMENT_A
from nrmlc.data import synthetic_suite
from nrmlc.data.image import as_gray_frame
from nrmlc.geometry import box_to_state
from nrmlc.tracker.algorithm import NRMLCTracker
from nrmlc.tracker.eyes import ERROR_SCALE
from nrmlc.tracker.params import TrackerParams


def true_box_errors(sequence, eyes: str, n_frames: int | None = None, seed: int = 0) -> np.ndarray:
    """eps_pos* (n,) of the true box on each annotated frame after the first (of the first
    ``n_frames``), in ``eyes``' own units, coded on the first frame's templates."""
    tracker = NRMLCTracker(seed, TrackerParams(second_expert="off", eyes=eyes))
    tracker.init(sequence.raw_frame(0), sequence.groundtruth[0])
    errors = []
    for index in range(1, min(len(sequence), n_frames or len(sequence))):
        box = sequence.groundtruth[index]
        if not np.all(np.isfinite(box)) or box[2] <= 0 or box[3] <= 0:
            continue
        image = sequence.raw_frame(index)
        state = box_to_state(box, tracker.params.patch_size)
        coding = tracker.encode(tracker.patches(as_gray_frame(image), state[None, :]))
        errors.append(coding.error_positive[0] * ERROR_SCALE[eyes])
    return np.array(errors)


def is_colour(image: np.ndarray) -> bool:
    """Whether a frame is stored in colour (three or four channels, BGR(A))."""
    return image.ndim == 3 and image.shape[2] >= 3


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--synthetic", type=int, default=6, help="synthetic sequences (300 frames each)")
    parser.add_argument("--frames", type=int, default=20, help="frames of each real video")
    parser.add_argument("--json", help="write the medians and scales here")
    args = parser.parse_args(argv)
    real = [s for s in development_sequences(default_roots(), DEVELOPMENT_A, 0) if is_colour(s.raw_frame(0))]
    sets = {"synthetic": (synthetic_suite(n_frames=300, n_sequences=args.synthetic), None),
            "A colour": (real, args.frames)}
    errors = {name: {eyes: np.concatenate([true_box_errors(s, eyes, n) for s in sequences]) for eyes in ERROR_SCALE}
              for name, (sequences, n) in sets.items()}
    for name, by_eye in errors.items():
        gray = np.median(by_eye["gray"])
        print(f"{name}: " + ", ".join(f"{eyes} {np.median(e) / gray:.3f}" for eyes, e in by_eye.items()))
    medians = {eyes: float(np.median(errors["A colour"][eyes])) for eyes in ERROR_SCALE}
    scales = {eyes: medians[eyes] / medians["gray"] for eyes in medians}
    for eyes in medians:
        print(f"{eyes:10s} median eps_pos* {medians[eyes]:.5f}  scale {scales[eyes]:.3f}")
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"medians": medians, "scales": scales, "synthetic": args.synthetic, "frames": args.frames,
                       "colour_videos": [s.name for s in real],
                       "synthetic_scales": {eyes: float(np.median(e) / np.median(errors["synthetic"]["gray"]))
                                            for eyes, e in errors["synthetic"].items()}}, out, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
