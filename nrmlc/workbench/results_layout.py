"""Sequence selection and the layout of a benchmark results folder: what ``nrmlc benchmark``
writes (:mod:`nrmlc.workbench.benchmark`) and ``nrmlc evaluate`` reads (:mod:`nrmlc.workbench.find`)::

    OUT/<Seq>.txt                the primary seed's boxes (what the OTB toolkits read)
    OUT/seeds/<seed>/<Seq>.txt   every other seed
    OUT/summary.csv, summary.json
    OUT/benchmark.json           the manifest (settings, one entry per finished run)
"""
from __future__ import annotations

import os
from pathlib import Path

from nrmlc.errors import DataError, ParameterError

MANIFEST_NAME = "benchmark.json"
SUMMARY_CSV = "summary.csv"
SUMMARY_JSON = "summary.json"
SEEDS_FOLDER = "seeds"
#: Held (flock) around every read-modify-write of the manifest; stays in the folder.
LOCK_NAME = ".benchmark.lock"


def parse_names(text: str | None) -> list[str] | None:
    """``"Car4,Caviar1"`` -> ["Car4", "Caviar1"]; None stays None."""
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise ParameterError(f"--sequences {text!r}: no sequence name given")
    return names


def _check_name(name: str, data_root) -> None:
    """A ``--sequences`` entry names a sequence of the data root, never a path elsewhere."""
    if not isinstance(name, str) or not name or name in (".", "..") or "/" in name or os.sep in name \
            or (os.altsep and os.altsep in name) or "\0" in name:
        raise ParameterError(f"--sequences {name!r}: give the name of a sequence of {data_root}, not a path")


def select_sequences(data_root, names: list[str] | None = None) -> list:
    """The sequences of ``data_root`` (all, or those named, in the order given; case-insensitive).

    Raises
    ------
    DataError
        For a name that is not a sequence of the root (the message lists them).
    """
    from nrmlc.data import list_sequences, open_sequence
    from nrmlc.data.otb import check_unique_names

    if names is not None:
        for name in names:
            _check_name(name, data_root)
        # Open only the named folders (the others' warnings are not this run's business) ...
        chosen = {}
        for name in names:
            try:
                sequence = open_sequence(Path(data_root) / name)
            except DataError:
                break  # ... unless a name is not a folder as written: then look it up below
            if sequence.name.lower() != name.lower():
                break  # a multi-target folder ("Jog" is Jog-1): the full listing finds every collision
            chosen.setdefault(sequence.name, sequence)
        else:
            check_unique_names(list(chosen.values()), data_root)
            return list(chosen.values())
    sequences = list_sequences(data_root)
    if names is None:
        return sequences
    by_name = {s.name.lower(): s for s in sequences}
    unknown = [n for n in names if n.lower() not in by_name]
    if unknown:
        raise DataError(f"{data_root}: no sequence {', '.join(unknown)} "
                        f"(sequences: {', '.join(s.name for s in sequences)})")
    return list({by_name[n.lower()].name: by_name[n.lower()] for n in names}.values())


def result_file(out: Path, name: str, seed: int, primary_seed: int) -> Path:
    """Where the boxes of ``name`` with ``seed`` go (top level for the primary seed)."""
    folder = out if seed == primary_seed else out / SEEDS_FOLDER / str(seed)
    return folder / f"{name}.txt"
