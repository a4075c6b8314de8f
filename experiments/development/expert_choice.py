"""Offline: two configurations' runs side by side, the output on each frame chosen by eps_pos*.

``python -m experiments.development.expert_choice --seeds 335-344 --partner update_interval=1 [--memory 0.95] [--blend-iou 0.5]
[--held-share 0.7] [--unrecognised-gate 0.15]``
``python -m experiments.development.expert_choice --seeds 370-374 --own second_expert=off
--partner second_expert=off,update_interval=1``

For every development target and seed, the default's run and a partner configuration's run (from
the run cache, computed where missing) are joined frame by frame: each run keeps a running average
of its estimate's eps_pos* (``average = memory * average + (1 - memory) * eps_pos*``, from 0 at the
first frame), and the output is the partner's box where its average is strictly lower, the
default's elsewhere; where the two boxes overlap at IoU >= ``--blend-iou`` (the default's
``expert_blend_iou``, 0.5 since round 76; 1: never), their blend
(:func:`nrmlc.tracker.experts.blend_experts`); on a frame where neither run's eps_pos* is under
``--unrecognised-gate``, the output's size moves ``--held-share`` of the way to the last recognised
output's (the default's ``unrecognised_size_share``, 0.7 since round 77; 0: never;
:func:`nrmlc.tracker.experts.held_size`). The choice is causal and changes neither run, so
it measures, before anything is built, what a second expert beside the tracker would give
(rounds 63 and 64, docs/findings/round-63-a-second-expert.md). It prints, as ``experiments.development.screen`` does, the paired
difference to the default on half A, half B and the synthetic suite with the adoption rule's
verdict, for the partner alone and for the choice. It chooses nothing by itself: a second expert
is judged by a screen of the tracker at seeds the study did not use.

Since round 64 the default is itself such a pair (``second_expert = 'every_frame'``), and its
runs' eps_pos* is, frame by frame, the chosen expert's; a partner beside it then stands for a third
expert only approximately. The two single trackers that rounds 63 and 64 studied are the default
of a commit before the adoption (``8668979``), whose cached runs the study reads unchanged.

``--own`` makes the own expert a configuration of its own (changes of the default): with
``--own second_expert=off`` the two runs are the default's two experts, each tracking alone, and
the choice at the default's ``expert_memory``, ``expert_blend_iou`` and held size is its own output frame by
frame (the experts never move each other's boxes; tested). A partner other than the default's
then gives, exactly and for the cost of its single runs, what the default would give with that
partner (round 71). The rows are always judged against the default's runs.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from experiments.development.devset import overlaps_of, run_measures, scales_of
from experiments.grid import specs_for
from experiments.development.screen import (_report, add_run_options, add_target_options, chosen_targets, parse_variant,
                                screen_document, screen_row)
from nrmlc.errors import NrmlcError
from nrmlc.workbench.run_cache import RunCache
from nrmlc.geometry import box_to_state
from nrmlc.tracker.experts import choose_expert, experts_output
from nrmlc.tracker.loop import TrackResult
from nrmlc.tracker.params import TrackerParams


#: What the choice can compare: 'error' is the tracker's (:func:`nrmlc.tracker.experts.choose_expert`).
CHOICES = ("error", "margin")


def expert_scores(errors: np.ndarray, negative_errors: np.ndarray, choice: str) -> np.ndarray:
    """What the choice compares of the two runs on one frame (lower is better).

    Parameters
    ----------
    errors, negative_errors : (2,) float64
        Each run's eps_pos* and eps_neg* of its estimate.
    choice : {'error', 'margin'}

    Returns
    -------
    scores : (2,) float64
        ``errors`` for 'error' (the tracker's choice); for 'margin' ``errors / (errors +
        negative_errors)``, in [0, 1], which no scale of a run's feature space changes (1/2 where
        both are 0). The margin was measured against the error and not adopted
        (docs/research/rounds/round-81-error-or-margin-on-fresh-seeds.md).
    """
    if choice == "error":
        return errors
    total = errors + negative_errors
    return np.where(total > 0, errors / np.where(total > 0, total, 1.0), 0.5)


def chosen_boxes(own: TrackResult, partner: TrackResult, memory: float, blend_iou: float = 1.0,
                 held_share: float = 0.0, gate: float = 0.15, choice: str = "error") -> tuple[np.ndarray, np.ndarray]:
    """The frame-by-frame choice between two runs of one sequence, as the tracker makes it.

    Parameters
    ----------
    own, partner : TrackResult
        Runs of the same frames, with ``diagnostics["error_positive"]`` (n_frames,).
    memory : float
        The weight of the past in each run's running average of eps_pos*, in [0, 1).
    blend_iou : float
        Where the two boxes overlap at least this much, the output is their blend
        (``expert_blend_iou``; 1, the default here: never).
    held_share, gate : float
        Where neither run's eps_pos* is under ``gate``, the output's log size moves ``held_share``
        of the way to the last recognised output's (``unrecognised_size_share`` and
        ``unrecognised_gate``; a share of 0, the default here: never).
    choice : {'error', 'margin'}
        What the choice and the blend compare (:func:`expert_scores`: the tracker's 'error', or
        the margin measured beside it; the margin also reads ``diagnostics["error_negative"]``).

    Returns
    -------
    boxes : (n_frames, 4) float64
        The partner's box where its average is strictly lower, the own one elsewhere (frame 0:
        the own, the initial box of both), or the blend; held where neither run recognises the target.
    chosen : (n_frames,) int64
        1 where the partner is the chosen expert, 0 elsewhere.
    """
    boxes, chosen, _ = _choose(own, partner, memory, blend_iou, held_share, gate, choice)
    return boxes, chosen


def _choose(own: TrackResult, partner: TrackResult, memory: float, blend_iou: float,
            held_share: float, gate: float, choice: str = "error") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`chosen_boxes`, and (n_frames,) bool: where the output is neither run's box (the blend,
    or a held size)."""
    if len(own.boxes) != len(partner.boxes):
        raise NrmlcError(f"the two runs have {len(own.boxes)} and {len(partner.boxes)} frames")
    errors = np.stack([own.diagnostics["error_positive"], partner.diagnostics["error_positive"]], axis=1)
    # eps_neg* only where the margin reads it (runs may carry eps_pos* alone)
    negative_errors = (np.stack([own.diagnostics["error_negative"], partner.diagnostics["error_negative"]], axis=1)
                       if choice == "margin" else errors)
    average = np.zeros(2)
    chosen = np.zeros(len(own.boxes), dtype=np.int64)
    boxes = np.array(own.boxes, dtype=np.float64)
    changed = np.zeros(len(boxes), dtype=bool)
    recognised_log_size = np.log(boxes[0, 2:])
    params = TrackerParams(expert_blend_iou=blend_iou, unrecognised_size_share=held_share, unrecognised_gate=gate)
    for index in range(1, len(errors)):
        scores = expert_scores(errors[index], negative_errors[index], choice)
        average, chosen[index] = choose_expert(average, scores, memory)
        boxes[index], recognised_log_size, changed[index] = experts_output(
            np.stack([own.boxes[index], partner.boxes[index]]), errors[index], chosen[index], recognised_log_size,
            params, scores)
    return boxes, chosen, changed


def _chosen_run(own: TrackResult, partner: TrackResult, memory: float, blend_iou: float,
                held_share: float, gate: float, patch_size: int, choice: str = "error") -> TrackResult:
    """The choice as a run: each frame's box and state from the run chosen on it, or the blend's or
    the held size's (its state at the own expert's ``patch_size``, as the tracker makes it)."""
    boxes, chosen, changed = _choose(own, partner, memory, blend_iou, held_share, gate, choice)
    states = np.where(chosen[:, None] == 1, partner.states, own.states)
    states[changed] = box_to_state(boxes[changed], patch_size)
    return TrackResult(boxes, states)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_target_options(parser)
    parser.add_argument("--partner", required=True, metavar="PARAM=VALUE,...",
                        help="the partner configuration: changes of the default")
    parser.add_argument("--own", default="", metavar="PARAM=VALUE,...",
                        help="the own expert's configuration: changes of the default (default: the default)")
    parser.add_argument("--memory", type=float, default=0.95, help="weight of the past in the running average")
    parser.add_argument("--blend-iou", type=float, default=TrackerParams().expert_blend_iou,
                        help="blend the two boxes where they overlap at least this much (1: never; default: "
                             "the default's expert_blend_iou)")
    parser.add_argument("--held-share", type=float, default=TrackerParams().unrecognised_size_share,
                        help="where neither run recognises the target, move the size this share of the way to "
                             "the last recognised output's (0: never; default: the default's unrecognised_size_share)")
    parser.add_argument("--unrecognised-gate", type=float, default=TrackerParams().unrecognised_gate,
                        help="the eps_pos* at or above which a run does not recognise the target (default: the "
                             "default's unrecognised_gate)")
    parser.add_argument("--choice", choices=CHOICES, default=CHOICES[0],
                        help="what the choice and the blend compare: each run's eps_pos* (the tracker's choice) "
                             "or its margin eps_pos* / (eps_pos* + eps_neg*) (expert_scores)")
    add_run_options(parser)
    args = parser.parse_args(argv)
    try:
        try:
            TrackerParams(expert_memory=args.memory)  # the parameters' own bounds
        except NrmlcError as error:
            raise NrmlcError(f"--memory: {error}") from None
        try:
            TrackerParams(expert_blend_iou=args.blend_iou)
        except NrmlcError as error:
            raise NrmlcError(f"--blend-iou: {error}") from None
        try:
            TrackerParams(unrecognised_size_share=args.held_share, unrecognised_gate=args.unrecognised_gate)
        except NrmlcError as error:
            raise NrmlcError(f"--held-share or --unrecognised-gate: {error}") from None
        partner = parse_variant("partner", args.partner, "default")
        own = parse_variant("own", args.own, "default")
        seeds, sequences, groups = chosen_targets(args)
    except NrmlcError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    cache = RunCache(args.cache)
    default_specs = specs_for(sequences, TrackerParams(), seeds, n_frames=args.max_frames)
    default_runs = cache.run(default_specs, jobs=args.jobs)

    def runs_of(params: TrackerParams) -> list:
        return cache.run(specs_for(sequences, params, seeds, n_frames=args.max_frames), jobs=args.jobs)

    own_runs = default_runs if own == TrackerParams() else runs_of(own)
    partner_runs = runs_of(partner)
    choices = [_chosen_run(mine, other, args.memory, args.blend_iou, args.held_share, args.unrecognised_gate,
                           own.patch_size, args.choice)
               for mine, other in zip(own_runs, partner_runs)]
    named = [("partner alone", partner, partner_runs)]
    if own != TrackerParams():
        named.append(("own alone", own, own_runs))
    blend = "" if args.blend_iou >= 1 else f", blend at IoU >= {args.blend_iou:g}"
    if args.held_share > 0:
        blend += f", size held {args.held_share:g} under eps_pos* >= {args.unrecognised_gate:g}"
    named.append((f"the choice (memory {args.memory:g}{blend}, by {args.choice})", partner, choices))
    base_measures = run_measures(default_runs, default_specs)
    base = overlaps_of(base_measures)
    rows = []
    for name, params, runs in named:
        measures = run_measures(runs, default_specs)
        rows.append(screen_row(name, params.as_dict(), overlaps_of(measures), scales_of(measures), base, groups, seeds))
    document = screen_document(TrackerParams().as_dict(), base, scales_of(base_measures), seeds, groups, rows)
    print(f"default; own ({args.own or 'the default'}) and partner ({args.partner}), seeds {args.seeds}")
    return _report(args, document)


if __name__ == "__main__":
    sys.exit(main())
