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

    Extensions match in any case (``Car4.TXT`` is Car4's file); names starting with a dot (a
    writer's hidden temporary file) are never results. A candidate that is a broken link, a
    FIFO or a folder is refused by name, never taken for an absent file, and so is one larger
    than a box file can be (:data:`nrmlc.data.boxes.MAX_BOX_FILE_BYTES`); memory running out
    while one is read stops the command (never a tracker scored as failing).

Other result layouts
    A folder of the OTB toolkit's own ``<Seq>_<Tracker>.mat`` files is one tracker per
    ``<Tracker>`` (:mod:`nrmlc.workbench.otb_results`); ``DIR:A,B`` or ``--otb-trackers A,B``
    selects some. A folder that holds both kinds is read as the kind whose files name sequences
    (:func:`reads_as_otb`: a ``readme.txt`` does not make a folder of ``.mat`` files a folder of
    ``.txt`` results). Sequence names match without regard to case and to the benchmark's spellings
    of a target number (``Skating2.1`` is ``Skating2-1``, :func:`nrmlc.workbench.otb_results.sequence_key`);
    two files of one folder level that name the same sequence (``car4.txt``, ``Car4.txt``) are
    refused.

A folder made by ``nrmlc benchmark`` has a ``benchmark.json`` (:func:`read_manifest`) and the
other seeds' results in ``seeds/<seed>/`` (:func:`seed_folders`).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from nrmlc.data.boxes import MAX_BOX_FILE_BYTES
from nrmlc.errors import DataError, ParameterError
from nrmlc.workbench.manifest import read_manifest as load_manifest
from nrmlc.workbench.otb_results import has_otb_results, otb_sequences, select_trackers, sequence_key
from nrmlc.workbench.results_layout import (MANIFEST_NAME, SEEDS_FOLDER, InputTooLarge, check_input_file,
                                            check_input_folder, has_suffix, reading)

#: A result file's extension (any case: ``Car4.TXT`` is Car4's).
RESULT_SUFFIX = ".txt"


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
        target number (``car4.txt``, ``Car4.TXT``): which one is meant cannot be known; for a
        candidate that is a broken link, a FIFO or a folder (never taken for an absent file).
    InputTooLarge
        For a candidate larger than a box file can be.
    """
    key = sequence_key(sequence_name)
    stems = {key} | {sequence_key(stem) for stem, target in name_map.items() if sequence_key(target) == key}
    folders = [folder] + sorted((p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")),
                                key=lambda p: p.name)
    found = []
    for where in folders:
        here = sorted(p for p in where.iterdir() if has_suffix(p, RESULT_SUFFIX) and sequence_key(p.stem) in stems
                      and check_input_file(p, "result file", MAX_BOX_FILE_BYTES))
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
            with reading(path, "result file"):
                boxes = read_box_file(path, predictions=True)
        except InputTooLarge:
            raise  # a resource limit, not the tracker's failure: never scored
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


def result_sources(entries, otb_trackers=None, sequence_keys=None, notes=None) -> list[tuple[str, Path, str | None]]:
    """One ``(name, folder, OTB tracker or None)`` per tracker of the ``--results`` entries.

    A folder of ``<Seq>.txt`` files is one tracker named after the folder; a folder of OTB
    ``<Seq>_<Tracker>.mat`` files is one tracker per ``<Tracker>`` (those of ``DIR:A,B``, else
    those of ``otb_trackers``, else all), named ``<Tracker>``. Which of the two a folder holding
    both kinds is: :func:`reads_as_otb`.

    Parameters
    ----------
    entries : list of str or Path
        ``DIR`` or ``DIR:A,B``.
    otb_trackers : list of str, optional
    sequence_keys : set of str, or a callable returning one, optional
        The :func:`~nrmlc.workbench.otb_results.sequence_key` of every sequence that may be
        scored (and of the file stems ``--name-map`` maps to them); asked for only when a folder
        holds both kinds.
    notes : list, optional
        Gets one line per folder that holds both kinds.
    """
    sources = []
    for entry in entries:
        folder, wanted = split_results_entry(entry)
        if not folder.is_dir():
            raise DataError(f"{folder}: result folder {'is not a folder' if folder.exists() else 'not found'}")
        if reads_as_otb(folder, wanted is not None, sequence_keys, notes if notes is not None else []):
            for tracker in select_trackers(folder, wanted or otb_trackers):
                sources.append((tracker, folder, tracker))
        elif wanted is not None:
            raise ParameterError(f"--results {entry}: ':{','.join(wanted)}' selects trackers of a folder of OTB "
                                 f"<Seq>_<Tracker>.mat files; {folder} is a folder of <Seq>.txt files")
        else:
            sources.append((folder.resolve().name, folder, None))
    return sources


def reads_as_otb(folder: Path, selected: bool, sequence_keys=None, notes=None) -> bool:
    """Whether ``folder`` is read as OTB ``<Seq>_<Tracker>.mat`` results rather than ``<Seq>.txt`` ones.

    Decided by what it holds: a folder without such ``.mat`` files, or with a ``benchmark.json``,
    holds ``<Seq>.txt`` results; one whose trackers are selected (``DIR:A,B``), or without a
    ``.txt`` file that names a sequence (a ``readme.txt``), holds ``.mat`` results. A folder with
    files of both kinds that name sequences is read as the kind that covers more sequences (the
    ``.txt`` files on a tie), and ``notes`` gets one line saying so.

    Parameters
    ----------
    folder : Path
    selected : bool
        Whether trackers of it were selected by name (``DIR:A,B``).
    sequence_keys : set of str, or a callable returning one, optional
        Keys of the sequences that may be scored (default: every name counts).
    notes : list, optional
    """
    if not has_otb_results(folder):
        return False
    if selected:
        return True
    if os.path.lexists(folder / MANIFEST_NAME):
        return False
    stems = [p.stem for p in folder.iterdir() if has_suffix(p, RESULT_SUFFIX)]
    if not stems:
        return True
    keys = sequence_keys() if callable(sequence_keys) else sequence_keys

    def covered(names) -> set:
        found = {sequence_key(name) for name in names}
        return found if keys is None else found & set(keys)

    texts, mats = covered(stems), covered(otb_sequences(folder))
    if not texts or not mats:
        return not texts
    as_otb = len(mats) > len(texts)
    if notes is not None:
        notes.append(f"{folder}: holds both <Seq>.txt results ({len(texts)} sequences) and OTB <Seq>_<Tracker>.mat "
                     f"results ({len(mats)} sequences); read as "
                     + ("the .mat files (the kind that covers more)" if as_otb else
                        "a folder of <Seq>.txt files (the kind that covers as many or more; DIR:TRACKER reads "
                        "its .mat files)"))
    return as_otb


def read_manifest(folder) -> dict | None:
    """The checked ``benchmark.json`` of a ``nrmlc benchmark`` folder, None for any other folder.

    The runs whose result file is not there are left out of it (:mod:`nrmlc.workbench.manifest`).

    Raises
    ------
    DataError
        For a ``benchmark.json`` that is not a benchmark manifest (the one check ``nrmlc
        benchmark`` makes too), or that is a broken link, a FIFO or a folder.
    """
    found = load_manifest(folder)
    return None if found is None else found.data


def primary_seed(folder) -> str:
    """The seed of a ``nrmlc benchmark`` folder's top-level files ("" if it has no manifest, or none yet)."""
    manifest = read_manifest(folder)
    if manifest is None or manifest.get("primary_seed") is None:
        return ""
    return str(manifest["primary_seed"])


def seed_folders(folder) -> list[Path]:
    """The other seeds' folders of a ``nrmlc benchmark`` folder, ``<folder>/seeds/<seed>``, by seed.

    Entries whose name is not a seed (``README``, a hidden file) are not seeds' folders.

    Raises
    ------
    DataError
        For ``seeds`` or a ``seeds/<seed>`` that is there but no folder (a broken or looping
        link, a file, a FIFO): a seed's results are never taken for absent.
    """
    root = Path(folder) / SEEDS_FOLDER
    if not check_input_folder(root, "folder of other seeds' results"):
        return []
    found = [p for p in root.iterdir() if p.name.isascii() and p.name.isdigit()
             and check_input_folder(p, "seed's results folder")]
    return sorted(found, key=lambda p: int(p.name))
