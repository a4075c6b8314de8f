"""nrmlc: Visual Tracking via Nonnegative Regularization Multiple Locality Coding.

``from nrmlc import make_tracker`` gives the tracker (got10k-style ``init`` /
``update``; ``NRMLCTracker`` is one expert, ``ExpertPair`` the default's two); :mod:`nrmlc.data`, :mod:`nrmlc.workbench.metrics` and :mod:`nrmlc.geometry`
are usable on their own.
"""
__version__ = "0.1.0"

# First, before anything can start numba's OpenMP pool: sets the thread policy's
# environment (see nrmlc.config.set_threads). Light: it imports only os, sys, warnings.
from nrmlc import config as _config  # noqa: E402,F401


def __getattr__(name):
    # Lazy, so that `python -m nrmlc evaluate` and the data tools do not pay for
    # compiling the tracker's kernels.
    if name in ("NRMLCTracker", "ExpertPair", "make_tracker", "TrackerParams"):
        from nrmlc import tracker

        return getattr(tracker, name)
    raise AttributeError(f"module 'nrmlc' has no attribute {name!r}")
