"""Tests that kill the mutants `make mutate` found alive in nrmlc/workbench/metrics.py
(docs/research/mutation.md)."""
from __future__ import annotations

import math
import re
import warnings
from fractions import Fraction

import numpy as np
import pytest

from nrmlc.errors import DataError, ParameterError
from nrmlc.workbench.metrics import (FIRST_BOX_MIN_IOU, MAX_COORDINATE, center_errors, evaluate, evaluate_files,
                                     first_box_mismatch, overlaps, precision_curve, success_auc, success_curve)

NAN4 = [np.nan] * 4


def test_success_auc_uses_the_thresholds_given():
    # overlaps 0.3 and 0.6 at the single threshold 0.5: one of two frames succeeds.
    assert success_auc([0.3, 0.6], thresholds=[0.5]) == 0.5
    assert success_auc([0.3, 0.6], thresholds=[0.0, 0.5]) == 0.75


def test_evaluate_files_passes_skip_first_on(tmp_path):
    truth = tmp_path / "groundtruth_rect.txt"
    result = tmp_path / "result.txt"
    np.savetxt(truth, [[1, 1, 10, 10], [2, 2, 10, 10], [3, 3, 10, 10]], fmt="%d", delimiter=",")
    np.savetxt(result, [[1, 1, 10, 10], [50, 50, 10, 10], [3, 3, 10, 10]], fmt="%d", delimiter=",")
    assert evaluate_files(result, truth, skip_first=False).n_frames == 3
    assert evaluate_files(result, truth).n_frames == 2
    assert evaluate_files(result, truth, skip_first=False).mean_overlap == 2 / 3


# ---------------------------------------------------------------- issue 80 item 5: the survivors of 350ea83
#
# Each test below pins one behaviour that a surviving mutant changed and no test looked at (the
# mutant names are in brackets); numbers are worked out by hand in the comments. The survivors no
# input can tell apart are listed at the end of this file.

# The same four frames as tests/test_metrics.py's GT (frame 0 is the initial box).
GT = np.array([[0, 0, 10, 10], [0, 0, 10, 10], [10, 10, 10, 10], [20, 20, 10, 10]], dtype=float)


def _raises_exactly(exc_type, message):
    """pytest.raises on the whole message, so a changed or missing word fails."""
    return pytest.raises(exc_type, match="^" + re.escape(message) + "$")


# ---- wording of every refusal: each names the argument at fault (x__boxes_7/16, x__pair_*, names in the
# curves and evaluate, x__values_8/11, x__thresholds_16, x_evaluate_21..24 and 66..70)

@pytest.mark.parametrize("call, message", [
    (lambda: overlaps({"x": 1}, [0, 0, 1, 1]), "predicted: expected numeric boxes of shape (n, 4), got dict"),
    (lambda: overlaps([0, 0, 1, 1], "1,2,3,4"), "groundtruth: expected numeric boxes of shape (n, 4), got str"),
    (lambda: center_errors([0, 0, 1], [0, 0, 1, 1]), "predicted: expected boxes of shape (n, 4) or (4,), got shape (3,)"),
    (lambda: overlaps([0, 0, 1, 1], np.zeros((2, 2, 4))),
     "groundtruth: expected boxes of shape (n, 4) or (4,), got shape (2, 2, 4)"),
    (lambda: overlaps(np.zeros((3, 4)), np.zeros((2, 4))),
     "predicted and groundtruth have incompatible shapes (3, 4) and (2, 4)"),
    (lambda: evaluate(GT, {"x": 1}), "groundtruth: expected numeric boxes of shape (n, 4), got dict"),
    (lambda: evaluate(GT, GT[0]), "evaluate: predicted and groundtruth must be 2-D arrays of shape (n, 4)"),
    (lambda: success_curve([[0.5]]), "overlaps: expected a 1-D array, got shape (1, 1)"),
    (lambda: precision_curve([[1.0]]), "errors: expected a 1-D array, got shape (1, 1)"),
    (lambda: success_curve([0.5], [[0.1]]), "thresholds: expected a non-empty 1-D array of finite thresholds"),
    (lambda: precision_curve([1.0], [[5.0]]), "thresholds: expected a non-empty 1-D array of finite thresholds"),
], ids=["overlaps-dict", "overlaps-str-truth", "cle-3-values", "overlaps-3d-truth", "incompatible",
        "evaluate-dict-truth", "evaluate-1d", "success-2d", "precision-2d", "success-2d-thresholds",
        "precision-2d-thresholds"])
def test_each_parameter_error_names_the_argument_and_the_shape(call, message):
    with _raises_exactly(ParameterError, message):
        call()


@pytest.mark.parametrize("curve, message", [
    (success_curve, "overlaps: no frames to score"), (precision_curve, "errors: no frames to score"),
])
def test_an_empty_curve_input_is_a_data_error_naming_it(curve, message):
    with _raises_exactly(DataError, message):
        curve([])


@pytest.mark.parametrize("skip_first, message", [
    (True, "no annotated frames to evaluate (1 ground-truth rows, frame 0 skipped)"),
    (False, "no annotated frames to evaluate (4 ground-truth rows)"),
])
def test_nothing_to_evaluate_message_says_whether_frame_0_was_skipped(skip_first, message):
    truth = GT[:1] if skip_first else np.full((4, 4), np.nan)
    with _raises_exactly(DataError, message):
        evaluate(GT[: len(truth)], truth, skip_first=skip_first)


def test_empty_groundtruth_is_a_data_error_not_an_index_error():
    # n == 0: frame 0 does not exist, so there is nothing to un-mark (x_evaluate_56 indexed it).
    with _raises_exactly(DataError, "no annotated frames to evaluate (0 ground-truth rows, frame 0 skipped)"):
        evaluate(np.zeros((0, 4)), np.zeros((0, 4)))


# ---- thresholds: non-empty, finite, taken as float64 (x__thresholds_4/6/7, x__values_3/5)

@pytest.mark.parametrize("curve", [success_curve, precision_curve])
@pytest.mark.parametrize("thresholds", [[], [np.nan], [0.5, np.inf], [-np.inf]], ids=["empty", "nan", "inf", "-inf"])
def test_empty_or_non_finite_thresholds_are_refused(curve, thresholds):
    with _raises_exactly(ParameterError, "thresholds: expected a non-empty 1-D array of finite thresholds"):
        curve([0.5], thresholds)


def test_curves_take_numbers_written_as_text():
    # Values and thresholds are converted to float64 (e.g. read from a text file):
    # overlaps 0.3, 0.6 at 0.5 -> 1 of 2; errors 3, 7 at 5 px -> 1 of 2.
    assert success_curve(["0.3", "0.6"], ["0.5"]).tolist() == [0.5]
    assert precision_curve(["3", "7"], ["5"]).tolist() == [0.5]


def test_exact_fraction_thresholds_are_taken_as_floats():
    # Fraction(1, 2) -> 0.5: overlap 0.5 is not > 0.5, 0.6 is; error 5 <= 5, 7 is not.
    assert success_curve([0.5, 0.6], [Fraction(1, 2)]).tolist() == [0.5]
    assert precision_curve([5.0, 7.0], [Fraction(5)]).tolist() == [0.5]


def test_a_missing_value_given_as_none_counts_as_a_failure():
    # None -> NaN, which is neither > t nor <= t.
    assert success_curve([None, 0.6], [0.5]).tolist() == [0.5]
    assert precision_curve([None, 3.0], [5.0]).tolist() == [0.5]


# ---- overlaps: NaN is per box, never spread to the other rows (x_overlaps_122/126)

def test_a_nan_box_makes_only_its_own_overlap_nan():
    boxes = np.array([[0, 0, 10, 10], NAN4, [5, 0, 10, 10]])
    iou = overlaps(boxes, [0, 0, 10, 10])  # NaN in predicted row 1 only
    assert np.isnan(iou[1]) and iou[0] == 1.0 and iou[2] == pytest.approx(50 / 150)
    iou = overlaps([0, 0, 10, 10], boxes)  # NaN in ground-truth row 1 only
    assert np.isnan(iou[1]) and iou[0] == 1.0 and iou[2] == pytest.approx(50 / 150)


@pytest.mark.parametrize("a, b", [
    # disjoint in x (gap 1e10) but overlapping over a height of 1e300 in y
    ([0, 0, 10, 1e300], [1e10, 0, 10, 1e300]),
    # disjoint in y, overlapping over a width of 1e300 in x
    ([0, 0, 1e300, 10], [0, 1e10, 1e300, 10]),
], ids=["apart-in-x", "apart-in-y"])
def test_huge_disjoint_boxes_have_overlap_zero_not_nan(a, b):
    # The negative side of the intersection is clamped to 0 before the product: unclamped,
    # -1e10 * 1e300 overflows to -inf and the IoU becomes -inf / inf = NaN (x_overlaps_42/58).
    assert overlaps(a, b).tolist() == 0.0
    assert overlaps(b, a).tolist() == 0.0


# ---- first_box_mismatch (x_first_box_mismatch_*)

def test_first_box_mismatch_is_none_when_the_first_box_is_the_reference():
    # Only the first box counts: the second one, far off, must not be looked at.
    boxes = np.array([[0.0, 0.0, 10.0, 10.0], [500.0, 500.0, 10.0, 10.0]])
    assert first_box_mismatch(boxes, np.array([0.0, 0.0, 10.0, 10.0])) is None


def test_first_box_mismatch_accepts_an_overlap_of_exactly_one_half():
    # [0, 0, 10, 5] inside [0, 0, 10, 10]: 50 / 100 = 0.5 exactly, which is >= FIRST_BOX_MIN_IOU.
    assert FIRST_BOX_MIN_IOU == 0.5
    assert first_box_mismatch(np.array([[0.0, 0.0, 10.0, 5.0]]), np.array([0.0, 0.0, 10.0, 10.0])) is None
    # just below one half: refused
    assert first_box_mismatch(np.array([[0.0, 0.0, 10.0, 4.9]]), np.array([0.0, 0.0, 10.0, 10.0])) is not None


def test_first_box_mismatch_reports_both_boxes_to_one_decimal_and_their_iou():
    reference = np.array([0.04, 1.16, 10.0, 10.0])
    # The second box is the reference itself: only the first is compared and reported.
    boxes = np.array([[5.14, 0.26, 10.0, 10.0], reference])
    first, ref, iou = first_box_mismatch(boxes, reference)
    assert first == [5.1, 0.3, 10.0, 10.0]  # not [5.0, 0.0, ...] (0 decimals) nor [5.14, 0.26, ...] (2)
    assert ref == [0.0, 1.2, 10.0, 10.0]  # not [0.0, 1.0, ...] nor [0.04, 1.16, ...]
    # x: [5.14, 15.14] & [0.04, 10.04] = 4.9; y: [0.26, 10.26] & [1.16, 11.16] = 9.1
    assert iou == pytest.approx(4.9 * 9.1 / (200 - 4.9 * 9.1))
    assert isinstance(iou, float)


# ---- evaluate: boundaries and the returned arrays

def test_a_coordinate_of_exactly_max_coordinate_is_accepted():
    # MAX_COORDINATE itself is not "beyond" it: neither refused in the ground truth (x_evaluate_46)
    # nor a missing prediction (x_evaluate_83).
    assert MAX_COORDINATE == 1e9
    truth = np.array([[MAX_COORDINATE, 0, 10, 10], [MAX_COORDINATE, -MAX_COORDINATE, 10, 10]])
    result = evaluate(truth.copy(), truth, skip_first=False)
    assert result.n_frames == 2 and result.n_missing == 0
    assert result.overlaps.tolist() == [1.0, 1.0] and result.center_errors.tolist() == [0.0, 0.0]


def test_precision_20_counts_a_centre_error_of_exactly_20_px():
    # Centres (5, 5) and (17, 21): hypot(12, 16) = 20 exactly, which is <= 20 (x_evaluate_171).
    truth = np.array([[0, 0, 10, 10]] * 2, dtype=float)
    predicted = np.array([[0, 0, 10, 10], [12, 16, 10, 10]], dtype=float)
    result = evaluate(predicted, truth)
    assert result.center_errors.tolist() == [20.0]
    assert result.precision_20 == 1.0
    assert result.precision[19] == 0.0 and result.precision[20] == 1.0


def test_evaluation_arrays_are_read_only_and_frames_are_int64():
    # The Evaluation is frozen, and so are its arrays (x_evaluate_122..125, 137, 138);
    # frames are int64 indices, as documented (x_evaluate_136).
    result = evaluate(GT.copy(), GT)
    for name in ("overlaps", "center_errors", "success", "precision", "frames"):
        array = getattr(result, name)
        assert not array.flags.writeable, name
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0
    assert result.frames.dtype == np.int64
    assert result.frames.tolist() == [1, 2, 3]


def test_all_predictions_missing_gives_nan_mean_error_without_a_warning():
    # No frame has a prediction: mean_center_error is NaN, set directly rather than as the
    # mean of an empty slice, which warns "Mean of empty slice" (x_evaluate_132).
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = evaluate(np.full((4, 4), np.nan), GT)
    assert math.isnan(result.mean_center_error) and result.n_missing == 3


# ---- survivors left alive: no input tells them apart (checked by hand and on random extreme inputs)
#
# overlaps
#   83, 85  errstate(invalid=...) dropped around the division: its denominator is union (> 0) or 1.0, and
#           inf / inf cannot occur (inter = inf forces an area of inf, so union = inf - inf = NaN -> 1.0).
#   84, 86  errstate(divide=...) dropped: the denominator is never 0.
#   98      where(union >= 0, ...): union == 0 only when both areas and inter are 0, so inter / 1.0 = 0.
#   107     inner where(union >= 0, ...): a union of 0 gives 0 / 0, discarded by the outer where.
#   109     placeholder denominator 2.0 instead of 1.0: only used where the outer where discards it.
#   113     final clip without lower bound: inter >= 0 (clamped factors) and union > 0, so iou >= 0.
#   114, 119  final clip to 2.0 or none: in IEEE rounding inter <= each area, so union >= inter, iou <= 1.
# evaluate
#   28      p.shape[0] > n: when equal, vstack with 0 padding rows gives the same array (a copy).
#   36      pads n + m rows instead of n - m: rows beyond n are never indexed (p[frames], frames < n).
#   39, 73  errstate(invalid=...) dropped around NaN comparisons: NumPy 2.4 compares NaN quietly.
#   58      annotated[0] = None: a bool array stores None as False.
#   98, 117 placeholder None for missing rows: an object array, converted back to NaN by _boxes, and
#           the missing rows are replaced by 0 / inf by the outer where anyway.
#   102, 121  placeholder 1.0 for missing rows: discarded by the outer where(have, ...).
