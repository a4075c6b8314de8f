"""What every experiment script shares: where the data is, which seeds, the run cache.

Each script has ``main(context=None)``; called alone it builds a context from
the command line (``--data``, ``--seeds``, ...), so
``python -m experiments.fig4_lambda_sweep --data ../shared/data/sequences``
works as well as ``make figures``.
"""
from __future__ import annotations

import argparse
import math
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
    max_frames : int or None
        Track only the first frames of every sequence (development; None: all).
    base_params : TrackerParams
        Parameters every grid starts from (the paper's defaults unless a
        ``--param`` changed them; the report says so).
    n_synthetic : int
        Sequences of the synthetic suite (when no data root is given).
    peer_root : Path or None
        Folder of the shipped peer results (default: ``<data_root>/../peer_results``).
    """

    data_root: Path | None = None
    figures_dir: Path = REPO_ROOT / "figures"
    seeds: tuple = (0, 1, 2, 3, 4)
    sweep_seeds: tuple = (0, 1, 2)
    jobs: int | None = None
    executor: object = None
    cache: RunCache = field(default_factory=lambda: RunCache(REPO_ROOT / DEFAULT_CACHE))
    max_frames: int | None = None
    base_params: TrackerParams = field(default_factory=TrackerParams)
    n_synthetic: int = 3
    peer_root: Path | None = None
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

                self._sequences = synthetic_suite(n_sequences=self.n_synthetic)
            else:
                from nrmlc.data import list_sequences

                self._sequences = list_sequences(self.data_root)
        return self._sequences

    def paper_sequences(self) -> list:
        """The given sequences that are among the paper's 12 (all of them when synthetic)."""
        if self.is_synthetic:
            return self.sequences()
        return [s for s in self.sequences() if paper_name(s.name) is not None]

    def ordered_sequences(self) -> tuple[list, list]:
        """(the paper's sequences in its table order, the other given sequences by name).

        Unlike :meth:`paper_sequences`, synthetic sequences count as *others*
        here: no paper number belongs to them.
        """
        order = {name: i for i, name in enumerate(PAPER_SEQUENCES)}
        paper = [s for s in self.sequences() if paper_name(s.name) is not None]
        paper.sort(key=lambda s: order[paper_name(s.name)])
        others = [s for s in self.sequences() if paper_name(s.name) is None]
        return paper, others

    def n_frames(self, sequence) -> int:
        """Frames tracked in ``sequence`` under :attr:`max_frames`."""
        n = len(sequence)
        return n if self.max_frames is None else max(1, min(n, int(self.max_frames)))

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
        return f"seeds {list(self.seeds)}, sweep seeds {list(self.sweep_seeds)}{cap}"

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


def spec_frames(spec: RunSpec) -> int:
    """Frames a run tracks."""
    n = len(spec.sequence)
    return n if spec.n_frames is None else max(1, min(n, int(spec.n_frames)))


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
    nrmlc.metrics.Evaluation
    """
    import numpy as np

    from nrmlc.metrics import evaluate

    n = len(boxes) if n_frames is None else int(n_frames)
    n = min(n, len(sequence))
    return evaluate(np.asarray(boxes, dtype=np.float64)[:n], sequence.groundtruth[:n])


def mean_std(values) -> tuple[float, float]:
    """Mean and (population) standard deviation of the finite values.

    (nan, nan) for no value; the std is NaN for a single value (one seed has
    no spread to report, and :func:`fmt` then prints the mean alone).
    """
    import numpy as np

    array = np.asarray([v for v in values if v is not None], dtype=np.float64)
    array = array[np.isfinite(array)]
    if array.size == 0:
        return math.nan, math.nan
    return float(array.mean()), float(array.std()) if array.size > 1 else math.nan


def fmt(value, digits: int = 2, std=None) -> str:
    """``value`` (``± std``) with ``digits`` decimals; an en dash for missing values."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    text = f"{value:.{digits}f}"
    if std is not None and math.isfinite(std):
        text += f" ± {std:.{digits}f}"
    return text


def clean(obj):
    """``obj`` with NaN/inf floats replaced by None, ready for strict JSON."""
    if isinstance(obj, dict):
        return {str(k): clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    try:
        import numpy as np

        if isinstance(obj, np.ndarray):
            return clean(obj.tolist())
        if isinstance(obj, np.generic):
            return clean(obj.item())
    except ImportError:  # pragma: no cover
        pass
    return obj


def write_csv(path, header: list[str], rows: list[list]) -> Path:
    """Write a CSV atomically (floats with 6 significant digits, missing values empty)."""
    import csv
    import io as _io

    from nrmlc import io

    def cell(value):
        if value is None:
            return ""
        if isinstance(value, float):
            return "" if not math.isfinite(value) else f"{value:.6g}"
        return value

    buffer = _io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows([[cell(v) for v in row] for row in rows])
    return io.write_text(path, buffer.getvalue())


def params_differences(params: TrackerParams, reference: TrackerParams | None = None) -> dict:
    """Fields of ``params`` that differ from ``reference`` (default: the paper's defaults)."""
    reference = TrackerParams() if reference is None else reference
    mine, theirs = params.as_dict(), reference.as_dict()
    return {k: v for k, v in mine.items() if theirs.get(k) != v}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", default=None, help="data root of real sequences (default: $NRMLC_DATA, else synthetic)")
    parser.add_argument("--seeds", type=int, default=None, help="number of seeds for the main tables (default 5)")
    parser.add_argument("--sweep-seeds", type=int, default=None, help="number of seeds for sweeps/ablations (default 3)")
    parser.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    parser.add_argument("--figures", default=None, help="output folder (default: figures/)")
    parser.add_argument("--max-frames", type=int, default=None,
                        help="development: track only the first N frames of every sequence")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="development: change a tracker parameter of every run (repeatable)")
    parser.add_argument("--synthetic-sequences", type=int, default=None,
                        help="sequences in the synthetic suite (default 3; only without --data)")
    parser.add_argument("--cache", default=None, help="run cache folder (default: .cache/runs)")
    parser.add_argument("--peers", default=None,
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
    if args.jobs:
        context.jobs = args.jobs
    if args.figures:
        context.figures_dir = Path(args.figures).resolve()
    if getattr(args, "max_frames", None):
        context.max_frames = int(args.max_frames)
    if getattr(args, "param", None):
        from nrmlc.tracker.params import parse_param_assignment

        changes = dict(parse_param_assignment(text) for text in args.param)
        context.base_params = context.base_params.replace(**changes)
    if getattr(args, "synthetic_sequences", None):
        context.n_synthetic = int(args.synthetic_sequences)
    if getattr(args, "cache", None):
        context.cache = RunCache(Path(args.cache).resolve())
    if getattr(args, "peers", None):
        context.peer_root = Path(args.peers).resolve()
    return context


def collect_and_plot(context, doc: str, stem: str, collect, plot):
    """The opening every figure script's ``main`` shares.

    Builds the context from the command line when the script runs alone (its
    module docstring's first line is the ``--help`` text), collects the numbers
    and draws ``figures/<stem>.png``.

    Returns
    -------
    context : Context
    data : dict, what ``collect(context)`` returned
    png : Path
    plotted : whatever ``plot(data, png)`` returned
    """
    context = context or context_from_args(description=doc.splitlines()[0])
    data = collect(context)
    png = context.output(stem, ".png")
    return context, data, png, plot(data, png)


def save_figure(fig, path, dpi: int = 100, rect=None) -> Path:
    """Lay out ``fig`` (``tight_layout`` within ``rect``), write it to ``path`` as PNG
    atomically (a killed run leaves the old file or the new one, never half of one) and
    close it."""
    import io as _io

    import matplotlib.pyplot as plt

    from nrmlc import io

    fig.tight_layout(rect=rect)
    buffer = _io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    return io.write_bytes(path, buffer.getvalue())
