"""The OTB toolkit's own result files, ``<Seq>_<Tracker>.mat``, read for ``nrmlc evaluate``.

``python -m nrmlc evaluate --results OTB_RESULTS_DIR --data DATA`` scores every tracker of such a
folder; ``--results DIR:ASLA,IVT`` (or ``--otb-trackers ASLA,IVT``) only some of them.

File layout
    The benchmark's results (``results_OPE``, e.g. ``Biker_ASLA.mat``) hold a cell ``results``
    whose first element is a struct with ``res`` (one row per frame), ``type``, ``fps``,
    ``len``, ``startFrame``, ``annoBegin`` and, for affine types, ``tmplsize``. Some trackers'
    files (MDNet's) hold only a matrix ``result``: one ``x,y,w,h`` row per frame, as ``rect``,
    without fps (the toolkit's ``genPerfMat`` reads them the same way). Numbers come as any
    integer or float class (uint8, uint16, int16, double): everything is read as float64.

Box conversion (as the toolkit's ``calcSeqErrRobust``)
    ``rect``: the row as it is, ``x, y, w, h``, 1-based. ``ivtAff`` (IVT, ASLA;
    ``calcRectCenter``): the row is ``p = (tx, ty, a11, a12, a21, a22)``, the template
    ``tmplsize = (w, h)`` is centred on 0, its corners map to ``(tx + a11 u + a12 v,
    ty + a21 u + a22 v)``; the box runs from the floored top-left corner ``(-w/2, -h/2)`` to the
    floored bottom-right one ``(w/2, h/2)`` (two opposite corners, not the bounding box of all
    four: for IVT's near-axis-aligned affines the two differ by < 0.001 AUC on the OTB-100
    files). ``L1Aff`` (L1, L1-APG; ``aff2image``, ``calcCenter_L1``): the row is ``(a11, a12,
    a21, a22, t1, t2)`` acting on (row, column) template coordinates, ``tmplsize = (rows,
    cols)``; the corners ``(1, 1)`` and ``(rows, cols)`` mapped and rounded give the box, ``+1``
    in each size. Any other type (``LK_Aff``, ``4corner``, ``SIMILARITY``) is refused with a
    :class:`~nrmlc.errors.DataError` naming the file and the type.

Frames
    Row ``k`` of ``res`` is annotation row ``startFrame - annoBegin + k`` (0-based), which is
    frame ``startFrame - annoBegin + k`` of a sequence read from the benchmark's folder with its
    annotation (e.g. Tiger1: ``startFrame`` 6, ``annoBegin`` 1, so the boxes start at frame 6).
    Frames the file does not cover (before its first row, after its last) are missing
    predictions, scored as failures like every missing prediction in :mod:`nrmlc.workbench.metrics`.
    Where the toolkit differs: it replaces a ``rect`` row that is NaN or of non-positive size
    by the previous row before scoring (TLD's lost frames); here such a row stays a failed
    frame, as in every result this package scores.

Malformed and over-large files
    A file that cannot be read as an OTB result (damaged, a field of the wrong kind: text or a
    struct where numbers belong, a ``type`` that is not text) is not used, with a note naming it
    and the field; the sequence then has no result from that tracker. A ``type`` that is text
    but not converted here, a file of more than :data:`MAX_MAT_BYTES`, variables of more than
    :data:`MAX_MAT_CONTENT_BYTES` once decompressed (checked before loading) or memory running
    out while one is read stop the command with one line naming the file: scoring the tracker
    as failing there would be wrong. The extension is matched without regard to case
    (``Biker_IVT.MAT``); a broken link, a FIFO or a folder by a result file's name is refused
    by name, never taken for an absent file.

Which file is a sequence's
    ``<Seq>`` is matched without regard to case and to the benchmark's spellings of a target
    number (:func:`sequence_key`): ``Skating2.1``, ``Skating2_1`` and ``Skating2-1`` are one
    sequence, ``dudek`` is ``Dudek``. The first box must be the sequence's box on the file's
    first frame (IoU >= 0.5, as :func:`nrmlc.workbench.find.find_result`), else the file is not used:
    results on another version of the sequence. Two files of one tracker that name the same
    sequence (``car4_X.mat``, ``Car4_X.mat``) are refused.
"""
from __future__ import annotations

import functools
import math
import re
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nrmlc.errors import DataError, ParameterError
from nrmlc.workbench.manifest import MAX_FPS
from nrmlc.workbench.results_layout import InputTooLarge, check_input_file, has_suffix, reading

MAT_SUFFIX = ".mat"
#: Largest ``.mat`` result file read (the benchmark's largest is 116 kB).
MAX_MAT_BYTES = 64 << 20
#: Most bytes a ``.mat`` file's variables may take once decompressed, checked before loading.
MAX_MAT_CONTENT_BYTES = 256 << 20
#: The ``type`` values converted here (the toolkit's ``calcSeqErrRobust`` knows more).
SUPPORTED_TYPES = ("rect", "ivtAff", "L1Aff")
class UnsupportedResultType(DataError):
    """A result file whose ``type`` this reader does not convert (refused, never scored as failures)."""


# "Skating2.1", "Skating2_1", "jogging-1": a name, one separator, a target number.
_TARGET = re.compile(r"^(.+?)[._-](\d+)$")
# "<Seq>_<Tracker>" where <Seq> may itself end in "_<number>" (Jogging_1_siamfc3s): the
# optional group is tried first, so a trailing target number stays with the sequence.
_RESULT_NAME = re.compile(r"^(?P<sequence>[^_]+(?:_\d+)?)_(?P<tracker>.+)$")


def sequence_key(name: str) -> str:
    """The name under which a sequence is matched: lower case, target number after ``-``.

    ``"Skating2.1"``, ``"skating2_1"``, ``"Skating2-1"`` -> ``"skating2-1"``; ``"Car24"``
    -> ``"car24"`` (no separator, no target number).
    """
    name = str(name).strip().lower()
    match = _TARGET.match(name)
    return f"{match.group(1)}-{match.group(2)}" if match else name


def split_result_name(stem: str) -> tuple[str, str] | None:
    """``"Biker_KCF_GaussHog"`` -> ``("Biker", "KCF_GaussHog")``; None without a tracker part."""
    match = _RESULT_NAME.match(stem)
    if not match or not match.group("tracker"):
        return None
    return match.group("sequence"), match.group("tracker")


def _result_files(folder) -> list[tuple[Path, str, str]]:
    """``(path, sequence, tracker)`` of every ``<Seq>_<Tracker>.mat`` directly in ``folder``."""
    folder = Path(folder)
    try:
        stamp = folder.stat().st_mtime_ns
    except OSError:
        return []
    # One listing per folder state: a comparison looks up trackers x sequences files in it.
    return list(_listing(str(folder), stamp))


@functools.lru_cache(maxsize=16)
def _listing(folder: str, stamp: int) -> tuple:
    # Whatever the entry is (a link to nothing, a FIFO): looking its file up refuses it by name,
    # where skipping it here would turn it into "no result file".
    found = []
    for path in sorted(Path(folder).iterdir()):
        parts = split_result_name(path.stem) if has_suffix(path, MAT_SUFFIX) else None
        if parts is not None:
            found.append((path, *parts))
    return tuple(found)


def has_otb_results(folder) -> bool:
    """True for a folder that holds ``<Seq>_<Tracker>.mat`` files (any case of ``.mat``).

    Whether it is read as such when it also holds ``<Seq>.txt`` files:
    :func:`nrmlc.workbench.find.result_sources`.
    """
    folder = Path(folder)
    return folder.is_dir() and bool(_result_files(folder))


def otb_sequences(folder) -> list[str]:
    """The ``<Seq>`` parts of a folder's ``<Seq>_<Tracker>.mat`` files, as written, once each."""
    return list(dict.fromkeys(sequence for _, sequence, _ in _result_files(folder)))


def otb_trackers(folder) -> list[str]:
    """The trackers of a folder of OTB result files: the distinct ``<Tracker>`` parts, sorted.

    Parts that differ only by case are one tracker, named by its most frequent spelling.

    Returns
    -------
    list of str
        E.g. ``['ASLA', 'CSK', ..., 'TLD']``; empty if the folder has no such file.
    """
    spellings: dict = {}
    for _, _, tracker in _result_files(folder):
        spellings.setdefault(tracker.lower(), []).append(tracker)
    names = [max(sorted(set(s)), key=s.count) for s in spellings.values()]
    return sorted(names, key=str.lower)


def select_trackers(folder, wanted=None) -> list[str]:
    """``wanted`` (names, any case) checked against :func:`otb_trackers`; all of them when None.

    Raises
    ------
    ParameterError
        For a name the folder does not have (the message lists those it has).
    """
    available = otb_trackers(folder)
    if wanted is None:
        return available
    by_key = {name.lower(): name for name in available}
    unknown = [name for name in wanted if name.lower() not in by_key]
    if unknown:
        raise ParameterError(f"{folder}: no OTB results of {', '.join(unknown)} "
                             f"(trackers there: {', '.join(available) or 'none'})")
    return list(dict.fromkeys(by_key[name.lower()] for name in wanted))


@dataclass(frozen=True)
class OtbResult:
    """One ``<Seq>_<Tracker>.mat`` file, its boxes converted.

    Attributes
    ----------
    path : Path
    type : str
        The file's ``type`` (``'rect'`` for a bare ``result`` matrix).
    boxes : (m, 4) float64
        ``x, y, w, h`` per row of ``res``, 1-based.
    offset : int
        0-based annotation row of ``boxes[0]``: ``startFrame - annoBegin``.
    start_frame, anno_begin : int
        The file's ``startFrame`` and ``annoBegin`` (1 when absent).
    declared_length : int or None
        The file's ``len``.
    fps : float or None
        The file's ``fps`` (None when absent, not finite, not positive or beyond
        :data:`nrmlc.workbench.manifest.MAX_FPS`).
    """

    path: Path
    type: str
    boxes: np.ndarray
    offset: int
    start_frame: int
    anno_begin: int
    declared_length: int | None
    fps: float | None


def _first(value):
    """Unwrap MATLAB's 1x1 cells and structs: the first element until it is not a 1-element object array."""
    while isinstance(value, np.ndarray) and value.dtype == object and value.size >= 1:
        value = value.flat[0]
    return value


def _struct_fields(struct) -> dict:
    """{field: value} of a MATLAB struct as ``scipy.io.loadmat`` returns it (a record or a 1x1 record array)."""
    if isinstance(struct, np.ndarray) and struct.dtype.names:
        struct = struct.flat[0]
    if not (isinstance(struct, np.void) and struct.dtype.names):
        return {}
    return {name: struct[name] for name in struct.dtype.names}


def _numbers(value, path, field) -> np.ndarray:
    """The numbers of a field (a matrix of any numeric class, or a cell holding one), flat, as float64.

    Raises
    ------
    DataError
        Naming the file and the field, for text, a struct, a cell of several things.
    """
    array = np.asarray(_first(value))
    if array.dtype.kind not in "biuf":
        kind = "a struct" if array.dtype.names else "text" if array.dtype.kind in "US" else str(array.dtype)
        raise DataError(f"{path}: field '{field}' is not numeric ({kind})")
    return array.astype(np.float64).ravel()


def _scalar(value, path, field):
    """A real number from a field (a 1x1 matrix of any numeric class), None when empty."""
    numbers = _numbers(value, path, field)
    return float(numbers[0]) if numbers.size else None


def _text(value, path, field) -> str:
    """The text of a field (a char array); anything else is a malformed field, not an unknown type."""
    array = np.asarray(_first(value))
    if array.dtype.kind not in "US" or array.size == 0:
        raise DataError(f"{path}: field '{field}' is not text ({'empty' if array.size == 0 else array.dtype})")
    return "".join(str(s) for s in array.ravel()).strip()


def _frame_number(value, path, field) -> int:
    number = _scalar(value, path, field)
    if number is None:
        return 1
    if not (math.isfinite(number) and number >= 1 and number == int(number)):
        raise DataError(f"{path}: field '{field}' must be a frame number >= 1, got {number:g}")
    return int(number)


def _matrix(value, path, columns: int, what: str) -> np.ndarray:
    array = np.asarray(_first(value) if isinstance(value, np.ndarray) and value.dtype == object else value)
    if array.dtype.kind not in "biuf":
        raise DataError(f"{path}: {what} is not numeric ({array.dtype})")
    array = array.astype(np.float64)
    if array.ndim != 2 or array.shape[1] != columns or array.shape[0] == 0:
        raise DataError(f"{path}: {what} has shape {array.shape}; expected one row of {columns} numbers per frame")
    return array


def matlab_round(x):
    """MATLAB's ``round``: halves away from zero (numpy's rounds them to even)."""
    return np.sign(x) * np.floor(np.abs(x) + 0.5)


def ivt_affine_boxes(res, template_size) -> np.ndarray:
    """Boxes of IVT-style affine states (``type`` ``ivtAff``), as the toolkit's ``calcRectCenter``.

    Parameters
    ----------
    res : (n, 6) array_like
        ``(tx, ty, a11, a12, a21, a22)`` per frame: the template point ``(u, v)`` (centred on 0)
        goes to ``(tx + a11 u + a12 v, ty + a21 u + a22 v)``.
    template_size : (2,) array_like
        ``(w, h)`` of the template (``tmplsize``).

    Returns
    -------
    boxes : (n, 4) float64
        ``x, y, w, h``: from the floored image of the corner ``(-w/2, -h/2)`` to the floored
        image of ``(w/2, h/2)``.
    """
    p = np.asarray(res, dtype=np.float64).reshape(-1, 6)
    w, h = (float(v) for v in np.asarray(template_size, dtype=np.float64).ravel()[:2])
    x0 = np.floor(p[:, 0] - p[:, 2] * w / 2 - p[:, 3] * h / 2)
    y0 = np.floor(p[:, 1] - p[:, 4] * w / 2 - p[:, 5] * h / 2)
    x1 = np.floor(p[:, 0] + p[:, 2] * w / 2 + p[:, 3] * h / 2)
    y1 = np.floor(p[:, 1] + p[:, 4] * w / 2 + p[:, 5] * h / 2)
    return np.stack([x0, y0, x1 - x0, y1 - y0], axis=1)


def l1_affine_boxes(res, template_size) -> np.ndarray:
    """Boxes of L1-tracker affine states (``type`` ``L1Aff``), as the toolkit's ``calcCenter_L1``.

    Parameters
    ----------
    res : (n, 6) array_like
        ``(a11, a12, a21, a22, t1, t2)`` per frame: the template pixel (row ``r``, column ``c``),
        1-based, goes to image row ``a11 r + a12 c + t1`` and column ``a21 r + a22 c + t2``.
    template_size : (2,) array_like
        ``(rows, cols)`` of the template (``tmplsize``).

    Returns
    -------
    boxes : (n, 4) float64
        ``x, y, w, h`` from the rounded images of the corners ``(1, 1)`` and ``(rows, cols)``,
        sizes counted inclusively (``+1``).
    """
    p = np.asarray(res, dtype=np.float64).reshape(-1, 6)
    rows, cols = (float(v) for v in np.asarray(template_size, dtype=np.float64).ravel()[:2])
    top = matlab_round(p[:, 0] + p[:, 1] + p[:, 4])
    left = matlab_round(p[:, 2] + p[:, 3] + p[:, 5])
    bottom = matlab_round(p[:, 0] * rows + p[:, 1] * cols + p[:, 4])
    right = matlab_round(p[:, 2] * rows + p[:, 3] * cols + p[:, 5])
    return np.stack([left, top, right - left + 1, bottom - top + 1], axis=1)


def read_otb_result(path) -> OtbResult:
    """Read one ``<Seq>_<Tracker>.mat`` file and convert its boxes (see the module docstring).

    Raises
    ------
    DataError
        Naming the file: not a MAT file MATLAB v5-v7.2 can hold (v7.3 HDF5 files are not read),
        no ``results`` (or ``result``) variable, a missing or malformed field (text or a struct
        where numbers belong), a broken link, a FIFO or a folder.
    UnsupportedResultType
        For a ``type`` not in :data:`SUPPORTED_TYPES`.
    InputTooLarge
        For a file of more than :data:`MAX_MAT_BYTES`, variables of more than
        :data:`MAX_MAT_CONTENT_BYTES` once decompressed, or memory running out reading it.
    """
    path = Path(path)
    if not check_input_file(path, "OTB result file", MAX_MAT_BYTES):
        raise DataError(f"{path}: result file not found")
    _check_content_size(path)
    with reading(path, "OTB result file"):
        return _convert(path, _load(path))


def _load(path: Path) -> dict:
    import scipy.io

    try:
        return scipy.io.loadmat(str(path))
    except MemoryError:
        raise  # a resource limit, not a damaged file (:func:`reading` names it)
    except NotImplementedError:  # MATLAB v7.3 (HDF5)
        raise DataError(f"{path}: a MATLAB v7.3 (HDF5) file; save it with -v7 to read it here") from None
    except Exception as exc:  # scipy raises ValueError, TypeError, MatReadError... for a damaged file
        raise DataError(f"{path}: not a readable MAT file ({type(exc).__name__}: {exc})") from None


def _convert(path: Path, content: dict) -> OtbResult:
    """The boxes and fields of a loaded ``.mat`` file (see the module docstring)."""
    if "results" not in content and "result" in content:
        boxes = _matrix(content["result"], path, 4, "'result'")
        return OtbResult(path, "rect", boxes, 0, 1, 1, None, None)
    if "results" not in content:
        names = ", ".join(k for k in content if not k.startswith("__")) or "none"
        raise DataError(f"{path}: no 'results' variable (variables: {names}); not an OTB result file")
    fields = _struct_fields(_first(content["results"]))
    if not fields:
        raise DataError(f"{path}: 'results' holds no struct; expected results{{1}} with fields res, type, ...")
    if "res" not in fields or "type" not in fields:
        raise DataError(f"{path}: results{{1}} lacks field {'res' if 'res' not in fields else 'type'} "
                        f"(fields: {', '.join(fields)})")
    kind = _text(fields["type"], path, "type")
    if kind not in SUPPORTED_TYPES:
        raise UnsupportedResultType(f"{path}: result type '{kind}' is not supported (only {', '.join(SUPPORTED_TYPES)})")
    if kind == "rect":
        boxes = _matrix(fields["res"], path, 4, "res")
    else:
        states = _matrix(fields["res"], path, 6, "res")
        if "tmplsize" not in fields:
            raise DataError(f"{path}: type '{kind}' needs the field tmplsize (the template's size)")
        size = _numbers(fields["tmplsize"], path, "tmplsize")
        if size.size != 2 or not np.all(np.isfinite(size)) or np.any(size <= 0):
            raise DataError(f"{path}: tmplsize must be two positive numbers, got {size.tolist()[:4]}")
        # Huge or infinite states give non-finite boxes: failed frames, scored as such.
        with np.errstate(over="ignore", invalid="ignore"):
            boxes = (ivt_affine_boxes if kind == "ivtAff" else l1_affine_boxes)(states, size)
    start = _frame_number(fields.get("startFrame", np.empty(0)), path, "startFrame")
    anno_begin = _frame_number(fields.get("annoBegin", np.empty(0)), path, "annoBegin")
    length = _scalar(fields.get("len", np.empty(0)), path, "len")
    fps = _scalar(fields.get("fps", np.empty(0)), path, "fps")
    fps = fps if fps is not None and math.isfinite(fps) and 0 < fps <= MAX_FPS else None
    boxes.setflags(write=False)
    return OtbResult(path, kind, boxes, start - anno_begin, start, anno_begin,
                     None if length is None or not math.isfinite(length) else int(length), fps)


# MAT v5 data element types (MATLAB's "MAT-File Format"): a variable is one of these two at the top level.
_MI_MATRIX, _MI_COMPRESSED = 14, 15


def _check_content_size(path: Path) -> None:
    """Refuse, before loading, a ``.mat`` file whose variables take more than
    :data:`MAX_MAT_CONTENT_BYTES` (a few hundred kB of zeros can decompress to gigabytes).

    Each top-level variable of a v5 file is walked: an uncompressed one declares its size, a
    compressed one is inflated and counted (and dropped), never more than the limit. Files that
    are not v5 (v4: uncompressed, within the file's size; v7.3 and damaged ones: the loader
    refuses them) are left to the loader.

    Raises
    ------
    InputTooLarge
    """
    with open(path, "rb") as handle:
        header = handle.read(128)
        if len(header) < 128 or header[126:128] not in (b"IM", b"MI"):
            return
        order = "<" if header[126:128] == b"IM" else ">"
        if struct.unpack(order + "H", header[124:126])[0] != 0x0100:
            return
        total = 0
        while total <= MAX_MAT_CONTENT_BYTES:
            tag = handle.read(8)
            if len(tag) < 8:
                return
            kind, n_bytes = struct.unpack(order + "II", tag)
            if kind >> 16:  # a small element: its data is in the tag
                continue
            if kind == _MI_COMPRESSED:
                try:
                    total += _inflated_size(handle, n_bytes, MAX_MAT_CONTENT_BYTES - total)
                except zlib.error:
                    return  # damaged: the loader says so
            else:
                total += n_bytes
                handle.seek(n_bytes + (-n_bytes) % 8, 1)
    raise InputTooLarge(f"{path}: its variables take more than {MAX_MAT_CONTENT_BYTES >> 20} MB once "
                        f"decompressed, too large for an OTB result file; not read")


def _inflated_size(handle, n_bytes: int, budget: int) -> int:
    """Bytes that ``n_bytes`` of zlib data at ``handle`` inflate to, counted up to just over ``budget``."""
    inflater = zlib.decompressobj()
    size, left = 0, n_bytes
    while left > 0 and size <= budget:
        chunk = handle.read(min(left, 1 << 16))
        if not chunk:
            break
        left -= len(chunk)
        size += len(inflater.decompress(chunk, 1 << 20))
        while inflater.unconsumed_tail and size <= budget:
            size += len(inflater.decompress(inflater.unconsumed_tail, 1 << 20))
    return size


def _files_of(folder, tracker: str, sequence_name: str, name_map=None) -> list[Path]:
    """The files of ``tracker`` in ``folder`` that name ``sequence_name`` (or a stem mapped to it)."""
    keys = {sequence_key(sequence_name)} | {sequence_key(stem) for stem, target in (name_map or {}).items()
                                            if sequence_key(target) == sequence_key(sequence_name)}
    found = [path for path, sequence, name in _result_files(folder)
             if name.lower() == tracker.lower() and sequence_key(sequence) in keys]
    by_key: dict = {}
    for path in found:
        by_key.setdefault(sequence_key(split_result_name(path.stem)[0]), []).append(path)
    for same in by_key.values():
        if len(same) > 1:
            raise DataError(f"{same[0]} and {same[1]} both hold {tracker}'s results on {sequence_name} "
                            f"(their names differ only by case or spelling); keep one")
    return [path for path in found if check_input_file(path, "OTB result file", MAX_MAT_BYTES)]


def find_otb_result(folder, tracker: str, sequence, max_frames: int | None = None, name_map=None):
    """The file of ``tracker`` for ``sequence`` in ``folder`` and its boxes aligned to the frames.

    Parameters
    ----------
    folder : path
        A folder of ``<Seq>_<Tracker>.mat`` files.
    tracker : str
        The ``<Tracker>`` part (any case).
    sequence : nrmlc.data.Sequence
        Anything with ``name``, ``len()`` and ``groundtruth`` ((n, 4), NaN rows unannotated).
    max_frames : int, optional
        Only the first frames (the array is cut to them).
    name_map : dict, optional
        {file stem (lower case): sequence name (lower case)}, as :func:`nrmlc.workbench.find.parse_name_map`.

    Returns
    -------
    path : Path or None
    boxes : (n, 4) float64 or None
        One row per frame (``n = min(len(sequence), max_frames)``), NaN where the file has no
        box; None when there is no usable file.
    fps : float or None
    notes : list of str
        Files not used and why; frames the file does not cover.
    """
    from nrmlc.geometry import usable_boxes
    from nrmlc.workbench.metrics import first_box_mismatch

    n_sequence = len(sequence)
    n_frames = n_sequence if max_frames is None else min(n_sequence, max_frames)
    truth = np.asarray(sequence.groundtruth, dtype=np.float64)
    notes = []
    for path in _files_of(folder, tracker, sequence.name, name_map):
        try:
            result = read_otb_result(path)
        except (UnsupportedResultType, InputTooLarge):
            raise  # say so: scoring the tracker as failing there would be wrong
        except DataError as exc:
            notes.append(f"{path}: not used, unreadable ({exc})")
            continue
        offset, boxes = result.offset, result.boxes
        if offset < 0:  # boxes before the annotation's first frame: not frames of this sequence
            boxes, offset = boxes[-offset:], 0
        if offset >= n_sequence or not len(boxes):
            notes.append(f"{path}: not used, it starts at frame {offset + 1} of {sequence.name}'s {n_sequence}")
            continue
        first = truth[offset]
        mismatch = first_box_mismatch(boxes, first) \
            if bool(usable_boxes(first[None, :])[0]) and np.isfinite(boxes[0]).all() else None
        if mismatch:
            notes.append(f"{path}: not used, its first box {mismatch[0]} is not {sequence.name}'s box on frame "
                         f"{offset + 1} {mismatch[1]} (IoU {mismatch[2]:.2f}; results on another version of the "
                         f"sequence?)")
            continue
        aligned = np.full((n_frames, 4), np.nan)
        covered = boxes[: max(0, n_frames - offset)]
        aligned[offset: offset + len(covered)] = covered
        if result.declared_length is not None and result.declared_length != len(result.boxes):
            notes.append(f"{path}: {len(result.boxes)} rows of res, but len says {result.declared_length}")
        if offset:
            notes.append(f"{path}: starts at frame {offset + 1} (startFrame {result.start_frame}, annoBegin "
                         f"{result.anno_begin}); frames 1-{offset} count as missing predictions")
        end = offset + len(boxes)
        if end < n_frames:
            notes.append(f"{path}: boxes for frames {offset + 1}-{end} of {n_frames}; the last "
                         f"{n_frames - end} count as missing predictions")
        elif end > n_sequence:
            notes.append(f"{path}: {end - n_sequence} rows beyond {sequence.name}'s {n_sequence} frames ignored")
        return path, aligned, result.fps, notes
    return None, None, None, notes


def otb_result_boxes(folder, tracker: str, sequence, max_frames: int | None = None):
    """A tracker's boxes on a sequence from a folder of OTB result files, aligned to its frames.

    For experiments: ``boxes, fps, notes = otb_result_boxes(OTB_DIR, "ASLA", open_sequence(...))``,
    then ``nrmlc.workbench.metrics.evaluate(boxes, sequence.groundtruth)``.

    Parameters
    ----------
    folder : path
        A folder of ``<Seq>_<Tracker>.mat`` files (e.g. the benchmark's ``results_OPE``).
    tracker : str
        ``<Tracker>`` (any case), one of :func:`otb_trackers`.
    sequence : nrmlc.data.Sequence
    max_frames : int, optional
        Only the first frames.

    Returns
    -------
    boxes : (n, 4) float64 or None
        ``x, y, w, h`` (1-based) per frame of the sequence, NaN rows where the file has no box
        (before its ``startFrame``, after its last row, a NaN row); None without a usable file
        (none, or its first box is not the sequence's: see ``notes``).
    fps : float or None
        The file's recorded speed.
    notes : list of str
    """
    _, boxes, fps, notes = find_otb_result(folder, tracker, sequence, max_frames)
    return boxes, fps, notes
