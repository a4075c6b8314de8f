"""The ``track`` subcommand of ``python -m nrmlc``: track a sequence folder, write the boxes.

Every output (``--out``, ``--video``, ``--diagnostics``) is checked before
tracking starts (:func:`nrmlc.io.check_output`: writable, a regular file or
nothing yet, not an input of the run, not inside the frames' folder) and
written atomically once the run has succeeded; a failed or interrupted run
leaves earlier files as they were.
"""
from __future__ import annotations

import argparse
import os
import re
import sys

import numpy as np

# Names that would become part of a sequence folder if an output took them.
_SEQUENCE_FILE = re.compile(r"^(groundtruth_rect(\.\d+)?\.txt|datainfo\.txt|.*_gt\.mat)$", re.IGNORECASE)


def add_track_command(commands) -> None:
    from nrmlc.cli import add_command

    track = add_command(commands, "track", run_track)
    track.add_argument("sequence", metavar="SEQ_DIR|VIDEO",
                       help="sequence folder (OTB or sparse-tracker pack layout, or a folder of frames), or a "
                            "video file OpenCV reads (.mp4, .avi, ...; needs --init-box)")
    track.add_argument("--out", required=True, metavar="RESULT.txt", help="output boxes, one x,y,w,h line per frame")
    track.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    track.add_argument("--particles", type=int, help="number of particles (default: the preset's)")
    from nrmlc.tracker.params import PRESETS, TrackerParams

    track.add_argument("--coding", choices=TrackerParams.choices("coding"), help="coding mode (default regularized)")
    track.add_argument("--lambda", dest="lam", type=float, help="l2 weight on the coefficients (default 1)")
    track.add_argument("--beta", type=float, help="l2 weight on the dictionary weights (default 0.1)")
    track.add_argument("--frames", type=int, help="track only the first N frames")
    track.add_argument("--target", type=int, help="target number in a multi-target folder (groundtruth_rect.N.txt)")
    track.add_argument("--init-box", metavar="X,Y,W,H",
                       help="initial box (default: the first ground-truth box); may start with a minus sign")
    track.add_argument("--preset", default="default", choices=tuple(PRESETS),
                       help="parameter set (default: 'default', chosen on the development sequences; 'paper': "
                            "the paper as printed); --param and the options above change single values")
    track.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                       help="any other tracker parameter, e.g. --param occlusion_detection=false (repeatable; "
                            "names, defaults and ranges: see `nrmlc params`)")
    track.add_argument("--tracker", metavar="NAME|MODULE:FACTORY",
                       help="track with another tracker instead of NRMLC: one of the lineage's (ivt; "
                            "`nrmlc benchmark --help`) or package.module:factory, as benchmark's --tracker; "
                            "not with NRMLC's options (--preset, --param, --particles, --coding, --lambda, "
                            "--beta, --diagnostics)")
    track.add_argument("--threads", type=int, help="threads for numba/OpenBLAS/OpenCV (default: all cores)")
    track.add_argument("--video", metavar="OUT.mp4", help="also write the frames with the tracked box drawn "
                       "(.mp4, .m4v, .mov, .avi or .mkv)")
    track.add_argument("--diagnostics", metavar="DIAG.npz", help="also save per-frame diagnostics")


def check_outputs(args: argparse.Namespace, sequence) -> None:
    """Refuse, before tracking, outputs that cannot be written or would replace an input or each other."""
    from nrmlc import io
    from nrmlc.errors import ParameterError

    inputs = list(sequence.image_paths or [])
    if sequence.path is not None and sequence.path.is_file():  # a video file
        inputs.append(sequence.path)
    if sequence.groundtruth_path is not None:
        inputs.append(sequence.groundtruth_path)
    if sequence.path is not None:
        inputs.append(sequence.path / "datainfo.txt")
    folders = {path.parent for path in sequence.image_paths or []}
    outputs = {option: path for option, path in (("--out", args.out), ("--video", args.video),
                                                 ("--diagnostics", args.diagnostics)) if path is not None}
    seen = {}
    for option, path in outputs.items():
        io.check_output(path, option, inputs=inputs, input_folders=folders)
        target = os.path.realpath(path)
        if sequence.path is not None and os.path.dirname(target) == os.path.realpath(sequence.path) \
                and _SEQUENCE_FILE.match(os.path.basename(target)):
            raise ParameterError(f"{option} {path}: would become part of the sequence folder {sequence.path} "
                                 f"(a ground-truth or pack file name); write it elsewhere")
        if target in seen:
            raise ParameterError(f"{option} {path}: the same file as {seen[target]}; give each output its own file")
        seen[target] = f"{option} {path}"


def run_track(args: argparse.Namespace) -> int:
    """track the target of a sequence folder or a video file with NRMLC

    Track one target through a sequence folder or a video file with NRMLC and write its box in
    every frame to --out, one x,y,w,h line per frame (OTB convention, 1-based pixels). The first box
    is the ground truth's first, or --init-box. Where the sequence has ground truth, the closing
    line gives the mean overlap and centre error. Every output is checked before tracking starts
    and written only once the run has succeeded; the same seed gives the same boxes for any
    --threads.
    """
    from nrmlc import io
    from nrmlc.config import set_threads
    from nrmlc.data import open_sequence
    from nrmlc.data.boxes import parse_box_line
    from nrmlc.errors import ParameterError
    from nrmlc.workbench.metrics import evaluate
    from nrmlc.tracker.params import TrackerParams, parse_param_assignment
    from nrmlc.errors import interrupt_requested
    from nrmlc.tracker.loop import track_sequence

    overrides = dict(parse_param_assignment(text) for text in args.param)
    for option, name, value in (("--particles", "n_particles", args.particles), ("--coding", "coding", args.coding),
                                ("--lambda", "lam", args.lam), ("--beta", "beta", args.beta)):
        if value is not None:
            if name in overrides and overrides[name] != value:
                raise ParameterError(f"{option} {value} and --param {name}={overrides[name]} disagree; give one")
            overrides[name] = value
    if args.tracker is not None:
        given = [option for option, value in (("--preset", args.preset != "default"), ("--param", args.param),
                                              ("--particles", args.particles), ("--coding", args.coding),
                                              ("--lambda", args.lam), ("--beta", args.beta),
                                              ("--diagnostics", args.diagnostics)) if value]
        if given:
            raise ParameterError(f"--tracker {args.tracker}: {', '.join(given)} belong to NRMLC; "
                                 f"give them without --tracker")
    params = TrackerParams.preset(args.preset, **overrides)
    if args.frames is not None and args.frames < 1:
        raise ParameterError(f"--frames must be >= 1, got {args.frames}")
    if args.target is not None and args.target < 1:
        raise ParameterError(f"--target must be >= 1, got {args.target}")
    if args.video:
        from nrmlc.video import check_video_path

        check_video_path(args.video)
    if args.threads is not None:
        import numba

        if args.threads > numba.config.NUMBA_NUM_THREADS:
            # set_threads would cap it silently; on the command line that hides a typo.
            raise ParameterError(f"--threads {args.threads}: at most {numba.config.NUMBA_NUM_THREADS} here "
                                 f"(numba's thread pool, NUMBA_NUM_THREADS)")
    set_threads(args.threads)
    sequence = open_sequence(args.sequence, target=args.target)
    init_box = None
    if args.init_box is not None:
        init_box = np.array(parse_box_line(args.init_box, "--init-box"))
    check_outputs(args, sequence)
    entry = None
    if args.tracker is not None:
        from nrmlc.workbench.trackers import ImportedTracker

        entry = ImportedTracker(args.tracker)
    writer = None
    on_frame = None
    try:
        if args.video:
            from nrmlc.video import BoxVideoWriter

            # Inside the try: an interrupt right after its temporary file exists still removes it.
            writer = BoxVideoWriter(args.video, sequence)
            on_frame = writer.on_frame
        if entry is None:
            result = track_sequence(sequence, params, seed=args.seed, n_frames=args.frames, init_box=init_box,
                                    progress=True, on_frame=on_frame)
        else:
            result = _track_other(entry, sequence, args.seed, args.frames, init_box, writer)
        if interrupt_requested.is_set():
            raise KeyboardInterrupt  # a signal whose KeyboardInterrupt a finaliser swallowed
        # All or nothing: a failure while writing one output leaves every earlier file as it was.
        with io.Together() as outputs:
            outputs.boxes(args.out, result.boxes)
            if args.diagnostics:
                outputs.npz(args.diagnostics, **result.to_arrays())
            if writer is not None and (video := writer.finish()) is not None:
                outputs.file(video, args.video)
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    summary = (f"{sequence.name}: {len(result.boxes)} frames, {result.fps_tracking:.1f} fps tracking "
               f"({result.fps_total:.1f} fps with decoding)")
    annotated = sequence.groundtruth[: len(result.boxes)]
    if np.isfinite(annotated[1:]).all(axis=1).any():
        scores = evaluate(result.boxes, annotated)
        summary += f", mean overlap {scores.mean_overlap:.3f}, CLE {scores.mean_center_error:.1f} px"
    print(summary, file=sys.stderr)
    return 0


def _track_other(entry, sequence, seed: int, n_frames: int | None, init_box, writer):
    """``entry``'s (:class:`nrmlc.workbench.trackers.ImportedTracker`) run, as a TrackResult without states."""
    import time

    from nrmlc.tracker.loop import TrackResult
    from nrmlc.workbench.trackers import track_init_update

    start = time.perf_counter()
    n = len(sequence) if n_frames is None else min(n_frames, len(sequence))
    boxes, seconds = track_init_update(entry.spec, sequence, seed, n, init_box=init_box,
                                       on_box=writer.draw if writer is not None else None)
    return TrackResult(boxes, np.zeros((n, 0)), {}, seconds, time.perf_counter() - start)
