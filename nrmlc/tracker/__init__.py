"""The NRMLC tracker: parameters, the tracker (one expert), the pair of experts, and whole-sequence
runs. ``make_tracker(params, seed)`` gives the tracker the parameters describe.

Imports are lazy so that ``python -m nrmlc evaluate`` does not load numba.
"""
__all__ = ["NRMLCTracker", "ExpertPair", "make_tracker", "TrackerParams", "FrameResult", "TrackResult",
           "track_sequence"]

_WHERE = {"NRMLCTracker": "algorithm", "ExpertPair": "experts", "make_tracker": "experts",
          "FrameResult": "records", "TrackerParams": "params", "TrackResult": "loop", "track_sequence": "loop"}


def __getattr__(name):
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(f"nrmlc.tracker.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'nrmlc.tracker' has no attribute {name!r}")
