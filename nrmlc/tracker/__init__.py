"""The NRMLC tracker: parameters, the tracker, and whole-sequence runs."""
from nrmlc.tracker.nrmlc_tracker import FrameResult, NRMLCTracker
from nrmlc.tracker.params import TrackerParams
from nrmlc.tracker.run import TrackResult, track_sequence

__all__ = ["NRMLCTracker", "TrackerParams", "FrameResult", "TrackResult", "track_sequence"]
