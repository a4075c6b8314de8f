"""The sets of real sequences, defined once (the development protocol).

- :data:`DEVELOPMENT_SEQUENCES`: every default is chosen on these (and on the
  synthetic suite), one parameter set for all sequences: the 12 targets of
  ``../shared/data/sequences`` (:data:`FIRST_DEVELOPMENT`) and the 24 that
  ``../shared/tools/lay_sequences.py`` lays out (:data:`MORE_DEVELOPMENT`).
- :data:`DEVELOPMENT_A` and :data:`DEVELOPMENT_B`: the choosing and the confirming
  half of them, split once before any screening on the larger set, by
  :mod:`experiments.development.development_split` (which says how). A change is adopted only by
  :data:`ADOPTION_RULE`.
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

#: The first 12 development targets (``../shared/data/sequences``).
FIRST_DEVELOPMENT = ("Basketball", "Car1", "Car11", "Couple", "Crossing", "Dog", "Football1", "Girl",
                     "Jogging-1", "Jogging-2", "MotorRolling", "Toy")

#: The 24 more that ``../shared/tools/lay_sequences.py`` lays out (23 OTB-100 videos).
MORE_DEVELOPMENT = ("Bird1", "BlurBody", "BlurCar2", "BlurFace", "BlurOwl", "Boy", "Diving", "DragonBaby",
                    "Fish", "Football", "Freeman1", "Ironman", "KiteSurf", "Lemming", "Liquor", "Man", "Matrix",
                    "Singer2", "Skating2-1", "Skating2-2", "Skiing", "Subway", "Suv", "Walking2")

#: Development sequences: choose here, report on :data:`PAPER_SEQUENCES`.
DEVELOPMENT_SEQUENCES = FIRST_DEVELOPMENT + MORE_DEVELOPMENT

#: The choosing half (screen here) and the confirming half (a change must also gain here), drawn
#: once on 2026-12-01 before any screening on the 36 by ``python -m experiments.development.development_split
#: --peers PEERS.json --attributes otb_attributes --draws 20000 --seed 0``: the three OpenCV peers'
#: mean overlap 0.354 (A) and 0.364 (B); attribute counts within one of each other (IV 6 / 5,
#: SV 11 / 12, OCC 9 / 10, FM 9 / 8, ...); 6 of the first 12 targets in each.
DEVELOPMENT_A = ("Bird1", "BlurFace", "Boy", "Car1", "Crossing", "Dog", "DragonBaby", "Fish", "Football",
                 "Football1", "Girl", "KiteSurf", "Lemming", "MotorRolling", "Skating2-1", "Skating2-2", "Skiing",
                 "Subway")
DEVELOPMENT_B = ("Basketball", "BlurBody", "BlurCar2", "BlurOwl", "Car11", "Couple", "Diving", "Freeman1", "Ironman",
                 "Jogging-1", "Jogging-2", "Liquor", "Man", "Matrix", "Singer2", "Suv", "Toy", "Walking2")

#: The fewest seeds a paired gain is judged on.
MIN_SEEDS = 5
#: The least paired gain on half A worth a change's code and its cost in speed.
MIN_GAIN = 0.01

#: The rule every default is adopted by (:func:`experiments.development.devset.adopted` applies it).
ADOPTION_RULE = (f"a change is adopted only when its paired gain over at least {MIN_SEEDS} fresh seeds is at least "
                 f"{MIN_GAIN} and beyond its standard error on half A, is positive on half B, and does not lose on "
                 "the synthetic suite beyond its standard error")

#: Our name -> the paper's name, where they differ.
PAPER_NAME_OF = {"Occlusion1": "FaceOcc1", "Occlusion2": "FaceOcc2", "Carscale": "CarScale",
                 "Cliffbar": "ClifBar"}


def paper_name(sequence_name: str) -> str | None:
    """The paper's name for a sequence of ours, or None if it is not one of the paper's 12."""
    from experiments.paper_numbers import SEQUENCES

    name = PAPER_NAME_OF.get(sequence_name, sequence_name)
    return {s.lower(): s for s in SEQUENCES}.get(name.lower())
