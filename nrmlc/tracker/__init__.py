"""The NRMLC tracker: parameters, the tracker, and whole-sequence runs.

Imports are lazy so that ``python -m nrmlc evaluate`` does not load numba.
"""
__all__ = ["NRMLCTracker", "TrackerParams", "FrameResult", "TrackResult", "track_sequence"]

_WHERE = {"NRMLCTracker": "algorithm", "FrameResult": "algorithm", "TrackerParams": "params",
          "TrackResult": "loop", "track_sequence": "loop"}


def __getattr__(name):
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(f"nrmlc.tracker.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'nrmlc.tracker' has no attribute {name!r}")
