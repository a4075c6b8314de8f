"""Reading OTB sequence folders.

Layout::

    Folder/
        img/0001.jpg ...           frames (jpg, jpeg, png or bmp)
        groundtruth_rect.txt       one x,y,w,h line per frame (1-based)

Variants handled here:

- several targets: ``groundtruth_rect.1.txt``, ``groundtruth_rect.2.txt``, ...
  give one sequence per target, named ``Folder-1``, ``Folder-2`` (OTB's own
  convention, e.g. Jogging-1, Jogging-2);
- sparse-tracker packs (``datainfo.txt`` + ``*_gt.mat``, see
  :mod:`nrmlc.data.sparsepack`): the mat file is the fallback when
  ``groundtruth_rect.txt`` is absent;
- no ground truth at all: every box is NaN, and the caller must give the
  initial box;
- the frames directly in the folder, without the ``img`` level (a folder
  of frames to track with a given initial box).

:func:`open_sequence` also opens a video file (:mod:`nrmlc.data.video_file`).

Frame order
    Frames are ordered by their frame number wherever it sits in the name
    (``0001.jpg``, ``img12.png``, ``1_cam0.png``): every name must follow one
    pattern in which exactly one number changes from file to file, or several
    that all give the same order. The numbers must be consecutive (any
    start). Names that follow different patterns, two files with the same
    number (``0003.png`` and ``0003.jpg``), a gap in the numbering, and
    broken, looping or non-regular entries are refused with a
    :class:`~nrmlc.errors.DataError` naming the files: each of them would
    silently shift the ground truth against the frames. Names starting with
    a dot are ignored.
"""
from __future__ import annotations

import errno
import os
import re
import stat
from pathlib import Path
from typing import Sequence as SequenceType

import numpy as np

from nrmlc.data.boxes import read_box_file
from nrmlc.data.sequence import Sequence
from nrmlc.data.sparsepack import (
    DATAINFO_NAME,
    find_groundtruth_mat,
    groundtruth_mats,
    is_sparsepack,
    read_datainfo,
    read_sparsepack_groundtruth,
)
from nrmlc.data.video_file import VideoFileSequence
from nrmlc.errors import DataError, ParameterError

IMAGE_FOLDER = "img"
IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp")
GROUNDTRUTH_NAME = "groundtruth_rect.txt"
_TARGET_GROUNDTRUTH = re.compile(r"^groundtruth_rect\.(\d+)\.txt$", re.IGNORECASE)
_TARGET_SUFFIX = re.compile(r"^(.+)-(\d+)$")
_NUMBER = re.compile(r"(\d+)")


def check_entry(path: Path, what: str | None = None, folder: bool = False) -> None:
    """Refuse a broken or looping symlink, and anything that is not a regular file (with
    ``folder``: not a folder); ``what`` names the entry's role in the messages."""
    role = f"; a {what}" if what else ""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise DataError(f"{path}: symbolic link loop" + (f" (a {what})" if what else "")) from None
        if exc.errno == errno.ENOENT and path.is_symlink():
            raise DataError(f"{path}: broken symbolic link (its target {os.readlink(path)!r} does not exist"
                            f"{role})") from None
        raise DataError(f"{path}: cannot read ({exc.strerror or exc}{role})") from None
    if folder and not stat.S_ISDIR(mode):
        raise DataError(f"{path}: named as a {what or 'folder'}, but not a folder")
    if not folder and not stat.S_ISREG(mode):
        raise DataError(f"{path}: not a regular file")


def order_frames(images: SequenceType[Path]) -> list[Path]:
    """Sort image files by frame number, refusing sets whose order is not certain.

    Parameters
    ----------
    images : paths of the frames of one folder, in any order.

    Returns
    -------
    list of Path, in frame order.

    Raises
    ------
    DataError
        Names that follow several patterns, several changing numbers that
        disagree on the order, two files with the same number, or a gap in
        the numbering (the message names the files).
    """
    images = sorted(images, key=lambda p: p.name)
    if len(images) <= 1:
        return list(images)
    folder = images[0].parent
    pieces = {path: _NUMBER.split(path.stem) for path in images}
    patterns: dict[tuple[str, ...], list[Path]] = {}
    for path, parts in pieces.items():
        patterns.setdefault(tuple(parts[0::2]), []).append(path)
    if len(patterns) > 1:
        first, second = (group[0].name for group in list(patterns.values())[:2])
        raise DataError(f"{folder}: frame names follow different patterns ({first}, {second}, ...); "
                        f"cannot tell the frame order: name every frame like the others, with one frame number")
    numbers = np.array([[int(v) for v in pieces[path][1::2]] for path in images], dtype=object).reshape(len(images), -1)
    varying = [column for column in range(numbers.shape[1]) if len(set(numbers[:, column])) > 1]
    if not varying:
        raise DataError(f"{folder}: {images[0].name} and {images[1].name} have the same frame number "
                        f"(or none); keep one")
    orders = [sorted(range(len(images)), key=lambda i, c=column: numbers[i, c]) for column in varying]
    if any(order != orders[0] for order in orders[1:]):
        raise DataError(f"{folder}: several numbers change from name to name and disagree on the order "
                        f"(e.g. {images[0].name}, {images[1].name}); cannot tell the frame order")
    column = varying[0]
    ordered = [images[i] for i in orders[0]]
    frame_numbers = [int(numbers[i, column]) for i in orders[0]]
    for previous, current, a, b in zip(frame_numbers, frame_numbers[1:], ordered, ordered[1:]):
        if current == previous:
            raise DataError(f"{folder}: {a.name} and {b.name} have the same frame number {current}; keep one")
        if current != previous + 1:
            missing = f"frame {previous + 1}" if current == previous + 2 else f"frames {previous + 1}-{current - 1}"
            raise DataError(f"{folder}: frame numbers jump from {a.name} to {b.name} ({missing} missing); "
                            f"the ground truth would be shifted against the frames")
    return ordered


def find_images(folder: str | os.PathLike) -> list[Path]:
    """Image files of ``folder/img`` (or of ``folder`` itself when it holds the frames) in frame order
    (see the module docstring).

    Raises
    ------
    DataError
        If there is no ``img`` folder, it holds no jpg/jpeg/png/bmp file, an
        image entry is a broken or looping link or not a regular file, or the
        frame order is not certain (:func:`order_frames`).
    """
    image_folder = Path(folder) / IMAGE_FOLDER
    if not image_folder.is_dir() and any(p.suffix.lower() in IMAGE_EXTENSIONS for p in Path(folder).iterdir()):
        image_folder = Path(folder)  # a plain folder of frames, without the 'img' level
    if not image_folder.is_dir():
        examples = sorted(p.name for p in Path(folder).iterdir() if (p / IMAGE_FOLDER).is_dir())
        hint = (f"; it looks like a data root: give one sequence folder, e.g. {Path(folder) / examples[0]}"
                if examples else "")
        raise DataError(f"{folder}: no '{IMAGE_FOLDER}' folder with the frames{hint}")
    images = sorted(
        p for p in image_folder.iterdir() if p.suffix.lower() in IMAGE_EXTENSIONS and not p.name.startswith(".")
    )
    if not images:
        raise DataError(f"{image_folder}: no images ({', '.join(IMAGE_EXTENSIONS)})")
    for image in images:
        check_entry(image)
    return order_frames(images)

def present(path: Path, what: str | None = None, folder: bool = False) -> bool:
    """Whether ``path`` is there as a readable regular file (with ``folder``: a folder); False when
    nothing is there.

    Something there that cannot be read as a file (a dangling or looping link, a FIFO, a
    device, a folder) is an error naming it, not an absence: it would silently turn an
    annotated sequence into one without ground truth.
    """
    if not os.path.lexists(path):
        return False
    check_entry(Path(path), what, folder)
    return True


def find_groundtruth(folder: str | os.PathLike) -> Path | None:
    """The folder's ``groundtruth_rect.txt``, its name in any case (``GROUNDTRUTH_RECT.TXT``, as
    written on a case-blind file system), or None; hidden names are never it.

    Raises
    ------
    DataError
        If it is not a readable regular file, or two names differ only in case.
    """
    found = [path for path in sorted(Path(folder).iterdir()) if path.name.lower() == GROUNDTRUTH_NAME]
    if len(found) > 1:
        raise DataError(f"{folder}: {' and '.join(p.name for p in found)} are both the ground truth; keep one")
    return found[0] if found and present(found[0]) else None


def find_target_groundtruths(folder: str | os.PathLike) -> dict[int, Path]:
    """Per-target ground-truth files ``groundtruth_rect.<k>.txt``, keyed by ``k``.

    Raises
    ------
    DataError
        If one of them is not a readable regular file, or two name the same target.
    """
    found = {}
    for path in sorted(Path(folder).iterdir()):
        match = _TARGET_GROUNDTRUTH.match(path.name)
        if match and present(path):
            target = int(match.group(1))
            if target in found:  # groundtruth_rect.1.txt and groundtruth_rect.01.txt
                raise DataError(f"{folder}: {found[target].name} and {path.name} are both target {target}; keep one")
            found[target] = path
    return dict(sorted(found.items()))


def _split_target_name(path: Path) -> tuple[Path, int] | None:
    """``root/Jogging-2`` -> ``(root/Jogging, 2)`` when that folder has target 2."""
    match = _TARGET_SUFFIX.match(path.name)
    if not match:
        return None
    folder = path.with_name(match.group(1))
    target = int(match.group(2))
    if folder.is_dir() and target in find_target_groundtruths(folder):
        return folder, target
    return None


def open_sequence(
    path: str | os.PathLike,
    target: int | None = None,
    init_box: SequenceType[float] | None = None,
) -> Sequence:
    """Open a sequence folder.

    Parameters
    ----------
    path : the sequence folder, or a video file (see
        :class:`~nrmlc.data.video_file.VideoFileSequence`); a name like
        ``root/Jogging-2`` (no such folder) means target 2 of ``root/Jogging``.
    target : for multi-target folders, which target (1, 2, ...); default
        the first one.
    init_box : (4,) 1-based ``x, y, w, h`` overriding the first box (needed
        when the sequence has no ground truth or frame 1 is unannotated).

    Returns
    -------
    Sequence

    Raises
    ------
    DataError
        Folder missing or not a folder, no images, first image unreadable,
        unknown target, malformed ground truth (the message names the file).
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ParameterError(f"open_sequence: path must be a str or os.PathLike, got {type(path).__name__}")
    if target is not None and (isinstance(target, bool) or not isinstance(target, (int, np.integer)) or target < 1):
        raise ParameterError(f"open_sequence: target must be an integer >= 1, got {target!r}")
    folder = Path(path)
    if folder.is_file():  # a video file (.mp4, .avi, ...): nrmlc/data/video_file.py
        if target is not None:
            raise DataError(f"{folder}: a video file has no per-target ground truth; target={target} is for folders")
        return VideoFileSequence(folder, init_box=init_box)
    if not folder.exists():
        split = _split_target_name(folder)
        if split is None:
            raise DataError(f"{folder}: sequence folder not found")
        folder, named_target = split
        if target is not None and target != named_target:
            raise DataError(f"{path}: the name says target {named_target} but target={target} was given")
        target = named_target
    if not folder.is_dir():
        raise DataError(f"{folder}: not a folder")
    images = find_images(folder)

    # "." or ".." (tracking from inside the folder) has no name of its own: take the real folder's.
    base_name = folder.name if folder.name not in ("", ".", "..") else os.path.basename(os.path.abspath(folder))
    name = base_name
    groundtruth_path: Path | None = None
    targets = find_target_groundtruths(folder)
    if target is not None:
        if target not in targets:
            available = ", ".join(str(k) for k in targets) or "none (single-target folder)"
            raise DataError(f"{folder}: no groundtruth_rect.{target}.txt (targets: {available})")
        groundtruth_path = targets[target]
        name = f"{base_name}-{target}"
    elif (single := find_groundtruth(folder)) is not None:
        groundtruth_path = single
    elif targets:
        first_target = next(iter(targets))
        groundtruth_path = targets[first_target]
        name = f"{base_name}-{first_target}"

    if groundtruth_path is None:
        for pack_file in (folder / DATAINFO_NAME, *groundtruth_mats(folder)):
            present(pack_file)  # a pack's files that exist must be readable files
    from_sparsepack = groundtruth_path is None and is_sparsepack(folder)
    if groundtruth_path is not None:
        groundtruth = read_box_file(groundtruth_path)
    elif from_sparsepack:
        groundtruth = read_sparsepack_groundtruth(folder, n_images=len(images))
        groundtruth_path = find_groundtruth_mat(folder)
    else:
        groundtruth = None

    sequence = Sequence(
        name, images, groundtruth, path=folder, groundtruth_path=groundtruth_path, init_box=init_box
    )
    if from_sparsepack:
        # The mat boxes are in the pixel frame datainfo.txt describes: check it is the images'.
        width, height, _ = read_datainfo(folder)
        if (height, width) != sequence.frame_size:
            raise DataError(
                f"{folder / DATAINFO_NAME}: says {width}x{height} (WxH) but the frames are "
                f"{sequence.frame_size[1]}x{sequence.frame_size[0]}"
            )
    return sequence


def list_sequences(root: str | os.PathLike) -> list[Sequence]:
    """Every sequence under ``root``, sorted by name.

    A subfolder counts as a sequence when it has an ``img`` folder; other
    subfolders are skipped silently. Multi-target folders give one sequence
    per target (``Jogging-1``, ``Jogging-2``).

    Returns
    -------
    list of Sequence

    Raises
    ------
    DataError
        If ``root`` is missing or not a folder, if it holds no sequence, or
        if a sequence folder is broken (the message names the file).
    """
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"{root}: data root {'is not a folder' if root.exists() else 'not found'}")
    sequences = []
    # Names starting with a dot are skipped, as among the frames (a writer's hidden temporary folder).
    for folder in sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")):
        if not (folder / IMAGE_FOLDER).is_dir():
            continue
        targets = find_target_groundtruths(folder)
        if targets and find_groundtruth(folder) is None:
            sequences.extend(open_sequence(folder, target) for target in targets)
        else:
            sequences.append(open_sequence(folder))
    if not sequences:
        hint = "; it is itself a sequence folder: use 'track' on it" if (root / IMAGE_FOLDER).is_dir() else ""
        raise DataError(f"{root}: no sequences (subfolders with an '{IMAGE_FOLDER}' folder){hint}")
    check_unique_names(sequences, root)
    return sorted(sequences, key=lambda s: s.name)


def _source(sequence: Sequence) -> str:
    """Where a sequence comes from, for messages: its folder, and its target file for one target of several."""
    gt = sequence.groundtruth_path
    if gt is not None and _TARGET_GROUNDTRUTH.match(gt.name):
        return f"{sequence.path} (target file {gt.name})"
    return str(sequence.path if sequence.path is not None else sequence.name)


def check_unique_names(sequences: SequenceType[Sequence], root) -> None:
    """Refuse two sequences of one root with the same name, ignoring case (``Jog`` with two targets
    is ``Jog-1`` and ``Jog-2``, so a folder ``Jog-1`` beside it collides): their result files
    (``Jog-1.txt``) would overwrite each other, and on a case-insensitive disk so would ``car4.txt`` and
    ``Car4.txt``.

    Raises
    ------
    DataError
        Naming both folders.
    """
    seen: dict[str, Sequence] = {}
    for sequence in sequences:
        other = seen.setdefault(sequence.name.lower(), sequence)
        if other is not sequence:
            raise DataError(f"{root}: two sequences are named {sequence.name!r} ({_source(other)} and "
                            f"{_source(sequence)}); rename one folder")
