"""What every experiment script shares: where the data is, which seeds, the run cache.

Each script has ``main(context=None)``; called alone it builds a context from
the command line (``--data``, ``--seeds``, ...), so
``python -m experiments.fig4_lambda_sweep --data ../shared/data/sequences``
works as well as ``make figures``.
"""
from __future__ import annotations

import argparse
import os
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # never a window: figures go to files

from nrmlc.config import data_root_from_env  # noqa: E402
from nrmlc.runner import DEFAULT_CACHE, RunCache, RunSpec  # noqa: E402
from nrmlc.tracker.params import TrackerParams  # noqa: E402

REPO_ROOT = Path(__file__).resolve().parent.parent

#: The paper's 12 sequences (Tables I and II) and the names they have in the data we
#: can get: Occlusion1/Occlusion2 are the sparse-tracker versions of FaceOcc1/FaceOcc2.
PAPER_SEQUENCES = ("Car4", "CarScale", "David3", "Deer", "FaceOcc2", "Caviar3", "ClifBar",
                   "Human7", "FaceOcc1", "Skating1", "Caviar1", "Singer1")
PAPER_NAME_OF = {"Occlusion1": "FaceOcc1", "Occlusion2": "FaceOcc2", "Carscale": "CarScale",
                 "Cliffbar": "ClifBar"}


def paper_name(sequence_name: str) -> str | None:
    """The paper's name for a sequence of ours, or None if it is not one of its 12."""
    name = PAPER_NAME_OF.get(sequence_name, sequence_name)
    lowered = {s.lower(): s for s in PAPER_SEQUENCES}
    return lowered.get(name.lower())


@dataclass
class Context:
    """Settings of one ``make figures`` run.

    Attributes
    ----------
    data_root : Path or None
        Folder of real sequences; None means the synthetic suite.
    figures_dir : Path
        Where PNG/CSV/JSON outputs go.
    seeds : tuple of int
        Seeds for the main tables (mean of these).
    sweep_seeds : tuple of int
        Seeds for sweeps and ablations (fewer, to keep the whole set under an hour).
    jobs : int or None
        Worker processes (default: all cores).
    executor : concurrent.futures.Executor or None
        Where runs execute; None means a local process pool.
    cache : RunCache
    """

    data_root: Path | None = None
    figures_dir: Path = REPO_ROOT / "figures"
    seeds: tuple = (0, 1, 2, 3, 4)
    sweep_seeds: tuple = (0, 1, 2)
    jobs: int | None = None
    executor: object = None
    cache: RunCache = field(default_factory=lambda: RunCache(REPO_ROOT / DEFAULT_CACHE))
    _sequences: list | None = None

    @property
    def is_synthetic(self) -> bool:
        return self.data_root is None

    @property
    def data_label(self) -> str:
        return "synthetic suite" if self.is_synthetic else str(self.data_root)

    def sequences(self) -> list:
        """Every sequence given (all targets of multi-target folders), sorted by name."""
        if self._sequences is None:
            if self.is_synthetic:
                from nrmlc.data import synthetic_suite

                self._sequences = synthetic_suite()
            else:
                from nrmlc.data import list_sequences

                self._sequences = list_sequences(self.data_root)
        return self._sequences

    def paper_sequences(self) -> list:
        """The given sequences that are among the paper's 12 (all of them when synthetic)."""
        if self.is_synthetic:
            return self.sequences()
        return [s for s in self.sequences() if paper_name(s.name) is not None]

    def sequence(self, *names: str):
        """The first given sequence whose name matches one of ``names`` (case-insensitive), else None."""
        by_name = {s.name.lower(): s for s in self.sequences()}
        for name in names:
            if name.lower() in by_name:
                return by_name[name.lower()]
        return None

    def run(self, specs: list[RunSpec]) -> list:
        """Results of ``specs`` (computed if not cached), in order."""
        return self.cache.run(specs, executor=self.executor, jobs=self.jobs)

    def output(self, stem: str, suffix: str) -> Path:
        self.figures_dir.mkdir(parents=True, exist_ok=True)
        return self.figures_dir / f"{stem}{suffix}"


def specs_for(sequences, params: TrackerParams, seeds, label: str = "") -> list[RunSpec]:
    """One RunSpec per (sequence, seed)."""
    return [RunSpec(sequence=s, params=params, seed=int(seed), label=label) for s in sequences for seed in seeds]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", default=None, help="data root of real sequences (default: $NRMLC_DATA, else synthetic)")
    parser.add_argument("--seeds", type=int, default=None, help="number of seeds for the main tables (default 5)")
    parser.add_argument("--sweep-seeds", type=int, default=None, help="number of seeds for sweeps/ablations (default 3)")
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    parser.add_argument("--figures", default=None, help="output folder (default: figures/)")


def context_from_args(argv=None, description: str = "") -> Context:
    parser = argparse.ArgumentParser(description=description)
    add_arguments(parser)
    args = parser.parse_args(argv)
    return context_from_namespace(args)


def context_from_namespace(args) -> Context:
    from nrmlc.errors import DataError

    data = args.data or data_root_from_env()
    context = Context()
    if data:
        context.data_root = Path(data).resolve()
        if not context.data_root.is_dir():
            raise DataError(f"{data}: data root not found")
    if args.seeds:
        context.seeds = tuple(range(args.seeds))
    if args.sweep_seeds:
        context.sweep_seeds = tuple(range(args.sweep_seeds))
    if args.jobs:
        context.jobs = args.jobs
    if args.figures:
        context.figures_dir = Path(args.figures).resolve()
    return context
