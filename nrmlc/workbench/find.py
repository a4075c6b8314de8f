"""Finding a tracker's results: result folders, the file of each sequence, benchmark manifests.

A *result folder* holds one ``<Seq>.txt`` per sequence, one ``x,y,w,h`` line
per frame from frame 1 (the OTB toolkit's layout; what ``nrmlc benchmark``
writes). Any tracker's folder works; nothing here is specific to NRMLC.

Finding a sequence's file in a folder
    The file stem is the sequence's name (case-insensitive), or a name that
    ``--name-map FILE_STEM=SEQUENCE`` maps to it (e.g. ``FaceOcc1=Occlusion1``).
    The folder itself is searched first, then its subfolders one level down
    in name order (e.g. ``peer_results/IVT/sparsepack/``). A file is taken
    only if its first box is the sequence's initial box (IoU >= 0.5, when
    frame 1 is annotated): results on another version of a sequence (another
    resolution or frame range) are refused, with a note. Among the files that
    pass, one with exactly one line per frame wins over one with another
    line count.

Other result layouts
    A folder of the OTB toolkit's own ``<Seq>_<Tracker>.mat`` files (and no ``.txt``) is one
    tracker per ``<Tracker>`` (:mod:`nrmlc.workbench.otb_results`); ``DIR:A,B`` or ``--otb-trackers A,B``
    selects some. Sequence names match without regard to case and to the benchmark's spellings
    of a target number (``Skating2.1`` is ``Skating2-1``, :func:`nrmlc.workbench.otb_results.sequence_key`);
    two files of one folder level that name the same sequence (``car4.txt``, ``Car4.txt``) are
    refused.

A folder made by ``nrmlc benchmark`` has a ``benchmark.json`` (:func:`read_manifest`) and the
other seeds' results in ``seeds/<seed>/`` (:func:`seed_folders`).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from nrmlc.errors import DataError, ParameterError
from nrmlc.workbench.otb_results import is_otb_results_folder, select_trackers, sequence_key
from nrmlc.workbench.results_layout import MANIFEST_NAME, SEEDS_FOLDER


def parse_name_map(items) -> dict:
    """``["FaceOcc1=Occlusion1", "A=B,C=D"]`` -> {file stem (lower case): sequence name (lower case)}."""
    mapping = {}
    for item in items or ():
        for pair in (p.strip() for p in str(item).split(",")):
            if not pair:
                continue
            stem, sep, sequence = (s.strip() for s in pair.partition("="))
            if not sep or not stem or not sequence:
                raise ParameterError(f"--name-map {pair!r}: expected FILE_STEM=SEQUENCE")
            mapping[stem.lower()] = sequence.lower()
    return mapping


def _candidates(folder: Path, sequence_name: str, name_map: dict) -> list[Path]:
    """Result files that may hold ``sequence_name``: the folder first, then its subfolders.

    Raises
    ------
    DataError
        For two files of one folder whose names differ only by case or by the spelling of a
        target number (``car4.txt``, ``Car4.txt``): which one is meant cannot be known.
    """
    key = sequence_key(sequence_name)
    stems = {key} | {sequence_key(stem) for stem, target in name_map.items() if sequence_key(target) == key}
    folders = [folder] + sorted((p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")),
                                key=lambda p: p.name)
    found = []
    for where in folders:
        here = sorted(p for p in where.glob("*.txt") if sequence_key(p.stem) in stems and p.is_file())
        by_stem: dict = {}
        for path in here:
            by_stem.setdefault(sequence_key(path.stem), []).append(path)
        for same in by_stem.values():
            if len(same) > 1:
                raise DataError(f"{same[0]} and {same[1]} both name sequence {sequence_name} (their names differ "
                                f"only by case or spelling); keep one")
        found += here
    return found


def find_result(folder, sequence, name_map=None, max_frames: int | None = None):
    """The result file of ``sequence`` in ``folder`` and its boxes (see the module docstring).

    Returns
    -------
    path : Path or None
    boxes : (m, 4) float64 or None
    notes : list of str
        Candidates refused, and a line-count mismatch of the file taken.
    """
    from nrmlc.data import read_box_file
    from nrmlc.geometry import usable_boxes
    from nrmlc.workbench.metrics import first_box_mismatch

    folder = Path(folder)
    n_frames = len(sequence) if max_frames is None else min(len(sequence), max_frames)
    first = sequence.groundtruth[0]
    check_first = bool(usable_boxes(first[None, :])[0])
    notes, fitting = [], []
    for path in _candidates(folder, sequence.name, name_map or {}):
        try:
            boxes = read_box_file(path, predictions=True)
        except DataError as exc:
            notes.append(f"{path}: not used, unreadable ({exc})")
            continue
        mismatch = first_box_mismatch(boxes, first) if check_first and len(boxes) and np.isfinite(boxes[0]).all() else None
        if mismatch:
            notes.append(f"{path}: not used, its first box {mismatch[0]} is not {sequence.name}'s initial box "
                         f"{mismatch[1]} (IoU {mismatch[2]:.2f}; results on another version of the sequence?)")
            continue
        fitting.append((path, boxes))
    if not fitting:
        return None, None, notes
    exact = [(p, b) for p, b in fitting if len(b) == len(sequence) or (max_frames is not None and len(b) >= n_frames)]
    path, boxes = (exact or fitting)[0]
    if not exact:
        if len(boxes) < n_frames:
            notes.append(f"{path}: {len(boxes)} lines for {n_frames} frames; the last "
                         f"{n_frames - len(boxes)} count as missing predictions")
        else:
            notes.append(f"{path}: {len(boxes)} lines for {len(sequence)} frames; extra lines ignored")
    return path, boxes[:n_frames], notes


def split_results_entry(entry) -> tuple[Path, list[str] | None]:
    """``"DIR"`` -> (DIR, None); ``"DIR:ASLA,IVT"`` -> (DIR, ["ASLA", "IVT"]) when DIR is a folder.

    A path that exists as written is never split (a folder name may hold a colon).
    """
    text = str(entry)
    path = Path(text)
    if path.exists() or ":" not in text:
        return path, None
    folder, _, selection = text.rpartition(":")
    if not folder or not Path(folder).is_dir():
        return path, None
    names = [n.strip() for n in selection.split(",") if n.strip()]
    if not names:
        raise ParameterError(f"--results {text}: no tracker named after the ':'")
    return Path(folder), names


def result_sources(entries, otb_trackers=None) -> list[tuple[str, Path, str | None]]:
    """One ``(name, folder, OTB tracker or None)`` per tracker of the ``--results`` entries.

    A folder of ``<Seq>.txt`` files is one tracker named after the folder; a folder of OTB
    ``<Seq>_<Tracker>.mat`` files is one tracker per ``<Tracker>`` (those of ``DIR:A,B``, else
    those of ``otb_trackers``, else all), named ``<Tracker>``.
    """
    sources = []
    for entry in entries:
        folder, wanted = split_results_entry(entry)
        if not folder.is_dir():
            raise DataError(f"{folder}: result folder {'is not a folder' if folder.exists() else 'not found'}")
        if is_otb_results_folder(folder):
            for tracker in select_trackers(folder, wanted or otb_trackers):
                sources.append((tracker, folder, tracker))
        elif wanted is not None:
            raise ParameterError(f"--results {entry}: ':{','.join(wanted)}' selects trackers of a folder of OTB "
                                 f"<Seq>_<Tracker>.mat files; {folder} is a folder of <Seq>.txt files")
        else:
            sources.append((folder.resolve().name, folder, None))
    return sources


def read_manifest(folder) -> dict | None:
    """The ``benchmark.json`` of a ``nrmlc benchmark`` folder, None for any other folder.

    Raises
    ------
    DataError
        For a ``benchmark.json`` that is not a benchmark manifest.
    """
    path = Path(folder) / MANIFEST_NAME
    if not path.is_file():
        return None
    try:
        manifest = json.loads(path.read_text())
        settings, runs = manifest["settings"], manifest.get("runs", {})
        if not isinstance(settings, dict) or not isinstance(runs, dict):
            raise TypeError("settings and runs must be objects")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DataError(f"{path}: not a benchmark manifest ({exc})") from None
    return manifest


def primary_seed(folder) -> str:
    """The seed of a ``nrmlc benchmark`` folder's top-level files ("" if it does not say)."""
    try:
        return str(json.loads((Path(folder) / MANIFEST_NAME).read_text())["primary_seed"])
    except (OSError, ValueError, KeyError, TypeError):
        return ""


def seed_folders(folder) -> list[Path]:
    """The other seeds' folders of a ``nrmlc benchmark`` folder, ``<folder>/seeds/<seed>``, by seed."""
    root = Path(folder) / SEEDS_FOLDER
    if not root.is_dir():
        return []
    found = [p for p in root.iterdir() if p.is_dir() and p.name.isdigit()]
    return sorted(found, key=lambda p: int(p.name))
