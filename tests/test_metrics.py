"""Tests for nrmlc.workbench.metrics (OTB one-pass evaluation)."""
from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrmlc.errors import DataError, ParameterError
from nrmlc.workbench.metrics import (
    PRECISION_THRESHOLDS,
    SUCCESS_THRESHOLDS,
    Evaluation,
    center_errors,
    evaluate,
    evaluate_files,
    overlaps,
    precision_curve,
    success_auc,
    success_curve,
)

NAN4 = [np.nan] * 4


def _data_root() -> Path:
    """Data root: $NRMLC_DATA if set, else <repo>/../shared/data/sequences."""
    env = os.environ.get("NRMLC_DATA")
    if env:
        return Path(env)
    repo = Path(__file__).resolve().parent.parent
    return repo.parent / "shared" / "data" / "sequences"


# ---------------------------------------------------------------- overlaps


def test_overlap_identical_boxes_is_one():
    assert overlaps([3.5, 7.25, 10.1, 20.3], [3.5, 7.25, 10.1, 20.3]) == 1.0


def test_overlap_disjoint_is_zero():
    assert overlaps([0, 0, 10, 10], [20, 20, 5, 5]) == 0.0
    assert overlaps([0, 0, 10, 10], [0, 50, 10, 10]) == 0.0  # overlap in x only


def test_overlap_half_shift_by_hand():
    # intersection 5x10 = 50, union 100 + 100 - 50 = 150
    assert overlaps([0, 0, 10, 10], [5, 0, 10, 10]) == pytest.approx(50 / 150)
    # 2-D shift: intersection 5x5 = 25, union 175
    assert overlaps([0, 0, 10, 10], [5, 5, 10, 10]) == pytest.approx(25 / 175)


def test_overlap_contained_box():
    # 4x5 box inside a 10x10 box: 20 / 100
    assert overlaps([0, 0, 10, 10], [2, 3, 4, 5]) == pytest.approx(0.2)


def test_overlap_touching_edges_and_corner_is_zero():
    assert overlaps([0, 0, 10, 10], [10, 0, 10, 10]) == 0.0
    assert overlaps([0, 0, 10, 10], [0, 10, 10, 10]) == 0.0
    assert overlaps([0, 0, 10, 10], [10, 10, 10, 10]) == 0.0


def test_overlap_area_has_no_plus_one():
    # With the "+1" pixel convention this would be 6*11 / (11*11 + 11*11 - 66).
    assert overlaps([0, 0, 10, 10], [5, 0, 10, 10]) != pytest.approx(66 / 176)


def test_overlap_vectorised_and_broadcast():
    pred = np.array([[0, 0, 10, 10], [5, 0, 10, 10], [20, 20, 1, 1]], float)
    iou = overlaps(pred, [0, 0, 10, 10])
    assert iou.shape == (3,)
    np.testing.assert_allclose(iou, [1.0, 1 / 3, 0.0])


def test_overlap_degenerate_and_nan():
    assert overlaps([0, 0, 0, 0], [0, 0, 0, 0]) == 0.0
    assert overlaps([0, 0, -5, 10], [0, 0, 10, 10]) == 0.0
    assert np.isnan(overlaps(NAN4, [0, 0, 10, 10]))


def test_bad_shapes_raise_parameter_error():
    with pytest.raises(ParameterError):
        overlaps([[0, 0, 1]], [[0, 0, 1]])
    with pytest.raises(ParameterError):
        center_errors(np.zeros((3, 4)), np.zeros((2, 4)))


# ---------------------------------------------------------------- centre error


def test_center_error_identical_is_zero():
    assert center_errors([1, 2, 3, 4], [1, 2, 3, 4]) == 0.0


def test_center_error_345_triangle():
    # same size, shifted by (3, 4)
    assert center_errors([[0, 0, 10, 10]], [[3, 4, 10, 10]])[0] == pytest.approx(5.0)
    # different sizes: centres (5, 5) and (8, 9) -> 5
    assert center_errors([0, 0, 10, 10], [6, 7, 4, 4]) == pytest.approx(5.0)


def test_center_error_uses_half_size():
    # centres (x + w/2): (1 + 1, 1 + 2) vs (0 + 5, 0 + 7) -> (3, 4) -> 5
    assert center_errors([1, 1, 2, 4], [0, 0, 10, 14]) == pytest.approx(5.0)


# ---------------------------------------------------------------- curves


def test_default_thresholds():
    np.testing.assert_allclose(SUCCESS_THRESHOLDS, np.linspace(0, 1, 21))
    np.testing.assert_array_equal(PRECISION_THRESHOLDS, np.arange(51))


def test_success_curve_is_strict():
    curve = success_curve([0.5, 0.5])
    assert curve.shape == (21,)
    assert curve[10] == 0.0  # threshold 0.5: 0.5 is not > 0.5
    assert curve[9] == 1.0  # threshold 0.45
    assert success_curve([0.0])[0] == 0.0  # 0 is not > 0
    assert success_curve([1.0])[-1] == 0.0  # nothing is > 1


def test_success_auc_by_hand():
    # overlap 0.5: > t for t in {0, .05, ..., .45} -> 10 of 21 thresholds
    # overlap 1.0: > t for t in {0, ..., .95}      -> 20 of 21
    # overlap 0.0: never                            -> 0
    ious = [0.5, 1.0, 0.0]
    expected = (10 + 20 + 0) / (21 * 3)
    assert success_auc(ious) == pytest.approx(expected)
    assert np.mean(success_curve(ious)) == pytest.approx(expected)
    # 0.26: > t for t in {0, ..., .25} -> 6 thresholds
    assert success_auc([0.26]) == pytest.approx(6 / 21)


def test_precision_curve_counts_exact_threshold():
    curve = precision_curve([20.0, 20.5, 0.0, np.inf])
    assert curve.shape == (51,)
    assert curve[20] == pytest.approx(2 / 4)  # 20.0 <= 20 counts, 20.5 does not
    assert curve[21] == pytest.approx(3 / 4)
    assert curve[0] == pytest.approx(1 / 4)  # 0 <= 0
    assert curve[-1] == pytest.approx(3 / 4)  # inf never counts


def test_custom_thresholds_and_errors():
    np.testing.assert_allclose(success_curve([0.2, 0.8], [0.1, 0.5, 0.9]), [1.0, 0.5, 0.0])
    np.testing.assert_allclose(precision_curve([3.0, 7.0], [5.0]), [0.5])
    with pytest.raises(ParameterError):
        success_curve([0.5], [[0.1]])
    with pytest.raises(DataError):
        success_curve([])
    with pytest.raises(DataError):
        precision_curve([])


# ---------------------------------------------------------------- evaluate


GT = np.array(
    [
        [0, 0, 10, 10],  # frame 0: initial box
        [0, 0, 10, 10],
        [10, 10, 10, 10],
        [20, 20, 10, 10],
    ],
    float,
)


def test_evaluate_perfect_tracker():
    ev = evaluate(GT.copy(), GT)
    assert isinstance(ev, Evaluation)
    assert ev.n_frames == 3 and ev.n_missing == 0
    assert ev.mean_overlap == 1.0 and ev.mean_center_error == 0.0
    assert ev.precision_20 == 1.0
    assert ev.success.shape == (21,) and ev.precision.shape == (51,)
    assert ev.success_auc == pytest.approx(20 / 21)
    np.testing.assert_array_equal(ev.frames, [1, 2, 3])
    assert ev.overlaps.shape == (3,) and ev.center_errors.shape == (3,)


def test_evaluate_skips_first_frame():
    pred = GT.copy()
    pred[0] = [100, 100, 10, 10]  # frame 0 wrong but ignored
    ev = evaluate(pred, GT)
    assert ev.n_frames == 3 and ev.mean_overlap == 1.0
    ev_all = evaluate(pred, GT, skip_first=False)
    assert ev_all.n_frames == 4
    assert ev_all.mean_overlap == pytest.approx(0.75)
    np.testing.assert_array_equal(ev_all.frames, [0, 1, 2, 3])


def test_evaluate_skips_unannotated_rows():
    gt = GT.copy()
    gt[1] = np.nan
    gt[2] = [10, 10, 0, 10]  # zero width: not annotated
    pred = GT.copy()
    pred[1] = pred[2] = [500, 500, 1, 1]  # would fail, but are not evaluated
    ev = evaluate(pred, gt)
    assert ev.n_frames == 1
    np.testing.assert_array_equal(ev.frames, [3])
    assert ev.mean_overlap == 1.0


def test_evaluate_by_hand_mixture():
    pred = GT.copy()
    pred[1] = [5, 0, 10, 10]  # IoU 1/3, CLE 5
    pred[2] = [13, 14, 10, 10]  # IoU 7*6/(200-42)=42/158, CLE 5
    ev = evaluate(pred, GT)
    np.testing.assert_allclose(ev.overlaps, [1 / 3, 42 / 158, 1.0])
    np.testing.assert_allclose(ev.center_errors, [5.0, 5.0, 0.0])
    assert ev.mean_overlap == pytest.approx((1 / 3 + 42 / 158 + 1) / 3)
    assert ev.mean_center_error == pytest.approx(10 / 3)
    assert ev.precision[4] == pytest.approx(1 / 3)
    assert ev.precision[5] == 1.0


def test_nan_prediction_is_a_failure():
    pred = GT.copy()
    pred[2] = np.nan
    ev = evaluate(pred, GT)
    assert ev.n_frames == 3 and ev.n_missing == 1
    np.testing.assert_array_equal(ev.overlaps, [1.0, 0.0, 1.0])
    assert np.isinf(ev.center_errors[1])
    assert ev.mean_overlap == pytest.approx(2 / 3)
    assert ev.precision_20 == pytest.approx(2 / 3)
    assert ev.precision[-1] == pytest.approx(2 / 3)
    assert ev.success[0] == pytest.approx(2 / 3)
    assert ev.mean_center_error == 0.0  # over frames with a prediction


@pytest.mark.parametrize("row", [
    [np.inf, 10, 20, 20], [10, 10, -np.inf, 20], [1e200, 1e200, 1e200, 1e200], [10, 10, 2e9, 20], [-1e10, 10, 20, 20],
], ids=["inf-x", "-inf-w", "1e200", "huge-w", "far-left"])
def test_non_finite_or_absurd_prediction_is_a_failed_frame(row):
    groundtruth = np.array([[10, 10, 20, 20]] * 3, dtype=float)
    predicted = groundtruth.copy()
    predicted[1] = row
    result = evaluate(predicted, groundtruth)
    assert result.n_missing == 1 and result.n_frames == 2
    assert result.overlaps.tolist() == [0.0, 1.0]
    assert result.center_errors[0] == np.inf and result.center_errors[1] == 0.0
    # Counted the same on both curves: it fails every threshold of each.
    assert result.precision_20 == 0.5 and result.precision[-1] == 0.5 and result.success[0] == 0.5
    assert result.mean_center_error == 0.0  # over the frames with a prediction


def test_absurd_groundtruth_is_refused():
    groundtruth = np.array([[10, 10, 20, 20], [1e200, 1e200, 1e200, 1e200]], dtype=float)
    with pytest.raises(DataError, match=r"groundtruth row 2: value beyond 1e\+09 px"):
        evaluate(groundtruth, groundtruth)


def test_evaluate_files_scores_failed_rows_of_a_result_file(tmp_path):
    (tmp_path / "gt.txt").write_text("10,10,20,20\n" * 4)
    (tmp_path / "r.txt").write_text("10,10,20,20\ninf,inf,inf,inf\n1e200,1e200,1e200,1e200\n10,10,20,20\n")
    result = evaluate_files(tmp_path / "r.txt", tmp_path / "gt.txt")
    assert result.n_missing == 2 and result.overlaps.tolist() == [0.0, 0.0, 1.0]
    assert result.precision_20 == pytest.approx(1 / 3) and result.success_auc == pytest.approx(1 / 3 * 20 / 21)


def test_all_predictions_missing():
    pred = np.full((4, 4), np.nan)
    ev = evaluate(pred, GT)
    assert ev.n_missing == 3 and ev.mean_overlap == 0.0 and ev.precision_20 == 0.0
    assert math.isnan(ev.mean_center_error)
    d = ev.as_dict()
    assert d["mean_center_error"] is None
    json.dumps(d)


def test_short_prediction_pads_with_failures():
    ev = evaluate(GT[:2], GT)
    assert ev.n_frames == 3 and ev.n_missing == 2
    np.testing.assert_array_equal(ev.overlaps, [1.0, 0.0, 0.0])
    assert ev.precision_20 == pytest.approx(1 / 3)


def test_long_prediction_extra_rows_ignored():
    pred = np.vstack([GT, [[999, 999, 1, 1]] * 5])
    ev = evaluate(pred, GT)
    assert ev.n_frames == 3 and ev.n_missing == 0 and ev.mean_overlap == 1.0


def test_nothing_evaluable_raises():
    with pytest.raises(DataError, match="no annotated frames to evaluate"):
        evaluate(GT[:1], GT[:1])  # only frame 0, skipped
    with pytest.raises(DataError, match="no annotated frames to evaluate"):
        evaluate(GT, np.full((4, 4), np.nan), skip_first=False)
    with pytest.raises(ParameterError):
        evaluate(GT[0], GT)


def test_as_dict_is_json_scalars():
    d = evaluate(GT.copy(), GT).as_dict()
    assert set(d) == {
        "n_frames", "n_missing", "mean_center_error", "mean_overlap", "success_auc", "precision_20",
    }
    assert json.loads(json.dumps(d)) == d


def test_evaluation_is_frozen():
    ev = evaluate(GT.copy(), GT)
    with pytest.raises(dataclasses.FrozenInstanceError, match="mean_overlap"):
        ev.mean_overlap = 0.0  # type: ignore[misc]
    assert ev.mean_overlap == 1.0


def test_evaluate_files(tmp_path):
    gt = tmp_path / "gt.txt"
    res = tmp_path / "res.txt"
    gt.write_text("1,1,10,10\r\n1,1,10,10\r\n0,0,0,0\r\n11,11,10,10\r\n")
    res.write_text("1 1 10 10\n6 1 10 10\n5 5 5 5\nNaN,NaN,NaN,NaN\n")
    ev = evaluate_files(res, gt)
    assert ev.n_frames == 2 and ev.n_missing == 1
    np.testing.assert_allclose(ev.overlaps, [1 / 3, 0.0])
    with pytest.raises(DataError):
        evaluate_files(tmp_path / "absent.txt", gt)
    only_first = tmp_path / "one.txt"
    only_first.write_text("1,1,10,10\n")
    with pytest.raises(DataError, match="no annotated frames"):
        evaluate_files(only_first, only_first)


# ---------------------------------------------------------------- properties

_coord = st.integers(-1000, 1000)
_size = st.integers(1, 500)
_box = st.tuples(_coord, _coord, _size, _size).map(lambda b: np.array(b, float))
_fcoord = st.floats(-1e3, 1e3, allow_nan=False)
_fsize = st.floats(0.5, 500, allow_nan=False)
_fbox = st.tuples(_fcoord, _fcoord, _fsize, _fsize).map(lambda b: np.array(b, float))


@settings(max_examples=200, deadline=None)
@given(_fbox, _fbox)
def test_prop_iou_symmetric_and_bounded(a, b):
    ab, ba = float(overlaps(a, b)), float(overlaps(b, a))
    assert ab == pytest.approx(ba, abs=1e-12)
    assert 0.0 <= ab <= 1.0


@settings(max_examples=200, deadline=None)
@given(_box, _box)
def test_prop_iou_one_iff_equal(a, b):
    assert float(overlaps(a, a)) == 1.0
    assert (float(overlaps(a, b)) == 1.0) == bool(np.array_equal(a, b))


@settings(max_examples=200, deadline=None)
@given(_fbox, _fbox)
def test_prop_iou_one_for_identical_float_boxes(a, _):
    assert float(overlaps(a, a.copy())) == 1.0


@settings(max_examples=200, deadline=None)
@given(_fbox, _fbox, _fcoord, _fcoord, st.floats(0.1, 10))
def test_prop_iou_translation_and_scale_invariant(a, b, dx, dy, s):
    base = float(overlaps(a, b))
    shift = np.array([dx, dy, 0.0, 0.0])
    assert float(overlaps(a + shift, b + shift)) == pytest.approx(base, abs=1e-6)
    assert float(overlaps(a * s, b * s)) == pytest.approx(base, abs=1e-6)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(0, 1), min_size=1, max_size=50))
def test_prop_success_curve_non_increasing(ious):
    curve = success_curve(ious)
    assert np.all(np.diff(curve) <= 0)
    assert 0.0 <= success_auc(ious) <= 1.0


@settings(max_examples=100, deadline=None)
@given(st.lists(st.one_of(st.floats(0, 100), st.just(math.inf)), min_size=1, max_size=50))
def test_prop_precision_curve_non_decreasing(errors):
    curve = precision_curve(errors)
    assert np.all(np.diff(curve) >= 0)


# ---------------------------------------------------------------- real data


@pytest.mark.realdata
def test_realdata_kcf_car4_mean_overlap():
    root = _data_root()
    gt = root / "Car4" / "groundtruth_rect.txt"
    result = root.parent / "peer_results" / "KCF" / "Car4.txt"
    for path in (gt, result):
        if not path.is_file():
            pytest.skip(f"real data absent: {path} not found (set NRMLC_DATA)")
    ev = evaluate_files(result, gt)
    assert ev.n_frames == 658 and ev.n_missing == 0
    # The paper's Table II gives 0.47 for KCF on Car4.
    assert 0.46 <= ev.mean_overlap <= 0.50


@pytest.mark.parametrize("predicted", [[["a", "b", "c", "d"]], "1,2,3,4", {"x": 1}], ids=["text", "str", "dict"])
def test_non_numeric_boxes_are_a_parameter_error(predicted):
    with pytest.raises(ParameterError, match="predicted: expected numeric boxes"):
        evaluate(predicted, GT)
