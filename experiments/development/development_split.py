"""How the development targets were split into a choosing half A and a confirming half B.

Run once, before any screening on the larger set; its output is committed, literally,
as :data:`experiments.sequence_sets.DEVELOPMENT_A` and ``DEVELOPMENT_B`` (so a later
change of this file, of OpenCV or of the data never moves a target from one half to the
other). What it balances, with nothing of NRMLC's in it:

- **difficulty**: each target's mean overlap under the three live OpenCV peers (MIL,
  KCF as published, CSRT; :mod:`experiments.peers`), an NRMLC-independent measure;
- **variety**: the OTB benchmark's 11 attribute flags of each target (illumination
  and scale variation, occlusion, ...; Car11, not an OTB-100 sequence, has none);
- **origin**: the 12 first development targets go 6 to each half, so the history
  measured on them stays comparable;
- **one video, one half**: the two targets of Jogging and of Skating2 share their
  frames, so each pair stays together (a half must not confirm on frames it chose on).

Among ``--draws`` random splits obeying the last two (seeded), it keeps the one with the
smallest cost: the difference of the halves' mean difficulty in units of its spread,
plus the attribute counts' differences over the number of targets.

``python -m experiments.development.development_split --peers PEERS.json --attributes DIR``, where
``PEERS.json`` maps each OpenCV tracker to ``{target: mean overlap}`` (what
``experiments.development.devset --json`` writes under ``columns``).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from nrmlc.workbench.attributes import ATTRIBUTES as OTB_ATTRIBUTES
from nrmlc.workbench.attributes import read_attributes as read_attribute_sets

#: The first 12 development targets (those of ``../shared/data/sequences``).
FIRST_TARGETS = ("Basketball", "Car1", "Car11", "Couple", "Crossing", "Dog", "Football1", "Girl",
                 "Jogging-1", "Jogging-2", "MotorRolling", "Toy")

#: Targets that share a video.
SAME_VIDEO = (("Jogging-1", "Jogging-2"), ("Skating2-1", "Skating2-2"))

#: The OTB toolkit's attribute codes, in the order of its flag files.
ATTRIBUTES = tuple(code for code, _ in OTB_ATTRIBUTES)


def read_attributes(folder: Path, targets) -> np.ndarray:
    """(n_targets, 11) 0/1 flags (:func:`nrmlc.workbench.attributes.read_attributes`); a target without a
    file (Car11, not an OTB-100 sequence) gets zeros."""
    found, _ = read_attribute_sets(folder, list(targets))
    return np.array([[code in found.get(t, ()) for code in ATTRIBUTES] for t in targets], dtype=np.float64)


def split_cost(in_a: np.ndarray, difficulty: np.ndarray, flags: np.ndarray) -> float:
    """How unlike the halves are: mean difficulty apart (in spreads) + attribute counts apart."""
    gap = abs(difficulty[in_a].mean() - difficulty[~in_a].mean()) / difficulty.std()
    counts = np.abs(flags[in_a].sum(axis=0) - flags[~in_a].sum(axis=0)).sum() / len(difficulty)
    return float(gap + counts)


def balanced_split(targets, difficulty, flags, draws: int = 20000, seed: int = 0) -> tuple[tuple, tuple]:
    """The most balanced of ``draws`` random splits that keep videos together and the
    first targets 6 / 6.

    Parameters
    ----------
    targets : sequence of str, length n
    difficulty : (n,) float
    flags : (n, 11) float

    Returns
    -------
    (half A, half B) : tuples of target names, each in the order of ``targets``
    """
    targets = list(targets)
    index = {t: i for i, t in enumerate(targets)}
    units = [tuple(pair) for pair in SAME_VIDEO if all(t in index for t in pair)]
    grouped = {t for unit in units for t in unit}
    units += [(t,) for t in targets if t not in grouped]
    first = [u for u in units if u[0] in FIRST_TARGETS]
    later = [u for u in units if u[0] not in FIRST_TARGETS]
    difficulty, flags = np.asarray(difficulty, float), np.asarray(flags, float)
    rng = np.random.default_rng(seed)
    best, best_cost = None, np.inf
    for _ in range(draws):
        in_a = np.zeros(len(targets), bool)
        for group, size in ((first, len(FIRST_TARGETS) // 2), (later, (len(targets) - len(FIRST_TARGETS)) // 2)):
            taken = 0
            for unit in rng.permutation(len(group)):
                if taken + len(group[unit]) <= size:
                    in_a[[index[t] for t in group[unit]]] = True
                    taken += len(group[unit])
        if in_a.sum() * 2 != len(targets):
            continue
        cost = split_cost(in_a, difficulty, flags)
        if cost < best_cost:
            best, best_cost = in_a, cost
    return (tuple(t for t, a in zip(targets, best) if a), tuple(t for t, a in zip(targets, best) if not a))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--peers", required=True, help="JSON: {tracker: {target: mean overlap}}")
    parser.add_argument("--attributes", required=True, help="folder of the OTB benchmark's attribute files")
    parser.add_argument("--draws", type=int, default=20000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    peers = json.loads(Path(args.peers).read_text())
    targets = sorted(next(iter(peers.values())))
    difficulty = np.array([np.mean([peers[t][name] for t in peers]) for name in targets])
    flags = read_attributes(Path(args.attributes), targets)
    half_a, half_b = balanced_split(targets, difficulty, flags, args.draws, args.seed)
    for label, half in (("A", half_a), ("B", half_b)):
        in_half = np.isin(targets, half)
        counts = dict(zip(ATTRIBUTES, flags[in_half].sum(axis=0).astype(int).tolist()))
        print(f"{label} ({len(half)}): peers' mean overlap {difficulty[in_half].mean():.3f}; {counts}")
        print(f"  {half}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
