"""Tests that kill the mutants `make mutate` found alive in nrmlc/workbench/otb_results.py.

Each test pins one behaviour a mutant changed and no earlier test looked at: exact boxes of the
affine conversions on asymmetric matrices (numbers by hand below), the fields' defaults, the
shapes refused, and the wording of each refusal (docs/research/mutation.md).
"""
from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
import scipy.io

from nrmlc.errors import DataError
from nrmlc.testing.otb_files import _save
from nrmlc.workbench.otb_results import (_matrix, _numbers, _struct_fields, _text, ivt_affine_boxes,
                                         l1_affine_boxes, read_otb_result)


def _rect_file(tmp_path, name="Walker_X.mat", **fields):
    content = {"res": np.array([[11.0, 21.0, 20.0, 30.0], [13.0, 22.0, 20.0, 30.0]]), "type": "rect"}
    content.update(fields)
    content = {k: v for k, v in content.items() if v is not None}
    path = tmp_path / name
    _save(path, **content)
    return path


def _refused(path, message: str):
    """read_otb_result(path) raises DataError whose text is exactly ``f'{path}: {message}'``."""
    with pytest.raises(DataError, match="^" + re.escape(f"{path}: {message}") + "$"):
        read_otb_result(path)


# -- the affine conversions, by hand -----------------------------------------------------------

def test_ivt_affine_box_of_an_asymmetric_matrix_by_hand():
    # (tx, ty, a11, a12, a21, a22) = (100, 50, 1, 0.25, -0.5, 2); template (w, h) = (32, 24):
    # x0 = floor(100 - 16 - 3) = 81, y0 = floor(50 + 8 - 24) = 34,
    # x1 = floor(100 + 16 + 3) = 119, y1 = floor(50 - 8 + 24) = 66.
    boxes = ivt_affine_boxes([[100.0, 50.0, 1.0, 0.25, -0.5, 2.0]], (32, 24))
    np.testing.assert_array_equal(boxes, [[81.0, 34.0, 38.0, 32.0]])


def test_ivt_affine_box_is_computed_in_float64_for_single_precision_states():
    # MAT files may hold single-precision res. 2**24 + 2 + 1.5 is 16777219.5 in float64 (floor 16777219)
    # but rounds to 16777220 in float32, which would widen the box by one pixel.
    res = np.array([[2.0**24 + 2, 10.0, 1.0, 0.0, 0.0, 1.0]], dtype=np.float32)
    boxes = ivt_affine_boxes(res, (3, 4))
    np.testing.assert_array_equal(boxes, [[2.0**24, 8.0, 3.0, 4.0]])


def test_l1_affine_box_of_an_asymmetric_matrix_by_hand():
    # (a11, a12, a21, a22, t1, t2) = (1.5, 0.25, -0.5, 2, 10, 20); template (rows, cols) = (8, 4):
    # top = round(1.5 + 0.25 + 10) = 12, left = round(-0.5 + 2 + 20) = round(21.5) = 22 (half away),
    # bottom = round(12 + 1 + 10) = 23, right = round(-4 + 8 + 20) = 24.
    boxes = l1_affine_boxes([[1.5, 0.25, -0.5, 2.0, 10.0, 20.0]], (8, 4))
    np.testing.assert_array_equal(boxes, [[22.0, 12.0, 3.0, 12.0]])


def test_l1_affine_box_is_computed_in_float64_for_single_precision_states():
    # top = round(2.5 + 0 + 2**24 + 4) = round(16777222.5) = 16777223 in float64 (half away from zero);
    # in float32 the sum is already 16777222 (spacing 2 there), one pixel off.
    res = np.array([[2.5, 0.0, 0.0, 1.0, 2.0**24 + 4, 0.0]], dtype=np.float32)
    np.testing.assert_array_equal(l1_affine_boxes(res, (1, 1)), [[1.0, 2.0**24 + 7, 1.0, 1.0]])


# -- fields --------------------------------------------------------------------------------------

def test_a_file_without_start_frame_and_anno_begin_starts_at_frame_one(tmp_path):
    result = read_otb_result(_rect_file(tmp_path))
    assert (result.start_frame, result.anno_begin, result.offset) == (1, 1, 0)


def test_empty_fps_and_len_are_none(tmp_path):
    result = read_otb_result(_rect_file(tmp_path, fps=np.zeros((0, 0)), len=np.zeros((0, 0))))
    assert result.fps is None and result.declared_length is None


def test_a_single_row_result_is_read(tmp_path):
    path = _rect_file(tmp_path, res=np.array([[11.0, 21.0, 20.0, 30.0]]))
    np.testing.assert_array_equal(read_otb_result(path).boxes, [[11.0, 21.0, 20.0, 30.0]])


def test_res_held_in_a_cell_is_read(tmp_path):
    cell = np.empty((1, 1), dtype=object)
    cell[0, 0] = np.array([[11.0, 21.0, 20.0, 30.0]])
    np.testing.assert_array_equal(read_otb_result(_rect_file(tmp_path, res=cell)).boxes, [[11.0, 21.0, 20.0, 30.0]])


def test_a_bare_result_matrix_is_a_rect_result_from_frame_one(tmp_path):
    path = tmp_path / "Walker_MDNet.mat"
    scipy.io.savemat(path, {"result": np.array([[11.0, 21.0, 20.0, 30.0]])})
    result = read_otb_result(path)
    assert (result.path, result.type, result.offset, result.start_frame, result.anno_begin) == (path, "rect", 0, 1, 1)
    assert result.fps is None and result.declared_length is None


def test_results_wins_over_a_bare_result_matrix(tmp_path):
    path = tmp_path / "Walker_Both.mat"
    cell = np.empty((1, 1), dtype=object)
    cell[0, 0] = {"res": np.array([[1.0, 2.0, 3.0, 4.0]]), "type": "rect"}
    scipy.io.savemat(path, {"results": cell, "result": np.array([[11.0, 21.0, 20.0, 30.0]])})
    np.testing.assert_array_equal(read_otb_result(path).boxes, [[1.0, 2.0, 3.0, 4.0]])


# -- refusals, word for word ---------------------------------------------------------------------

@pytest.mark.parametrize("value", [0, np.inf, 2.5])
def test_start_frame_must_be_a_frame_number(tmp_path, value):
    path = _rect_file(tmp_path, startFrame=np.array([[value]]))
    _refused(path, f"field 'startFrame' must be a frame number >= 1, got {value:g}")


def test_a_text_start_frame_names_the_file_and_field(tmp_path):
    _refused(_rect_file(tmp_path, startFrame="six"), "field 'startFrame' is not numeric (text)")


def test_a_text_fps_names_the_file_and_field(tmp_path):
    _refused(_rect_file(tmp_path, fps="fast"), "field 'fps' is not numeric (text)")


def test_an_empty_type_is_not_text(tmp_path):
    _refused(_rect_file(tmp_path, type=""), "field 'type' is not text (empty)")


def test_a_numeric_type_is_not_text(tmp_path):
    _refused(_rect_file(tmp_path, type=np.array([[1.0]])), "field 'type' is not text (float64)")


@pytest.mark.parametrize("res", [np.zeros((0, 4)), np.ones((2, 3)), np.ones((2, 4, 3))])
def test_res_of_the_wrong_shape_is_refused(tmp_path, res):
    _refused(_rect_file(tmp_path, res=res),
             f"res has shape {np.asarray(res).shape}; expected one row of 4 numbers per frame")


def test_a_bare_result_of_the_wrong_shape_is_refused(tmp_path):
    path = tmp_path / "Walker_MDNet.mat"
    scipy.io.savemat(path, {"result": np.ones((2, 3))})
    _refused(path, "'result' has shape (2, 3); expected one row of 4 numbers per frame")


def test_no_results_variable_lists_the_variables(tmp_path):
    path = tmp_path / "Walker_X.mat"
    scipy.io.savemat(path, {"alpha": np.ones((1, 1)), "beta": np.ones((1, 1))})
    _refused(path, "no 'results' variable (variables: alpha, beta); not an OTB result file")


def test_no_variables_at_all_says_none(tmp_path):
    path = tmp_path / "Walker_X.mat"
    scipy.io.savemat(path, {})
    _refused(path, "no 'results' variable (variables: none); not an OTB result file")


def test_results_without_a_struct_is_refused(tmp_path):
    path = tmp_path / "Walker_X.mat"
    scipy.io.savemat(path, {"results": np.ones((2, 2))})
    _refused(path, "'results' holds no struct; expected results{1} with fields res, type, ...")


@pytest.mark.parametrize("missing, present", [("res", "type"), ("type", "res")])
def test_a_missing_res_or_type_is_named(tmp_path, missing, present):
    path = _rect_file(tmp_path, **{missing: None, "fps": np.array([[30.0]])})
    fields = f"{present}, fps"
    _refused(path, f"results{{1}} lacks field {missing} (fields: {fields})")


# -- the helpers on inputs the files above do not produce -----------------------------------------

def test_struct_fields_of_what_is_not_a_struct_is_empty():
    assert _struct_fields("text") == {}
    assert _struct_fields(np.void(b"ab")) == {}


def test_numbers_names_a_kind_that_is_neither_text_nor_struct():
    with pytest.raises(DataError, match=re.escape("f.mat: field 'tmplsize' is not numeric (complex128)")):
        _numbers(np.array([[1 + 2j]]), "f.mat", "tmplsize")


def test_matrix_of_a_plain_list():
    np.testing.assert_array_equal(_matrix([[1, 2, 3, 4]], "f.mat", 4, "res"), [[1.0, 2.0, 3.0, 4.0]])


def test_text_of_a_char_matrix_joins_its_rows():
    assert _text(np.array(["ivt", "Aff"]), "f.mat", "type") == "ivtAff"


def test_affine_res_of_the_wrong_shape_is_refused(tmp_path):
    path = _rect_file(tmp_path, type="ivtAff", tmplsize=np.array([[32.0, 24.0]]))
    _refused(path, "res has shape (2, 4); expected one row of 6 numbers per frame")


def test_an_unsupported_type_lists_the_supported_ones(tmp_path):
    from nrmlc.workbench.otb_results import UnsupportedResultType
    path = _rect_file(tmp_path, type="4corner")
    with pytest.raises(UnsupportedResultType, match="^" + re.escape(
            f"{path}: result type '4corner' is not supported (only rect, ivtAff, L1Aff)") + "$"):
        read_otb_result(path)


def test_an_affine_type_without_tmplsize_is_refused(tmp_path):
    path = _rect_file(tmp_path, type="ivtAff", res=np.ones((2, 6)))
    _refused(path, "type 'ivtAff' needs the field tmplsize (the template's size)")


@pytest.mark.parametrize("size, shown", [([0.0, 24.0], "[0.0, 24.0]"), ([1.0, 2.0, 3.0, 4.0, 5.0], "[1.0, 2.0, 3.0, 4.0]")])
def test_tmplsize_must_be_two_positive_numbers(tmp_path, size, shown):
    path = _rect_file(tmp_path, type="ivtAff", res=np.ones((2, 6)), tmplsize=np.array([size]))
    _refused(path, f"tmplsize must be two positive numbers, got {shown}")


def test_a_template_of_one_pixel_is_read(tmp_path):
    path = _rect_file(tmp_path, type="ivtAff", res=np.array([[10.0, 20.0, 1.0, 0.0, 0.0, 1.0]]),
                      tmplsize=np.array([[1.0, 1.0]]))
    np.testing.assert_array_equal(read_otb_result(path).boxes, [[9.0, 19.0, 1.0, 1.0]])


def test_huge_affine_states_are_failed_frames_without_a_warning(tmp_path):
    # 1e308 * 16 overflows (inf) and inf - inf is invalid (NaN): both silent, the box is not finite.
    path = _rect_file(tmp_path, type="ivtAff", res=np.array([[0.0, 0.0, 1e308, -1e308, 0.0, 1.0]]),
                      tmplsize=np.array([[32.0, 24.0]]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        boxes = read_otb_result(path).boxes
    assert not np.isfinite(boxes[0]).all()


def test_anno_begin_is_read_and_named(tmp_path):
    result = read_otb_result(_rect_file(tmp_path, startFrame=np.array([[6.0]]), annoBegin=np.array([[2.0]])))
    assert (result.start_frame, result.anno_begin, result.offset) == (6, 2, 4)
    path = _rect_file(tmp_path, name="Walker_Y.mat", annoBegin=np.array([[0.0]]))
    _refused(path, "field 'annoBegin' must be a frame number >= 1, got 0")
