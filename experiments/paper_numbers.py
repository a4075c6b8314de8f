"""The numbers the paper reports, as printed (Tables I and II, Sec. 4.2 / Fig. 4).

Everything here is transcribed from ``nrmlc-paper.tex`` (Tables I and II in ``paper_tables.tsv``);
nothing is computed.
The experiment scripts put these beside what we measure, and fill the cells we
cannot measure (trackers we do not have, sequences whose frames are not given)
with them, marked as the paper's.

Sequence names are the paper's (``Carscale`` is written ``CarScale`` as in
OTB, ``Faceocc1`` as ``FaceOcc1``, ...), matching
:func:`experiments.sequence_sets.paper_name`.
"""
from __future__ import annotations

from pathlib import Path

#: Tracker columns of Tables I and II, in the paper's order ("Ours" is NRMLC).
TRACKERS = ("LSK", "L1", "L1APG", "MTT", "IVT", "MIL", "ASLA", "KCF", "Ours")

#: The paper's peers (every column but ours).
PEERS = TRACKERS[:-1]

#: Rows of Tables I and II, in the paper's order.
SEQUENCES = ("Car4", "CarScale", "David3", "Deer", "FaceOcc2", "Caviar3", "ClifBar",
             "Human7", "FaceOcc1", "Skating1", "Caviar1", "Singer1")


def _tables(path: Path) -> dict:
    """{table: ({sequence: {tracker: value}}, {tracker: value} of its "avg." row)} from
    :data:`TABLES_FILE`: a row per (table, sequence) with a value per tracker, in :data:`TRACKERS`
    order, as the paper prints them."""
    tables: dict = {}
    rows = [line.split("\t") for line in path.read_text().splitlines() if line and not line.startswith("#")]
    if tuple(rows[0][2:]) != TRACKERS:  # a transcription slip, caught at import
        raise ValueError(f"{path}: columns {rows[0][2:]} are not the paper's trackers {TRACKERS}")
    for table, sequence, *values in rows[1:]:
        tables.setdefault(table, {})[sequence] = dict(zip(TRACKERS, map(float, values)))
    return {table: (rows, rows.pop("avg.")) for table, rows in tables.items()}


#: Tables I and II, transcribed.
TABLES_FILE = Path(__file__).with_name("paper_tables.tsv")
_TABLES = _tables(TABLES_FILE)
#: Table I: centre location error (pixels) per sequence and tracker, and its "avg." row as printed.
CLE, CLE_AVERAGE = _TABLES["CLE"]
#: Table II: mean overlap rate (IoU) per sequence and tracker, and its "avg." row as printed.
OVERLAP, OVERLAP_AVERAGE = _TABLES["overlap"]

#: Table II, "fps." row (MATLAB on an Intel Xeon E5506 2.13 GHz; KCF is C++/MATLAB).
FPS = dict(zip(TRACKERS, [6.57, 0.28, 4.41, 1.02, 16.41, 0.86, 0.95, 89.8, 1.28]))

#: Fig. 4 / Sec. 4.2: the lambda values of the sweep (beta = 0.1).
FIG4_LAMBDAS = (0.0, 0.01, 0.1, 0.5, 0.8, 1.0, 5.0, 10.0)
#: Fig. 4: beta of the blue line and of the green dashed line.
FIG4_BETA = 0.1
#: Fig. 4: average overlap without regularisation (lambda = beta = 0, red dashed line).
FIG4_NO_REGULARISATION_OVERLAP = 0.3175
#: Fig. 4: the lambda at which the average overlap peaks (its value is Table II's avg., 0.70).
FIG4_BEST_LAMBDA = 1.0

#: The paper's defaults (Sec. 4, Setup), for the report.
SETUP = {"patch": "32x32", "dictionary_sizes": (5, 8, 10), "n_iterations": 3, "lam": 1.0, "beta": 0.1}


def average(table: dict, sequences, tracker: str) -> float:
    """Mean of ``table[s][tracker]`` over ``sequences`` (paper names).

    Used to compare our average over the sequences we have with the paper's
    average over the same subset (the printed avg. row covers all 12).
    """
    values = [table[s][tracker] for s in sequences]
    return sum(values) / len(values) if values else float("nan")
