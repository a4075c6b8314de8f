"""The brightness switch (round 36, the default; 'raw' is the paper): every frame shifted to the
first frame's mean gray."""
import numpy as np

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.tracker.brightness import levelled

FAST = dict(n_particles=150)


def _boxes(sequence, offsets, **changes):
    tracker = NRMLCTracker(seed=0, **FAST, **changes)
    tracker.init(sequence.frame(0), sequence.init_box)
    return np.array([tracker.update(sequence.frame(i) + np.float32(offsets[i])) for i in range(1, len(sequence))])


def test_first_frame_brightness_cancels_an_exposure_offset_and_raw_does_not():
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=25))
    # A camera whose exposure steps up by 0.15 gray from frame 5 on.
    shifted = np.where(np.arange(len(sequence)) >= 5, 0.15, 0.0)
    still = np.zeros(len(sequence))
    levelled = _boxes(sequence, still)
    np.testing.assert_allclose(_boxes(sequence, shifted), levelled, atol=0.5)
    raw = _boxes(sequence, shifted, brightness="raw")
    assert np.abs(raw - _boxes(sequence, still, brightness="raw")).max() > 0.5


def test_levelled_frame_has_the_first_frames_mean():
    sequence = SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=3))
    tracker = NRMLCTracker(seed=0, **FAST)
    tracker.init(sequence.frame(0), sequence.init_box)
    frame = sequence.frame(1).astype(np.float32) + np.float32(0.3)
    assert abs(levelled(frame, tracker.first_frame_mean, tracker.params).mean(dtype=np.float64) - sequence.frame(0).mean(dtype=np.float64)) < 1e-5
    assert TrackerParams().brightness == "first_frame"
    assert TrackerParams.paper().brightness == "raw"
