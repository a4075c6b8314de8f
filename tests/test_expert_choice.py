"""The offline frame-by-frame choice between two runs (experiments/development/expert_choice.py)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from experiments.development import expert_choice
from nrmlc.errors import NrmlcError
from nrmlc.tracker.loop import TrackResult


def _run(errors, offset):
    n = len(errors)
    boxes = np.tile(np.array([10.0, 10.0, 20.0, 20.0]), (n, 1)) + offset
    return TrackResult(boxes, np.zeros((n, 6)), {"error_positive": np.array([np.nan] + list(errors[1:]))})


def test_the_partner_is_output_only_where_its_average_is_strictly_lower():
    own = _run([0, 0.1, 0.1, 0.5, 0.5, 0.1], 0.0)
    partner = _run([0, 0.2, 0.1, 0.1, 0.1, 0.1], 1.0)
    boxes, chosen = expert_choice.chosen_boxes(own, partner, 0.0)
    np.testing.assert_array_equal(chosen, [0, 0, 0, 1, 1, 0])  # a tie keeps the own box
    np.testing.assert_array_equal(boxes, np.where(chosen[:, None] == 1, partner.boxes, own.boxes))
    # With memory the partner needs its better frames to outweigh its first worse one:
    # averages (own, partner) at 0.5: (0.05, 0.1), (0.075, 0.1), (0.2875, 0.1), ...
    _, chosen = expert_choice.chosen_boxes(own, partner, 0.5)
    np.testing.assert_array_equal(chosen, [0, 0, 0, 1, 1, 1])


def test_boxes_that_agree_are_blended_as_the_tracker_blends_them():
    own = _run([0, 0.1, 0.1, 0.3], 0.0)
    partner = _run([0, 0.3, 0.1, 0.1], 1.0)  # boxes 20 and 21 px wide, 1 px apart: IoU 361 / 480
    boxes, chosen = expert_choice.chosen_boxes(own, partner, 0.0, blend_iou=0.75)
    np.testing.assert_array_equal(chosen, [0, 0, 0, 1])
    np.testing.assert_array_equal(boxes[0], own.boxes[0])  # frame 0: the initial box
    weight = np.array([0.25, 0.5, 0.75])  # the partner's: own eps_pos* / the sum
    size = 20.0 ** (1 - weight) * 21.0 ** weight
    centre = 20.0 + 1.5 * weight  # 20 and 21.5
    np.testing.assert_allclose(boxes[1:], np.stack([centre - size / 2] * 2 + [size] * 2, axis=1))
    boxes, _ = expert_choice.chosen_boxes(own, partner, 0.0, blend_iou=0.76)  # 0.752 < 0.76: the choice
    np.testing.assert_array_equal(boxes, np.where(chosen[:, None] == 1, partner.boxes, own.boxes))


def test_where_neither_run_recognises_the_size_moves_toward_the_last_recognised():
    own = _run([0, 0.1, 0.3, 0.3, 0.1, 0.3], 0.0)
    partner = _run([0, 0.2, 0.3, 0.1, 0.3, 0.3], 0.0)
    own.boxes[:, 2:] = [[20, 20], [30, 30], [10, 10], [20, 20], [40, 40], [10, 10]]
    partner.boxes[:, 2:] = own.boxes[:, 2:]
    boxes, _ = expert_choice.chosen_boxes(own, partner, 0.0, held_share=0.5, gate=0.15)
    # Recognised at frames 1, 3 and 4 (30, 20 and 40 px): frame 2 moves half way to 30, frame 5 to 40.
    np.testing.assert_allclose(boxes[:, 2], [20, 30, (10 * 30) ** 0.5, 20, 40, (10 * 40) ** 0.5])
    np.testing.assert_allclose(boxes[:, :2] + boxes[:, 2:] / 2, own.boxes[:, :2] + own.boxes[:, 2:] / 2)
    boxes, _ = expert_choice.chosen_boxes(own, partner, 0.0, held_share=0.5, gate=0.35)  # all recognised
    np.testing.assert_array_equal(boxes, own.boxes)


def test_runs_of_other_lengths_are_refused():
    with pytest.raises(NrmlcError, match="frames"):
        expert_choice.chosen_boxes(_run([0, 0.1], 0.0), _run([0, 0.1, 0.2], 0.0), 0.5)


def test_the_study_reports_the_partner_and_the_choice(tmp_path, capsys):
    out = tmp_path / "choice.json"
    code = expert_choice.main(["--sequences", "", "--synthetic", "1", "--seeds", "0", "--max-frames", "8",
                               "--partner", "translation_floor=0", "--cache", str(tmp_path / "cache"),
                               "--json", str(out), "--jobs", "1"])
    assert code == 0
    names = [row["name"] for row in json.loads(out.read_text())["variants"]]
    assert names == ["partner alone",
                     "the choice (memory 0.95, blend at IoU >= 0.5, size held 0.7 under eps_pos* >= 0.15, by error)"]
    assert "the choice" in capsys.readouterr().out


@pytest.mark.parametrize("option, value", [("--memory", "1"), ("--blend-iou", "1.5")])
def test_a_value_outside_its_range_is_one_line(capsys, option, value):
    assert expert_choice.main(["--partner", "translation_floor=0", option, value]) == 2
    assert option in capsys.readouterr().err


def test_the_default_s_two_experts_run_alone_and_chosen_give_the_default(tmp_path):
    """--own: the default's own expert and its partner, each run alone, chosen offline at the
    default's memory, are the default's runs to the bit (the choice's paired difference is 0),
    while each expert alone differs from them."""
    out = tmp_path / "choice.json"
    code = expert_choice.main(["--sequences", "", "--synthetic", "1", "--seeds", "0", "--max-frames", "40",
                               "--own", "second_expert=off", "--partner", "second_expert=off,update_interval=1,eyes=gradient",
                               "--cache", str(tmp_path / "cache"), "--json", str(out), "--jobs", "1"])
    assert code == 0
    document = json.loads(out.read_text())
    rows = {row["name"]: row for row in document["variants"]}
    choice = "the choice (memory 0.95, blend at IoU >= 0.5, size held 0.7 under eps_pos* >= 0.15, by error)"
    assert list(rows) == ["partner alone", "own alone", choice]
    assert rows[choice]["per_seed"] == document["baseline_per_seed"]
    assert any(rows[name]["per_seed"] != document["baseline_per_seed"] for name in ("partner alone", "own alone"))


def test_the_margin_does_not_change_with_an_expert_s_scale():
    """The margin compares eps_pos* / (eps_pos* + eps_neg*): an expert whose errors are all ten
    times larger scores the same; 1/2 where both errors are 0."""
    errors, negatives = np.array([0.02, 0.3]), np.array([0.06, 0.5])
    margins = expert_choice.expert_scores(errors, negatives, "margin")
    np.testing.assert_allclose(margins, [0.25, 0.375])
    np.testing.assert_allclose(expert_choice.expert_scores(errors * [1, 10], negatives * [1, 10], "margin"), margins)
    assert expert_choice.expert_scores(np.zeros(2), np.zeros(2), "margin").tolist() == [0.5, 0.5]
    assert expert_choice.expert_scores(errors, negatives, "error") is errors
