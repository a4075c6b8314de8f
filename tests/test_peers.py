"""experiments.peers: the live OpenCV trackers."""
import numpy as np

from experiments.peers import LiveSpec, _run_live_here, run_live
from nrmlc.data import synthetic_suite


def test_a_live_run_gives_the_same_boxes_whatever_ran_before_it():
    sequence = synthetic_suite(n_frames=30, n_sequences=1)[0]
    spec = LiveSpec(sequence, "MIL", None)
    first = run_live(spec)["boxes"]
    _run_live_here(spec)  # leaves OpenCV's MIL state behind in this process
    again = run_live(spec)["boxes"]
    np.testing.assert_array_equal(first, again)
    assert np.isfinite(first).all() and first.shape == (30, 4)
