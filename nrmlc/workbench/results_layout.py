"""Sequence selection and the layout of a benchmark results folder: what ``nrmlc benchmark``
writes (:mod:`nrmlc.workbench.benchmark`) and ``nrmlc evaluate`` reads (:mod:`nrmlc.workbench.find`)::

    OUT/<Seq>.txt                the primary seed's boxes (what the OTB toolkits read)
    OUT/seeds/<seed>/<Seq>.txt   every other seed
    OUT/summary.csv, summary.json
    OUT/benchmark.json           the manifest (settings, one entry per finished run)

Reading ``evaluate``'s inputs
    Every file ``evaluate`` reads (result files, OTB ``.mat`` files, attribute files, manifests)
    goes through :func:`check_input_file` first: a broken or looping link, a FIFO, a device or
    a folder where a file is looked up is refused by name (as ground truth is, never taken for
    an absent file), and so is a file larger than its kind can be. Memory running out while
    one is read (:func:`reading`) is refused by name too. Both are :class:`InputTooLarge`: the
    command stops, since scoring the tracker as failing there would make a resource limit
    change the scores. File extensions are matched without regard to case (``Car4.TXT``,
    ``Biker_IVT.MAT``: :func:`has_suffix`); names starting with a dot (a writer's hidden
    temporary file) are never inputs.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path

from nrmlc.errors import DataError, ParameterError

MANIFEST_NAME = "benchmark.json"
SUMMARY_CSV = "summary.csv"
SUMMARY_JSON = "summary.json"
SEEDS_FOLDER = "seeds"
#: Held (flock) around every read-modify-write of the manifest; stays in the folder.
LOCK_NAME = ".benchmark.lock"


class InputTooLarge(DataError):
    """An input larger than its kind can be, or one that memory ran out reading: it stops the
    command (never a note, never a tracker scored as failing)."""


def has_suffix(path, suffix: str) -> bool:
    """Whether ``path`` is a visible file name ending in ``suffix``, in any case (``.TXT`` is ``.txt``)."""
    name = Path(path).name
    return not name.startswith(".") and name.lower().endswith(suffix.lower()) and len(name) > len(suffix)


def check_input_file(path, what: str, max_bytes: int) -> bool:
    """Whether an input is there to read; refuse, naming it, one that is there but unreadable or too large.

    Parameters
    ----------
    path : path
    what : str
        What the file is, for messages (``"result file"``).
    max_bytes : int
        The largest file of its kind.

    Returns
    -------
    bool
        False when nothing is there (not even a link).

    Raises
    ------
    DataError
        A broken or looping link, a FIFO, device or folder (:mod:`nrmlc.data.otb`'s check of
        ground-truth files).
    InputTooLarge
        A file of more than ``max_bytes``.
    """
    from nrmlc.data.otb import present

    path = Path(path)
    if not present(path):
        return False
    size = path.stat().st_size
    if size > max_bytes:
        raise InputTooLarge(f"{path}: {_size_text(size)} is too large ({what}: at most "
                            f"{_size_text(max_bytes)}); not read")
    return True


def check_input_folder(path, what: str) -> bool:
    """:func:`check_input_file` for a folder ``evaluate`` reads (``what``: ``"seed's results
    folder"``): something there by its name that is no folder (a broken or looping link, a file, a
    FIFO) is a :class:`DataError` naming it, never taken for an absent folder."""
    from nrmlc.data.otb import present

    return present(Path(path), what, folder=True)


def _size_text(n_bytes: int) -> str:
    return f"{n_bytes / 2**20:.1f} MB" if n_bytes >= 2**20 else f"{n_bytes / 2**10:.1f} kB"


@contextlib.contextmanager
def reading(path, what: str):
    """Turn memory running out while ``path`` is read into :class:`InputTooLarge` naming it."""
    try:
        yield
    except MemoryError:
        raise InputTooLarge(f"{path}: ran out of memory reading this {what}; not scored (free memory or "
                            f"leave the file out)") from None


def is_plain_name(name) -> bool:
    """Whether ``name`` can only name an entry of a folder (no path, no ``..``)."""
    return (isinstance(name, str) and bool(name) and name not in (".", "..") and "/" not in name
            and os.sep not in name and not (os.altsep and os.altsep in name) and "\0" not in name)


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
    if not is_plain_name(name):
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
