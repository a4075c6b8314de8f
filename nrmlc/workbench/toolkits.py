"""NRMLC inside tracking toolkits: an adapter for the got10k toolkit (``pip install got10k``).

got10k's experiments (``ExperimentOTB``, ``ExperimentGOT10k``, ``ExperimentVOT``, ...)
run any subclass of ``got10k.trackers.Tracker``: its ``track(img_files, box)`` opens
each frame with PIL, converts it to RGB and calls ``init(image, box)`` on the first
frame and ``update(image) -> box`` on the others. :class:`NRMLCGot10k` is that
subclass around :func:`~nrmlc.make_tracker`'s tracker (which takes PIL images as they come)::

    from got10k.experiments import ExperimentOTB
    from nrmlc.workbench.toolkits import NRMLCGot10k

    experiment = ExperimentOTB("data/OTB", version=2015, result_dir="results", report_dir="reports")
    experiment.run(NRMLCGot10k(seed=0))          # results/OTB2015/NRMLC/<Seq>.txt
    experiment.report(["NRMLC"])

:class:`LineageGot10k` does the same for the lineage's live trackers (:mod:`nrmlc.lineage`)::

    experiment.run(LineageGot10k("asla", seed=0))  # results/OTB2015/ASLA/<Seq>.txt

Boxes are passed through unchanged: ``x, y, w, h`` in the dataset's own
convention (OTB files are 1-based, as nrmlc assumes; GOT-10k's are 0-based,
which only shifts the patch grid by a pixel). Without got10k installed the class
still has ``init`` / ``update`` (but no ``track``).
"""
from __future__ import annotations

import numpy as np

from nrmlc.tracker.experts import make_tracker
from nrmlc.tracker.params import TrackerParams

try:  # the toolkit is optional: nrmlc does not need it
    from got10k.trackers import Tracker as _Got10kTracker
except ImportError:  # pragma: no cover - exercised only without got10k
    _Got10kTracker = object


class NRMLCGot10k(_Got10kTracker):
    """NRMLC as a ``got10k.trackers.Tracker``.

    Parameters
    ----------
    seed : int
        Seed of every sequence's run (each ``init`` restarts the generator
        from it, so a sequence's boxes do not depend on what ran before).
    params : TrackerParams, optional
    name : str
        The tracker's name in got10k's result and report folders.
    **overrides
        Any :class:`~nrmlc.TrackerParams` field, e.g. ``n_particles=300``.
    """

    def __init__(self, seed: int = 0, params: TrackerParams | None = None, name: str = "NRMLC", **overrides) -> None:
        self.tracker = make_tracker(params, seed, **overrides)
        if _Got10kTracker is object:
            self.name, self.is_deterministic = name, True
        else:
            # Deterministic: the same seed gives the same boxes (got10k then runs VOT once, not 3 times).
            super().__init__(name=name, is_deterministic=True)

    def init(self, image, box) -> None:
        """Start on ``image`` (PIL or numpy) with ``box`` = ``x, y, w, h``."""
        self.tracker.init(image, np.asarray(box, dtype=np.float64))

    def update(self, image) -> np.ndarray:
        """The target's ``(4,)`` box ``x, y, w, h`` in ``image``."""
        return self.tracker.update(image)


class LineageGot10k(_Got10kTracker):
    """A tracker of the lineage (``"ivt"``, ``"asla"``, ...: :data:`nrmlc.lineage.TRACKERS`) as a
    ``got10k.trackers.Tracker``.

    got10k gives RGB images (PIL); the lineage's trackers take OpenCV's BGR order, so each image
    is reordered before it is passed on. Each ``init`` makes the tracker again from ``seed``, so a
    sequence's boxes do not depend on what ran before.

    Parameters
    ----------
    short_name : str
        A key of :data:`nrmlc.lineage.TRACKERS` (any case).
    seed : int
    name : str, optional
        The tracker's name in got10k's result and report folders (default: the short name in
        capitals).
    """

    def __init__(self, short_name: str, seed: int = 0, name: str | None = None) -> None:
        from nrmlc.errors import ParameterError
        from nrmlc.lineage import TRACKERS
        from nrmlc.workbench.trackers import _make, _resolve, lineage_name

        short = lineage_name(short_name)
        if short is None:
            raise ParameterError(f"LineageGot10k: {short_name!r} is not a lineage tracker (one of "
                                 f"{', '.join(sorted(TRACKERS))})")
        self.spec, self.seed = TRACKERS[short], int(seed)
        self._factory = _resolve(self.spec)[1]
        self.tracker = _make(self.spec, self._factory, self.seed)
        name = name or short.upper()
        if _Got10kTracker is object:
            self.name, self.is_deterministic = name, True
        else:
            super().__init__(name=name, is_deterministic=True)

    def init(self, image, box) -> None:
        """Start on ``image`` (PIL RGB or numpy RGB / gray) with ``box`` = ``x, y, w, h``."""
        from nrmlc.workbench.trackers import _make

        self.tracker = _make(self.spec, self._factory, self.seed)
        self.tracker.init(_bgr(image), np.asarray(box, dtype=np.float64))

    def update(self, image) -> np.ndarray:
        """The target's ``(4,)`` box ``x, y, w, h`` in ``image``."""
        return np.asarray(self.tracker.update(_bgr(image)), dtype=np.float64)


def _bgr(image) -> np.ndarray:
    """An RGB image (PIL or (H, W, 3) uint8) in OpenCV's BGR order; a gray one as it is."""
    array = np.asarray(image)
    if array.ndim == 3 and array.shape[2] == 3:
        return np.ascontiguousarray(array[:, :, ::-1])
    return np.ascontiguousarray(array)
