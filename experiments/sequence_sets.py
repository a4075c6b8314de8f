"""The two sets of real sequences, defined once (issue 11's development protocol).

- :data:`DEVELOPMENT_SEQUENCES`: every default is chosen on these (and on the
  synthetic suite), one parameter set for all sequences.
- :data:`PAPER_SEQUENCES`: the paper's sequences we have; reported, never
  chosen on. In the order of the paper's Tables I and II.

Names are as :func:`nrmlc.data.list_sequences` gives them for
``../shared/data/sequences`` (a two-target folder gives ``Name-1``, ``Name-2``).
The paper's own names for ours are in :data:`PAPER_NAME_OF`; the paper's rows
and numbers are in :mod:`experiments.paper_numbers`.
"""
from __future__ import annotations

#: The paper's sequences in the data, in the order of its Tables I and II
#: (Occlusion1/Occlusion2 are the sparse-tracker versions of FaceOcc1/FaceOcc2).
PAPER_SEQUENCES = ("Car4", "CarScale", "David3", "Deer", "Occlusion2", "ClifBar", "Occlusion1",
                   "Skating1", "Caviar1")

#: Development sequences: choose here, report on :data:`PAPER_SEQUENCES`.
DEVELOPMENT_SEQUENCES = ("Basketball", "Car1", "Car11", "Couple", "Crossing", "Dog", "Football1", "Girl",
                         "Jogging-1", "Jogging-2", "MotorRolling", "Toy")

#: Our name -> the paper's name, where they differ.
PAPER_NAME_OF = {"Occlusion1": "FaceOcc1", "Occlusion2": "FaceOcc2", "Carscale": "CarScale",
                 "Cliffbar": "ClifBar"}


def paper_name(sequence_name: str) -> str | None:
    """The paper's name for a sequence of ours, or None if it is not one of the paper's 12."""
    from experiments.paper_numbers import SEQUENCES

    name = PAPER_NAME_OF.get(sequence_name, sequence_name)
    return {s.lower(): s for s in SEQUENCES}.get(name.lower())
