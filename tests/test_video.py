"""The --video overlay: boxes and a legend naming their colours."""
import numpy as np

from nrmlc.video import TRACKER_COLOUR, TRUTH_COLOUR, _legend


def _has_colour(image, colour) -> bool:
    return bool(np.any(np.all(image == np.array(colour, dtype=np.uint8), axis=-1)))


def test_the_legend_names_the_ground_truth_only_when_the_frame_has_one():
    with_truth = np.full((120, 320, 3), 128, np.uint8)
    _legend(with_truth, 0, has_truth=True)
    assert _has_colour(with_truth, TRACKER_COLOUR) and _has_colour(with_truth, TRUTH_COLOUR)
    without = np.full((120, 320, 3), 128, np.uint8)
    _legend(without, 0, has_truth=False)
    assert _has_colour(without, TRACKER_COLOUR) and not _has_colour(without, TRUTH_COLOUR)
    assert np.all(without[40:] == 128)  # only the top band is drawn on
