"""Tests that kill the mutants `make mutate` found alive in nrmlc/workbench/otb_results.py.

Each test pins one behaviour a mutant changed and no earlier test looked at: exact boxes of the
affine conversions on asymmetric matrices (numbers by hand below), the fields' defaults, the
shapes refused, and the wording of each refusal (docs/research/mutation.md).
"""
from __future__ import annotations

import io
import re
import struct
import warnings
import zlib

import numpy as np
import pytest
import scipy.io

from nrmlc.errors import DataError, ParameterError
from nrmlc.testing.otb_files import _save, truth
from nrmlc.workbench import otb_results
from nrmlc.workbench.manifest import MAX_FPS
from nrmlc.workbench.otb_results import (_inflated_size, _matrix, _numbers, _struct_fields, _text,
                                         find_otb_result, ivt_affine_boxes, l1_affine_boxes, otb_trackers,
                                         read_otb_result, select_trackers)
from nrmlc.workbench.results_layout import InputTooLarge


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


# == second round: the survivors of the mutmut run at 350ea83 ==================================


class _Sequence:
    """What find_otb_result needs of a sequence: a name, a length, the ground truth (kept as given)."""

    def __init__(self, groundtruth, name="Walker"):
        self.name, self.groundtruth = name, groundtruth

    def __len__(self):
        return len(self.groundtruth)


def _walker(folder, name="Walker_X.mat", res=None, **fields):
    """A rect result of the ten-frame Walker (truth() unless ``res``), startFrame 1 unless given."""
    path = folder / name
    _save(path, res=truth() if res is None else res, type="rect", **fields)
    return path


def _touch(folder, *names):
    for name in names:
        (folder / name).touch()
    return folder


# -- tracker names ---------------------------------------------------------------------------------

def test_trackers_are_named_by_their_most_frequent_spelling_and_sorted_regardless_of_case(tmp_path):
    # ASLA twice and asla once: one tracker, 'ASLA' (not the largest string, 'asla'); sorted as
    # ASLA, beta, Cxt (not by code point, which puts 'Cxt' before 'beta').
    _touch(tmp_path, "Walker_ASLA.mat", "Car4_ASLA.mat", "Bolt_asla.mat", "Walker_beta.mat", "Walker_Cxt.mat")
    assert otb_trackers(tmp_path) == ["ASLA", "beta", "Cxt"]


def test_trackers_are_grouped_by_the_lower_case_key_select_trackers_uses(tmp_path):
    # 'Aß' and 'ASS' differ in lower case ('aß', 'ass') but not in upper case ('ASS'): two trackers,
    # each of which select_trackers finds (grouping by another key would hide one of them).
    _touch(tmp_path, "Walker_Aß.mat", "Walker_ASS.mat")
    assert otb_trackers(tmp_path) == ["ASS", "Aß"]
    assert select_trackers(tmp_path, ["aß", "ass"]) == ["Aß", "ASS"]


def test_unknown_trackers_are_listed_with_those_the_folder_has(tmp_path):
    _touch(tmp_path, "Walker_ASLA.mat", "Walker_beta.mat")
    message = f"{tmp_path}: no OTB results of KCF, TLD (trackers there: ASLA, beta)"
    with pytest.raises(ParameterError, match="^" + re.escape(message) + "$"):
        select_trackers(tmp_path, ["KCF", "asla", "TLD"])


def test_unknown_tracker_of_a_folder_without_results_says_none(tmp_path):
    with pytest.raises(ParameterError, match="^" + re.escape(f"{tmp_path}: no OTB results of KCF (trackers "
                                                             "there: none)") + "$"):
        select_trackers(tmp_path, ["KCF"])


# -- the fields of a result ----------------------------------------------------------------------

@pytest.mark.parametrize("fps, read", [(0.0, None), (-1.0, None), (0.5, 0.5), (1.0, 1.0), (MAX_FPS, MAX_FPS),
                                       (2 * MAX_FPS, None), (np.inf, None)])
def test_fps_is_kept_only_when_positive_and_at_most_max_fps(tmp_path, fps, read):
    assert read_otb_result(_rect_file(tmp_path, fps=np.array([[fps]]))).fps == read


@pytest.mark.parametrize("fields", [{}, {"len": np.array([[10.0]])},
                                    {"startFrame": np.array([[3.0]]), "annoBegin": np.array([[2.0]])}])
def test_an_absent_fps_or_len_is_none(tmp_path, fields):
    # Whatever else the file holds: the fields read just before fps and len (annoBegin, len) must not
    # leak into them (an absent field is read from an empty array, never from uninitialised memory).
    result = read_otb_result(_rect_file(tmp_path, **fields))
    assert result.fps is None
    assert result.declared_length == (10 if "len" in fields else None)


@pytest.mark.parametrize("length, read", [(10.0, 10), (2.0, 2), (np.inf, None), (np.nan, None)])
def test_len_is_read_as_an_integer_unless_not_finite(tmp_path, length, read):
    assert read_otb_result(_rect_file(tmp_path, len=np.array([[length]]))).declared_length == read


def test_a_text_len_names_the_file_and_field(tmp_path):
    _refused(_rect_file(tmp_path, len="long"), "field 'len' is not numeric (text)")


def test_the_result_names_its_file_and_its_boxes_are_read_only(tmp_path):
    path = _rect_file(tmp_path)
    result = read_otb_result(path)
    assert result.path == path and result.type == "rect"
    assert not result.boxes.flags.writeable


# -- read_otb_result: absent, too large, out of memory, v7.3, damaged --------------------------

def test_an_absent_file_is_not_found(tmp_path):
    _refused(tmp_path / "Walker_X.mat", "result file not found")


def test_a_file_over_max_mat_bytes_is_refused_naming_its_kind(tmp_path):
    path = tmp_path / "Walker_X.mat"
    with open(path, "wb") as handle:  # sparse: nothing written
        handle.truncate(otb_results.MAX_MAT_BYTES + 1)
    message = f"{path}: 64.0 MB is too large (OTB result file: at most 64.0 MB); not read"
    with pytest.raises(InputTooLarge, match="^" + re.escape(message) + "$"):
        read_otb_result(path)


def test_memory_running_out_while_loading_names_the_file_and_its_kind(tmp_path, monkeypatch):
    def out_of_memory(*args, **kwargs):
        raise MemoryError

    path = _rect_file(tmp_path)
    monkeypatch.setattr(scipy.io, "loadmat", out_of_memory)
    message = (f"{path}: ran out of memory reading this OTB result file; not scored (free memory or leave the "
               "file out)")
    with pytest.raises(InputTooLarge, match="^" + re.escape(message) + "$"):
        read_otb_result(path)


def _v5(*elements: bytes, order: str = "<") -> bytes:
    """A MAT v5 file: the 128-byte header in byte order ``order`` (``IM`` little, ``MI`` big), then ``elements``."""
    text = b"MATLAB 5.0 MAT-file, written for a test".ljust(116, b" ") + bytes(8)
    return text + struct.pack(order + "H", 0x0100) + (b"IM" if order == "<" else b"MI") + b"".join(elements)


def _tag(kind: int, n_bytes: int, order: str = "<") -> bytes:
    return struct.pack(order + "II", kind, n_bytes)


def test_a_v73_file_is_refused_with_the_way_to_save_it(tmp_path):
    path = tmp_path / "Walker_X.mat"
    path.write_bytes(b"MATLAB 7.3 MAT-file".ljust(116, b" ") + bytes(8) + struct.pack("<H", 0x0200) + b"IM" + bytes(64))
    _refused(path, "a MATLAB v7.3 (HDF5) file; save it with -v7 to read it here")


def test_a_damaged_file_names_the_loaders_error(tmp_path, monkeypatch):
    def damaged(*args, **kwargs):
        raise ValueError("bad tag")

    path = _rect_file(tmp_path)
    monkeypatch.setattr(scipy.io, "loadmat", damaged)
    _refused(path, "not a readable MAT file (ValueError: bad tag)")


# -- the content size checked before loading ---------------------------------------------------

_TOO_LARGE = "its variables take more than {} MB once decompressed, too large for an OTB result file; not read"


def _too_large(path, megabytes=256):
    with pytest.raises(InputTooLarge, match="^" + re.escape(f"{path}: " + _TOO_LARGE.format(megabytes)) + "$"):
        read_otb_result(path)


def _left_to_the_loader(path):
    """The size check lets the file through: the loader refuses it (a DataError, not InputTooLarge)."""
    with pytest.raises(DataError, match="^" + re.escape(f"{path}: not a readable MAT file (")) as caught:
        read_otb_result(path)
    assert type(caught.value) is DataError


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("declared", [otb_results.MAX_MAT_CONTENT_BYTES + 1, 1 << 31])
def test_a_variable_declaring_more_than_the_limit_is_refused_in_either_byte_order(tmp_path, order, declared):
    # Only the tag: the file is tiny, the size it declares is counted (2**31: an unsigned count).
    path = tmp_path / "Walker_X.mat"
    path.write_bytes(_v5(_tag(14, declared, order), order=order))
    _too_large(path)


def test_a_file_without_the_v5_marker_is_not_walked(tmp_path):
    # Version 0x0100 (big-endian) at 124 but 'XX' where 'IM'/'MI' belong: not v5, left to the loader,
    # even though a big-endian walk would find a variable over the limit.
    path = tmp_path / "Walker_X.mat"
    path.write_bytes(b"not v5".ljust(124, b" ") + b"\x01\x00XX" + _tag(14, 1 << 30, ">"))
    _left_to_the_loader(path)


def test_elements_are_walked_at_their_8_byte_padded_ends(tmp_path):
    # A 5-byte uint8 element (3 bytes of padding), then a tag declaring over the limit: found only when the
    # walk skips 5 + 3 bytes.
    path = tmp_path / "Walker_X.mat"
    path.write_bytes(_v5(_tag(2, 5) + bytes(8), _tag(14, otb_results.MAX_MAT_CONTENT_BYTES + 1)))
    _too_large(path)


def test_a_small_element_holds_its_data_in_its_tag(tmp_path):
    # A small element of one byte (kind = 1 << 16 | miUINT8, its byte 5 in the tag's second word) adds
    # nothing and the walk goes on to the next tag ...
    small = struct.pack("<I", 1 << 16 | 2) + b"\x05\x00\x00\x00"
    path = tmp_path / "Walker_X.mat"
    path.write_bytes(_v5(small, _tag(14, otb_results.MAX_MAT_CONTENT_BYTES + 1)))
    _too_large(path)
    # ... and a file of only that element is left to the loader (which refuses it).
    path.write_bytes(_v5(small))
    _left_to_the_loader(path)


def _content_bytes(path) -> int:
    """What the variables of a v5 file take decompressed (every top-level element inflated whole)."""
    raw, at, total = path.read_bytes(), 128, 0
    while at < len(raw):
        kind, n_bytes = struct.unpack("<II", raw[at: at + 8])
        data = raw[at + 8: at + 8 + n_bytes]
        total += len(zlib.decompress(data)) if kind == 15 else n_bytes
        at += 8 + n_bytes + (-n_bytes % 8 if kind != 15 else 0)
    return total


@pytest.mark.parametrize("compressed", [False, True])
def test_variables_taking_exactly_the_limit_are_read_one_byte_more_is_refused(tmp_path, monkeypatch, compressed):
    path = tmp_path / "Walker_X.mat"
    cell = np.empty((1, 1), dtype=object)
    cell[0, 0] = {"res": truth(), "type": "rect"}
    scipy.io.savemat(path, {"results": cell}, do_compression=compressed)
    content = _content_bytes(path)
    monkeypatch.setattr(otb_results, "MAX_MAT_CONTENT_BYTES", content)
    np.testing.assert_array_equal(read_otb_result(path).boxes, truth())
    monkeypatch.setattr(otb_results, "MAX_MAT_CONTENT_BYTES", content - 1)
    _too_large(path, 0)


@pytest.mark.parametrize("compressed", [False, True])
def test_the_sizes_of_all_variables_add_up(tmp_path, monkeypatch, compressed):
    # Two variables, each within the limit, together one byte over it.
    path = tmp_path / "Walker_X.mat"
    cell = np.empty((1, 1), dtype=object)
    cell[0, 0] = {"res": truth(), "type": "rect"}
    scipy.io.savemat(path, {"results": cell, "extra": np.ones((8, 8))}, do_compression=compressed)
    content = _content_bytes(path)
    monkeypatch.setattr(otb_results, "MAX_MAT_CONTENT_BYTES", content)
    np.testing.assert_array_equal(read_otb_result(path).boxes, truth())
    monkeypatch.setattr(otb_results, "MAX_MAT_CONTENT_BYTES", content - 1)
    _too_large(path, 0)


def test_a_later_compressed_variable_is_inflated_only_up_to_what_the_earlier_ones_left(tmp_path, monkeypatch):
    # Limit 8 MiB: 6 MiB of zeros, then 64 MiB of zeros. The second is inflated only while the total stays
    # within the limit (1 MiB steps), never up to its own 8 MiB: at most ~10 MiB inflated in all.
    inflated = []

    class Counting:
        def __init__(self):
            self._inflater = real()

        def decompress(self, data, max_length=0):
            out = self._inflater.decompress(data, max_length)
            inflated.append(len(out))
            return out

        @property
        def unconsumed_tail(self):
            return self._inflater.unconsumed_tail

    def compressed(n_bytes):
        packer = zlib.compressobj(1)
        body = b"".join(packer.compress(bytes(1 << 20)) for _ in range(n_bytes >> 20)) + packer.flush()
        return _tag(15, len(body)) + body

    real = zlib.decompressobj
    path = tmp_path / "Walker_X.mat"
    path.write_bytes(_v5(compressed(6 << 20), compressed(64 << 20)))
    monkeypatch.setattr(otb_results, "MAX_MAT_CONTENT_BYTES", 8 << 20)
    monkeypatch.setattr(zlib, "decompressobj", Counting)
    _too_large(path, 8)
    assert sum(inflated) <= 10 << 20


# -- _inflated_size: exact counts, where it stops ------------------------------------------------

def _stored(n_bytes: int) -> bytes:
    """``n_bytes`` of random data as a zlib stream of stored blocks (incompressible: ~as long as the data)."""
    packer = zlib.compressobj(0)
    return packer.compress(np.random.default_rng(0).bytes(n_bytes)) + packer.flush()


@pytest.mark.parametrize("data_bytes", [100, 65521, 200000])
def test_inflated_size_counts_the_whole_stream_and_stops_at_its_end(data_bytes):
    # 65521 bytes of data are a stream of 65537 bytes: one 64 KiB read and one byte more. The bytes after
    # the stream (the next element) are neither read nor counted.
    stream = _stored(data_bytes)
    handle = io.BytesIO(stream + b"next element")
    assert _inflated_size(handle, len(stream), 1 << 30) == data_bytes
    assert handle.tell() == len(stream)


def test_inflated_size_of_a_truncated_stream_counts_what_is_there():
    stream = _stored(1000)
    handle = io.BytesIO(stream)
    assert _inflated_size(handle, len(stream) + 100, 1 << 30) == 1000


def test_inflated_size_stops_reading_at_the_chunk_that_crosses_the_budget():
    # 200000 bytes of incompressible data, budget 1000: one 64 KiB read (65529 bytes of data in it) and no more.
    stream = _stored(200000)
    handle = io.BytesIO(stream)
    first = len(zlib.decompressobj().decompress(stream[: 1 << 16]))
    assert _inflated_size(handle, len(stream), 1000) == first
    assert handle.tell() == 1 << 16


def test_inflated_size_exactly_at_the_budget_counts_on():
    # A content that reaches the budget exactly with more to come is counted past it, never reported as fitting.
    stream = _stored(200000)
    first = len(zlib.decompressobj().decompress(stream[: 1 << 16]))
    assert _inflated_size(io.BytesIO(stream), len(stream), first) > first
    # The same with output steps of 1 MiB (3 MiB of zeros in one read): 1 MiB is the budget, 2 MiB are counted.
    zeros = zlib.compress(bytes(3 << 20))
    assert _inflated_size(io.BytesIO(zeros), len(zeros), 1 << 20) == 2 << 20


# -- find_otb_result: notes, offsets, the first box, name maps ---------------------------------

@pytest.mark.parametrize("length", [None, 10])
def test_a_file_covering_every_frame_has_no_note(tmp_path, length):
    fields = {} if length is None else {"len": np.array([[length]])}
    path = _walker(tmp_path, **fields)
    found, boxes, fps, notes = find_otb_result(tmp_path, "x", _Sequence(truth()))
    assert (found, fps, notes) == (path, None, [])
    np.testing.assert_array_equal(boxes, truth())


def test_a_len_other_than_the_rows_is_noted(tmp_path):
    path = _walker(tmp_path, len=np.array([[12]]))
    assert find_otb_result(tmp_path, "X", _Sequence(truth()))[3] == [f"{path}: 10 rows of res, but len says 12"]


def test_rows_beyond_the_sequence_are_noted_and_dropped(tmp_path):
    more = np.vstack([truth(), [[31.0, 31.0, 20.0, 30.0], [33.0, 32.0, 20.0, 30.0]]])
    path = _walker(tmp_path, res=more)
    found, boxes, _, notes = find_otb_result(tmp_path, "X", _Sequence(truth()))
    np.testing.assert_array_equal(boxes, truth())
    assert notes == [f"{path}: 2 rows beyond Walker's 10 frames ignored"]


def test_a_file_starting_after_the_last_frame_is_not_used(tmp_path):
    # startFrame 11 of a ten-frame sequence: offset 10, exactly the sequence's length.
    path = _walker(tmp_path, startFrame=np.array([[11]]))
    assert find_otb_result(tmp_path, "X", _Sequence(truth())) == (
        None, None, None, [f"{path}: not used, it starts at frame 11 of Walker's 10"])


def test_rows_before_the_annotations_first_frame_are_dropped(tmp_path):
    # startFrame 1, annoBegin 3: the file's first two rows are frames before the annotation's first.
    junk = [[500.0, 500.0, 5.0, 5.0], [600.0, 600.0, 5.0, 5.0]]
    _walker(tmp_path, res=np.vstack([junk, truth()]), annoBegin=np.array([[3]]))
    found, boxes, _, notes = find_otb_result(tmp_path, "X", _Sequence(truth()))
    np.testing.assert_array_equal(boxes, truth())
    assert notes == []


def test_a_file_whose_rows_all_precede_the_annotation_is_not_used(tmp_path):
    path = _walker(tmp_path, res=truth()[:2], annoBegin=np.array([[5]]))
    assert find_otb_result(tmp_path, "X", _Sequence(truth()))[1:] == (
        None, None, [f"{path}: not used, it starts at frame 1 of Walker's 10"])


def test_a_first_box_of_another_sequence_is_noted_with_both_boxes(tmp_path):
    # Ground truth given as integers: the note shows it as the float64 boxes it is compared as.
    res = truth()
    res[0] = [100.0, 100.0, 20.0, 30.0]
    path = _walker(tmp_path, res=res)
    note = (f"{path}: not used, its first box [100.0, 100.0, 20.0, 30.0] is not Walker's box on frame 1 "
            "[11.0, 21.0, 20.0, 30.0] (IoU 0.00; results on another version of the sequence?)")
    assert find_otb_result(tmp_path, "X", _Sequence(truth().astype(int))) == (None, None, None, [note])


def test_a_failed_first_box_is_not_compared(tmp_path):
    # A NaN first row (a failed frame) is no mismatch: the file is used, the frame stays failed.
    res = truth()
    res[0] = np.nan
    path = _walker(tmp_path, res=res)
    found, boxes, _, notes = find_otb_result(tmp_path, "X", _Sequence(truth()))
    assert (found, notes) == (path, [])
    np.testing.assert_array_equal(boxes, res)


def test_an_unannotated_first_frame_is_not_compared(tmp_path):
    # The sequence's first frame has no box: the file's first box, whatever it is, is not checked.
    res = truth()
    res[0] = [100.0, 100.0, 20.0, 30.0]
    path = _walker(tmp_path, res=res)
    groundtruth = truth()
    groundtruth[0] = np.nan
    found, boxes, _, notes = find_otb_result(tmp_path, "X", _Sequence(groundtruth))
    assert (found, notes) == (path, [])
    np.testing.assert_array_equal(boxes, res)


def test_a_file_starting_after_max_frames_gives_only_missing_frames(tmp_path):
    path = _walker(tmp_path, res=truth()[5:], startFrame=np.array([[6]]))
    found, boxes, _, _ = find_otb_result(tmp_path, "X", _Sequence(truth()), max_frames=3)
    assert found == path and boxes.shape == (3, 4) and np.isnan(boxes).all()


def _unreadable(path):
    path.write_bytes(b"not a mat file at all")


@pytest.mark.parametrize("first, note", [
    (_unreadable, "not used, unreadable ("),
    (lambda path: _walker(path.parent, path.name, startFrame=np.array([[11]])), "not used, it starts at frame 11"),
    (lambda path: _walker(path.parent, path.name, res=truth()[::-1]), "not used, its first box")])
def test_a_file_not_used_leaves_the_next_one_of_the_sequence(tmp_path, first, note):
    # Walker_X.mat (listed first) is not usable; Wlkr_X.mat, mapped to Walker by name_map, is used.
    first(tmp_path / "Walker_X.mat")
    mapped = _walker(tmp_path, "Wlkr_X.mat")
    found, boxes, _, notes = find_otb_result(tmp_path, "X", _Sequence(truth()), name_map={"wlkr": "walker"})
    assert found == mapped and len(notes) == 1 and notes[0].startswith(f"{tmp_path / 'Walker_X.mat'}: {note}")
    np.testing.assert_array_equal(boxes, truth())


def test_a_name_map_only_maps_stems_to_their_own_sequence(tmp_path):
    # 'wlkr' maps to Walker, 'other' to Bolt: only Wlkr_X.mat is Walker's.
    mapped = _walker(tmp_path, "Wlkr_X.mat")
    _walker(tmp_path, "Other_X.mat")
    name_map = {"wlkr": "walker", "other": "bolt"}
    assert find_otb_result(tmp_path, "X", _Sequence(truth()), name_map=name_map)[0] == mapped
    assert find_otb_result(tmp_path, "X", _Sequence(truth(), "Bolt"), name_map=name_map)[0] == tmp_path / "Other_X.mat"
    assert find_otb_result(tmp_path, "X", _Sequence(truth(), "Car4"), name_map=name_map)[0] is None
