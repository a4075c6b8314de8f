"""The experiment grid: where the data is, which sequences and seeds, the run cache,
and the one shape every experiment script has.

Every script in :data:`experiments.run_all.SCRIPTS` defines

- ``STEM``: the stem of its outputs;
- ``runs(context)``: every job it reads (tracking runs, live peer runs of
  OpenCV and the lineage, recorded internals), so that ``run_all`` computes the whole grid in one pool;
- ``collect(context) -> data``: the numbers, from the cached jobs;
- ``plot(data, path)``: the figure ``<STEM>.png``;
- ``report(context, data) -> section``: writes ``<STEM>.csv/.json`` and returns
  its section of ``REPORT.md`` (``title``, ``figures``, ``markdown``);
- ``main(argv=None)`` (``main = script_entry(__name__)``), so that
  ``python -m experiments.paper.fig4_lambda_sweep --data ../shared/data/sequences``
  works alone, with the options of ``make figures``.

:func:`run_script` is what ``run_all`` does with each of them.
"""
from __future__ import annotations

import argparse
import functools
import sys
from dataclasses import dataclass, field
from pathlib import Path

from experiments.sequence_sets import DEVELOPMENT_SEQUENCES, PAPER_SEQUENCES
from nrmlc.config import data_root_from_env
from nrmlc.io import write_json
from nrmlc.workbench.jobs import RunSpec, frames_tracked
from nrmlc.workbench.run_cache import DEFAULT_CACHE, RunCache
from nrmlc.tracker.params import PRESETS, TrackerParams

REPO_ROOT = Path(__file__).resolve().parent.parent

#: Where results go unless ``--out`` says otherwise: git-ignored, so that no run
#: overwrites the committed real-data results in ``figures/`` by accident.
DEFAULT_OUT = REPO_ROOT / "out" / "figures"


@dataclass
class Context:
    """Settings of one ``make figures`` run.

    Attributes
    ----------
    data_root : Path or None
        Folder of real sequences; None means the synthetic suite.
    figures_dir : Path
        Where PNG/CSV/JSON outputs go (default ``out/figures``, git-ignored).
    seeds : tuple of int
        Seeds for the main tables (mean of these).
    sweep_seeds : tuple of int
        Seeds of the lambda sweep (Fig. 4) and the per-sequence motion runs.
    ablation_seeds : tuple of int
        Seeds of the ablations and the re-centring runs (fewer: many
        configurations, all nine sequences).
    jobs : int or None
        Worker processes (default: all cores).
    executor : concurrent.futures.Executor or None
        Where runs execute; None means a local process pool.
    cache : RunCache
    max_frames : int or None
        Track only the first frames of every sequence (development; None: all).
    base_params : TrackerParams
        Parameters every grid starts from (the 'default' preset unless a
        ``--param`` changed them; the report says so).
    param_changes : dict
        The ``--param`` changes (also applied to :meth:`paper_params`).
    n_synthetic : int
        Sequences of the synthetic suite (when no data root is given).
    peer_root : Path or None
        Folder of the shipped peer results (default: ``<data_root>/../peer_results``).
    only_sequences : tuple of str or None
        Use only the given sequences with these names (``--sequences``).
    """

    data_root: Path | None = None
    figures_dir: Path = DEFAULT_OUT
    seeds: tuple = (0, 1, 2, 3, 4)
    sweep_seeds: tuple = (0, 1)
    ablation_seeds: tuple = (0,)
    jobs: int | None = None
    executor: object = None
    cache: RunCache = field(default_factory=lambda: RunCache(REPO_ROOT / DEFAULT_CACHE))
    max_frames: int | None = None
    base_params: TrackerParams = field(default_factory=TrackerParams)
    param_changes: dict = field(default_factory=dict)
    n_synthetic: int = 3
    peer_root: Path | None = None
    only_sequences: tuple | None = None
    _sequences: list | None = None

    @property
    def is_synthetic(self) -> bool:
        return self.data_root is None

    @property
    def data_label(self) -> str:
        return "synthetic suite" if self.is_synthetic else str(self.data_root)

    def sequences(self) -> list:
        """Every sequence given (all targets of multi-target folders), sorted by name,
        or only those named by :attr:`only_sequences`."""
        if self._sequences is None:
            if self.is_synthetic:
                from nrmlc.data import synthetic_suite

                sequences = synthetic_suite(n_sequences=self.n_synthetic)
            elif self.only_sequences is not None:
                from nrmlc.workbench.results_layout import select_sequences

                # Only the named folders are opened: the others' warnings are not this run's.
                sequences = select_sequences(self.data_root, list(self.only_sequences))
            else:
                from nrmlc.data import list_sequences

                sequences = list_sequences(self.data_root)
            if self.only_sequences is not None and self.is_synthetic:
                from nrmlc.errors import DataError

                by_name = {s.name.lower(): s for s in sequences}
                unknown = [n for n in self.only_sequences if n.lower() not in by_name]
                if unknown:
                    raise DataError(f"--sequences: {', '.join(unknown)} not in {self.data_label} "
                                    f"(given: {', '.join(s.name for s in sequences)})")
                wanted = {n.lower() for n in self.only_sequences}
                sequences = [s for s in sequences if s.name.lower() in wanted]
            self._sequences = sequences
        return self._sequences

    def paper_sequences(self) -> list:
        """The given sequences among the paper's, in its table order (all of them when synthetic)."""
        if self.is_synthetic:
            return self.sequences()
        return self.ordered_sequences()[0]

    def development_sequences(self) -> list:
        """The given development sequences (:data:`~experiments.sequence_sets.DEVELOPMENT_SEQUENCES`)."""
        if self.is_synthetic:
            return []
        by_name = {s.name: s for s in self.sequences()}
        return [by_name[n] for n in DEVELOPMENT_SEQUENCES if n in by_name]

    def ordered_sequences(self) -> tuple[list, list]:
        """(the paper's sequences in its table order, the other given sequences by name).

        Unlike :meth:`paper_sequences`, synthetic sequences count as *others*
        here: no paper number belongs to them.
        """
        order = {name: i for i, name in enumerate(PAPER_SEQUENCES)}
        paper = sorted((s for s in self.sequences() if s.name in order), key=lambda s: order[s.name])
        others = [s for s in self.sequences() if s.name not in order]
        return paper, others

    def paper_params(self) -> TrackerParams:
        """The 'paper' preset (the paper as printed) with the ``--param`` changes: what the
        experiments about the paper's own claims (Theorem 1, Figs. 1 and 2, statistics,
        occlusion) run."""
        return TrackerParams.paper(**self.param_changes)

    def n_frames(self, sequence) -> int:
        """Frames tracked in ``sequence`` under :attr:`max_frames`."""
        return frames_tracked(sequence, self.max_frames)

    def specs(self, sequences, params: TrackerParams | None = None, seeds=None, label: str = "") -> list[RunSpec]:
        """One RunSpec per (sequence, seed), honouring :attr:`max_frames`.

        Parameters
        ----------
        sequences : list of Sequence
        params : TrackerParams, optional
            Default :attr:`base_params`.
        seeds : iterable of int, optional
            Default :attr:`seeds`.
        label : str
        """
        params = self.base_params if params is None else params
        seeds = self.seeds if seeds is None else seeds
        return specs_for(sequences, params, seeds, label=label, n_frames=self.max_frames)

    def shipped_peer_root(self) -> Path | None:
        """Where the shipped per-frame peer results are, or None (synthetic, or not there)."""
        if self.peer_root is not None:
            return self.peer_root if self.peer_root.is_dir() else None
        if self.data_root is None:
            return None
        root = self.data_root.parent / "peer_results"
        return root if root.is_dir() else None

    def describe_grid(self) -> str:
        """One line naming the seeds and the frame cap (for the report's sections)."""
        cap = "" if self.max_frames is None else f", first {self.max_frames} frames only"
        return (f"seeds {list(self.seeds)}, sweep seeds {list(self.sweep_seeds)}, "
                f"ablation seeds {list(self.ablation_seeds)}{cap}")

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

    def evaluate(self, specs: list[RunSpec]) -> list:
        """The :func:`score` of each run of ``specs`` (computed if not cached), in order."""
        return [score(result.boxes, spec.sequence) for spec, result in zip(specs, self.run(specs))]

    def output(self, stem: str, suffix: str) -> Path:
        self.figures_dir.mkdir(parents=True, exist_ok=True)
        return self.figures_dir / f"{stem}{suffix}"


def specs_for(sequences, params: TrackerParams, seeds, label: str = "", n_frames: int | None = None) -> list[RunSpec]:
    """One RunSpec per (sequence, seed)."""
    return [RunSpec(sequence=s, params=params, seed=int(seed), n_frames=n_frames, label=label)
            for s in sequences for seed in seeds]


def score(boxes, sequence, n_frames: int | None = None):
    """Evaluate ``boxes`` on the first frames of ``sequence`` (OTB one-pass, frame 0 skipped).

    Parameters
    ----------
    boxes : (m, 4) array
        1-based OTB boxes from frame 0.
    sequence : Sequence
    n_frames : int, optional
        Frames to score (default ``len(boxes)``): with a frame cap the ground
        truth is cut to the frames tracked, so untracked frames are not failures.

    Returns
    -------
    nrmlc.workbench.metrics.Evaluation
    """
    import numpy as np

    from nrmlc.workbench.metrics import evaluate

    n = frames_tracked(sequence, len(boxes) if n_frames is None else n_frames)
    return evaluate(np.asarray(boxes, dtype=np.float64)[:n], sequence.groundtruth[:n])


def params_differences(params: TrackerParams, reference: TrackerParams | None = None) -> dict:
    """Fields of ``params`` that differ from ``reference`` (default: ``TrackerParams()``, the chosen defaults)."""
    reference = TrackerParams() if reference is None else reference
    mine, theirs = params.as_dict(), reference.as_dict()
    return {k: v for k, v in mine.items() if theirs.get(k) != v}


def describe_params(params: TrackerParams) -> str:
    """Which preset ``params`` are (the closest one) and what differs from it."""
    name, changed = min(((name, params_differences(params, TrackerParams.preset(name))) for name in PRESETS),
                        key=lambda pair: len(pair[1]))
    text = f"the '{name}' preset" + (" (the paper as printed)" if name == "paper" else "")
    if changed:
        text += " except " + ", ".join(f"{k} = {v}" for k, v in sorted(changed.items()))
    return text



def section(title: str, stem: str, lines: list[str]) -> dict:
    """A script's section of ``REPORT.md``: its title, its figure ``<stem>.png`` and its markdown lines."""
    return {"title": title, "figures": [f"{stem}.png"], "markdown": "\n".join(lines)}

def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options every experiment takes (``make figures`` passes them through)."""
    parser.add_argument("--data", default=None, metavar="DIR",
                        help="data root of real sequences (default: $NRMLC_DATA, else the synthetic suite)")
    parser.add_argument("--out", "--figures", dest="out", default=None, metavar="DIR",
                        help="output folder (default: out/figures, git-ignored; the committed real-data "
                             "results are written with --out figures)")
    parser.add_argument("--sequences", default=None, metavar="NAME[,NAME]",
                        help="use only these sequences (e.g. Car4,Caviar1)")
    parser.add_argument("--seeds", type=int, default=None, metavar="N",
                        help="seeds of Tables I/II and Fig. 3 (default 5)")
    parser.add_argument("--sweep-seeds", type=int, default=None, metavar="N",
                        help="seeds of the lambda sweep (Fig. 4) and the per-sequence motion runs (default 2)")
    parser.add_argument("--ablation-seeds", type=int, default=None, metavar="N",
                        help="seeds of the ablations and the re-centring runs (default 1)")
    parser.add_argument("--jobs", type=int, default=None, metavar="J", help="worker processes (default: all cores)")
    parser.add_argument("--max-frames", type=int, default=None, metavar="N",
                        help="development: track only the first N frames of every sequence (tables then say "
                             "so beside every full-sequence paper number)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="development: change a tracker parameter of every run (repeatable)")
    parser.add_argument("--synthetic-sequences", type=int, default=None, metavar="N",
                        help="sequences in the synthetic suite (default 3; only without --data)")
    parser.add_argument("--cache", default=None, metavar="DIR", help="run cache folder (default: .cache/runs)")
    parser.add_argument("--peers", default=None, metavar="DIR",
                        help="folder of shipped peer results (default: <data>/../peer_results)")


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
    if getattr(args, "ablation_seeds", None):
        context.ablation_seeds = tuple(range(args.ablation_seeds))
    if args.jobs:
        context.jobs = args.jobs
    if getattr(args, "out", None):
        context.figures_dir = Path(args.out).resolve()
    if getattr(args, "sequences", None):
        context.only_sequences = tuple(n.strip() for n in args.sequences.split(",") if n.strip())
    if getattr(args, "max_frames", None):
        context.max_frames = int(args.max_frames)
    if getattr(args, "param", None):
        from nrmlc.tracker.params import parse_param_assignment

        changes = dict(parse_param_assignment(text) for text in args.param)
        context.base_params = context.base_params.replace(**changes)
        context.param_changes = changes
    if getattr(args, "synthetic_sequences", None):
        context.n_synthetic = int(args.synthetic_sequences)
    if getattr(args, "cache", None):
        context.cache = RunCache(Path(args.cache).resolve())
    if getattr(args, "peers", None):
        context.peer_root = Path(args.peers).resolve()
        if not context.peer_root.is_dir():
            raise DataError(f"--peers {args.peers}: folder not found")
    return context




def run_script(module, context) -> dict:
    """What ``run_all`` does with every script: collect, plot, write the numbers; returns
    the script's section of the report.

    A script whose ``applies(context)`` returns a reason (a string) instead of None has
    nothing to show on this data: no figure is drawn and its section says why.
    """
    reason = module.applies(context) if hasattr(module, "applies") else None
    if reason is not None:
        return {"title": module.TITLE, "figures": [], "markdown": f"Not drawn on this data: {reason}"}
    data = module.collect(context)
    module.plot(data, context.output(module.STEM, ".png"))
    return module.report(context, data)


def json_report(stem: str):
    """``report`` of a script whose ``collect`` returns ``{"result", "section", ...}``: it writes
    ``result`` as ``<stem>.json`` and returns ``section``."""
    def report(context, data: dict) -> dict:
        write_json(context.output(stem, ".json"), data["result"])
        return data["section"]

    return report


def script_main(name: str, argv=None) -> int:
    """``main`` of a script run alone: options as ``make figures``, its jobs computed in
    one pool, its outputs written, its report section printed."""
    from nrmlc.errors import NrmlcError

    module = sys.modules[name]
    name = getattr(module.__spec__, "name", None) or module.__name__  # not "__main__" under python -m
    parser = argparse.ArgumentParser(prog=f"python -m {name}", description=module.__doc__.splitlines()[0])
    add_arguments(parser)
    try:
        context = context_from_namespace(parser.parse_args(argv))
        context.cache.ensure(list(module.runs(context)), executor=context.executor, jobs=context.jobs)
    except NrmlcError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(run_script(module, context)["markdown"])
    return 0


def script_entry(name: str):
    """A script's ``main`` (``main = script_entry(__name__)``, its last line): :func:`script_main`
    for that script; run at once, its status the exit status, when the script is ``__main__``."""
    main = functools.partial(script_main, name)
    if name == "__main__":
        sys.exit(main())
    return main
