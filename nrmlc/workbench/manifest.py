"""The one check of a ``benchmark.json``, for ``nrmlc benchmark`` (which writes it) and ``nrmlc evaluate``
(which follows it).

A manifest is strict JSON (no ``NaN``, no ``Infinity``) of this shape::

    {"settings": {"params": {...}, "max_frames": null or an integer >= 2, "data": "/abs/root"},
     "primary_seed": null or an integer >= 0,
     "runs": {"<Seq>": {"<seed>": {"frames": 1..10^9, "fps": null or 0 < fps <= 10^9,
                                   "scores": null or {"success_auc": ..., ...}, "code_version": "...",
                                   "sequence_identity": "<content key>" (text; absent in older folders)}}}}

A folder of an imported tracker (``nrmlc benchmark --tracker``) has ``"tracker":
"package.module:factory"`` (text) in its settings instead of ``params``.

Counts are integers, never booleans or floats (``2.7`` is refused, not read as 2). A ``<Seq>`` key
names a folder entry (no ``/``, not ``..``), unique without regard to case; a ``<seed>`` key is a
seed written as :func:`str` writes it (``"3"``, not ``"03"``). Scores are finite: AUC, precision
and overlap in [0, 1], the centre error in [0, 10^10] px. Anything else refuses the whole file,
in one line naming it and the field (:func:`check_manifest`).

A run whose result file is not in the folder (its entry written, its file lost or never
written) is no run: :func:`read_manifest` leaves it out and says so, one line per run
(:attr:`Manifest.unwritten`), so that neither a summary row nor a sequence to score comes
from it.
"""
from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path

from nrmlc.errors import DataError
from nrmlc.workbench.results_layout import (MANIFEST_NAME, check_input_file, is_plain_name, reading,
                                            result_file)

#: The entry of a run that holds its sequence's content key (:attr:`nrmlc.data.Sequence.identity`),
#: which ``nrmlc benchmark`` compares with the sequence's on a rerun.
IDENTITY_FIELD = "sequence_identity"
#: Largest ``benchmark.json`` read (about 400,000 runs).
MAX_MANIFEST_BYTES = 64 << 20
#: Largest speed taken as measured: one frame per nanosecond.
MAX_FPS = 1e9
#: Longest run taken as real (a sparse pack holds at most 10^7 frames).
MAX_FRAMES = 10**9
#: Largest mean centre error (px): boxes beyond 1e9 px are failed frames, not errors.
MAX_CENTER_ERROR = 1e10
#: Scores that are fractions.
FRACTION_SCORES = ("success_auc", "precision_20", "mean_overlap")
#: Scores that are counts of frames.
COUNT_SCORES = ("n_frames", "n_missing")


@dataclass
class Manifest:
    """A checked ``benchmark.json``.

    Attributes
    ----------
    path : Path
    data : dict
        ``settings``, ``primary_seed`` and ``runs``: only the runs whose result file is there.
    unwritten : list of str
        One line per run left out because its result file is not there.
    """

    path: Path
    data: dict
    unwritten: list = field(default_factory=list)


def _count(value, low: int, high: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and low <= value <= high


def _finite(value, low: float, high: float) -> bool:
    return (isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
            and low <= value <= high)


def _refuse_constant(name: str):
    raise ValueError(f"{name} is not a JSON number")


def check_manifest(manifest, path, advice: str = "repair or remove it") -> dict:
    """Refuse a ``benchmark.json`` of the wrong shape (see the module docstring) with one line naming it.

    Parameters
    ----------
    manifest : object
        The parsed JSON.
    path : path
        The file, for messages.
    advice : str
        What to do about it, ending the message.

    Returns
    -------
    dict
        ``manifest``, with ``runs`` added when it was absent.

    Raises
    ------
    DataError
        ``path: not a benchmark manifest (<the field and what is wrong>); <advice>``.
    """
    def fail(what: str):
        raise DataError(f"{path}: not a benchmark manifest ({what}); {advice}")

    if not isinstance(manifest, dict):
        fail(f"a JSON {type(manifest).__name__}, not an object")
    _check_settings(manifest.get("settings"), fail)
    primary = manifest.get("primary_seed")
    if primary is not None and not _count(primary, 0, 2**63 - 1):
        fail(f"'primary_seed' must be a seed or null, got {primary!r}")
    runs = manifest.setdefault("runs", {})
    if not isinstance(runs, dict):
        fail("'runs' is not an object")
    if runs and primary is None:
        fail("runs but no 'primary_seed'")
    seen: dict = {}
    for name, seeds in runs.items():
        if not is_plain_name(name):
            fail(f"runs key {name!r} is not a sequence name")
        if seen.setdefault(name.lower(), name) != name:
            fail(f"runs has both {seen[name.lower()]!r} and {name!r}")
        if not isinstance(seeds, dict):
            fail(f"runs[{name!r}] is not an object")
        for seed, entry in seeds.items():
            _check_run(f"runs[{name!r}][{seed!r}]", seed, entry, fail)
    return manifest


def _check_settings(settings, fail) -> None:
    if not isinstance(settings, dict):
        fail("no 'settings' object")
    if not isinstance(settings.get("params", {}), dict):
        fail("'settings.params' is not an object")
    tracker = settings.get("tracker")  # an imported tracker's package.module:factory (NRMLC's folders have none)
    if tracker is not None and not (isinstance(tracker, str) and tracker.strip() and "\0" not in tracker):
        fail(f"'settings.tracker' must be the tracker's package.module:factory or absent, got {tracker!r}")
    cap = settings.get("max_frames")
    if cap is not None and not _count(cap, 2, MAX_FRAMES):
        fail(f"'settings.max_frames' must be an integer >= 2 or null, got {cap!r}")
    data = settings.get("data")
    if data is not None and not (isinstance(data, str) and data.strip() and "\0" not in data):
        fail(f"'settings.data' must be the data root's path or null, got {data!r}")


def _check_run(where: str, seed, entry, fail) -> None:
    if not (seed.isdigit() and seed.isascii() and str(int(seed)) == seed):
        fail(f"{where}: the key is not a seed")
    if not isinstance(entry, dict):
        fail(f"{where} is not an object")
    frames = entry.get("frames")
    if not _count(frames, 1, MAX_FRAMES):
        fail(f"{where}.frames must be a positive integer (at most {MAX_FRAMES:.0e}), got {frames!r}")
    fps = entry.get("fps")
    if fps is not None and not (_finite(fps, 0, MAX_FPS) and fps > 0):
        fail(f"{where}.fps must be a number in (0, {MAX_FPS:g}] or null, got {fps!r}")
    if IDENTITY_FIELD in entry and not isinstance(entry[IDENTITY_FIELD], str):
        fail(f"{where}.{IDENTITY_FIELD} must be the sequence's content key (text) or absent, "
             f"got {entry[IDENTITY_FIELD]!r}")
    scores = entry.get("scores")
    if scores is None:
        return
    if not isinstance(scores, dict):
        fail(f"{where}.scores must be an object of numbers or null")
    for key, value in scores.items():
        if value is None:
            continue
        if key in COUNT_SCORES:
            ok = _count(value, 0, MAX_FRAMES)
        elif key in FRACTION_SCORES:
            ok = _finite(value, 0.0, 1.0)
        elif key == "mean_center_error":
            ok = _finite(value, 0.0, MAX_CENTER_ERROR)
        else:
            ok = _finite(value, -math.inf, math.inf)
        if not ok:
            fail(f"{where}.scores must be an object of numbers or null; {key} is {value!r}")


def read_manifest(folder, advice: str = "repair or remove it") -> Manifest | None:
    """The checked ``benchmark.json`` of ``folder``, None when there is none.

    Parameters
    ----------
    folder : path
        A ``nrmlc benchmark`` folder (or any folder: None when it holds no manifest).
    advice : str
        Ends the message of a refused manifest (:func:`check_manifest`).

    Returns
    -------
    Manifest or None

    Raises
    ------
    DataError
        A manifest that is not strict JSON or not of the shape of the module docstring; a
        ``benchmark.json`` that is a broken link, a FIFO or a folder; a result file of a run that
        is a broken link, a FIFO or a folder.
    nrmlc.workbench.results_layout.InputTooLarge
        A manifest of more than :data:`MAX_MANIFEST_BYTES`, or memory running out reading it.
    """
    folder = Path(folder)
    path = folder / MANIFEST_NAME
    if not check_input_file(path, "benchmark manifest", MAX_MANIFEST_BYTES):
        return None
    with reading(path, "benchmark manifest"):
        try:
            data = json.loads(path.read_bytes(), parse_constant=_refuse_constant)
        except (OSError, ValueError, RecursionError) as exc:
            raise DataError(f"{path}: not a benchmark manifest ({type(exc).__name__}: {exc}); {advice}") from None
        check_manifest(data, path, advice)
    unwritten = _drop_unwritten(folder, data)
    return Manifest(path, data, unwritten)


def _drop_unwritten(folder: Path, data: dict) -> list[str]:
    """Remove from ``data`` the runs whose result file is not in ``folder``; one line for each."""
    from nrmlc.data.otb import present

    lines = []
    primary = data.get("primary_seed")
    for name in list(data["runs"]):
        seeds = data["runs"][name]
        for seed in list(seeds):
            path = result_file(folder, name, int(seed), primary)
            if not present(path):
                del seeds[seed]
                lines.append(f"{path}: its run (seed {seed}) is in {MANIFEST_NAME} but the file is not there; "
                             f"that run is left out")
        if not seeds:
            del data["runs"][name]
    return lines
