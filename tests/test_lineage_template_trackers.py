"""What each of the lineage's template trackers (L1, L1-APG, MTT) must do: refuse a bad box or
frame, follow a moving target, give the same boxes for a seed and for any thread count, and follow
Car4 where a still box loses the car (:mod:`nrmlc.testing.lineage`)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.errors import ParameterError
from nrmlc.lineage.l1 import L1Tracker
from nrmlc.lineage.l1apg import L1APGTracker
from nrmlc.lineage.mtt import MTTTracker
from nrmlc.testing import lineage
from nrmlc.workbench.otb_results import l1_affine_boxes


def _check_l1_box(tracker, box):
    # the box is the toolkit's of the state, and every lasso converged
    np.testing.assert_array_equal(box, l1_affine_boxes(tracker.state[None], (12, 15))[0])
    assert tracker.unconverged == 0


@dataclass(frozen=True)
class TemplateTrackerCase:
    """One template tracker and what its tests ask of it."""

    name: str  # the synthetic sequence's name, and the test id
    tracker: type
    params: object | None  # of the tracker given the bad boxes and frames; None: the authors'
    bad_inits: tuple  # (frame, box, message), refused in turn by one tracker
    n_frames: int  # of the synthetic sequence, all tracked
    still_below: float  # overlap of the first box held still
    overlap_above: float
    repeat_frames: int  # tracked again for the seed and thread-count checks
    car4_floor: float
    on_box: Callable | None = None  # lineage.track's check after each update


#: L1-APG's and MTT's refusals: a box with a side below 2 pixels, a frame neither uint8 gray nor RGB.
SMALL_REFUSALS = (
    (np.zeros((20, 20), dtype=np.uint8), (1, 1, 1, 5), "box"),
    *((frame, (1, 1, 5, 5), "frame")
      for frame in (np.zeros((20, 20, 2), dtype=np.uint8), np.zeros((20, 20), dtype=np.float32), np.zeros(20))),
)


CASES = [
    TemplateTrackerCase(
        "l1", L1Tracker, None,
        (((np.random.default_rng(0).random((120, 160)) * 255).astype(np.uint8), [1, 2, 3], "box must be"),
         (np.full((60, 80), 7, dtype=np.uint8), [10, 10, 20, 20], "constant gray"),
         (np.zeros((60, 80), dtype=np.float32), [10, 10, 20, 20], "frame must be")),
        n_frames=40, still_below=0.2, overlap_above=0.65, repeat_frames=15,
        car4_floor=0.65,  # seeds 0-4 gave 0.74-0.87 there
        on_box=_check_l1_box),
    TemplateTrackerCase(
        "l1apg", L1APGTracker, lineage.small_params(L1APGTracker), SMALL_REFUSALS,
        n_frames=40, still_below=0.2, overlap_above=0.65, repeat_frames=15,
        car4_floor=0.7),  # seeds 0-4 gave 0.81-0.84 there
    TemplateTrackerCase(
        "mtt", MTTTracker, lineage.small_params(MTTTracker), SMALL_REFUSALS,
        n_frames=30, still_below=0.3, overlap_above=0.6, repeat_frames=10,
        car4_floor=0.7),  # seeds 0 and 1 gave 0.83 there
]


@pytest.fixture(scope="module", params=CASES, ids=[case.name for case in CASES])
def case(request):
    return request.param


@pytest.fixture(scope="module")
def synthetic(case):
    return SyntheticSequence(SyntheticSpec(name=case.name, seed=1, n_frames=case.n_frames))


@pytest.fixture(scope="module")
def tracked(case, synthetic):
    return lineage.track(case.tracker, synthetic, case.n_frames, on_box=case.on_box)


def test_bad_box_and_frame(case):
    tracker = case.tracker(case.params)
    for frame, box, message in case.bad_inits:
        with pytest.raises(ParameterError, match=message):
            tracker.init(frame, box)


def test_tracks_a_moving_target(case, synthetic, tracked):
    overlap, still = lineage.overlap_and_still(tracked, synthetic.groundtruth)
    assert still < case.still_below  # the target moves away from its first box
    assert overlap > case.overlap_above, (overlap, still)


def test_same_seed_same_boxes(case, synthetic, tracked):
    lineage.check_seeds(case.tracker, synthetic, tracked, case.repeat_frames)


def test_boxes_do_not_depend_on_the_thread_count(case, synthetic, tracked):
    lineage.check_thread_counts(case.tracker, synthetic, tracked, case.repeat_frames)


def test_car4_follows_the_car_where_a_still_box_loses_it(case, real_data_root):
    """:func:`nrmlc.testing.lineage.check_car4`; what seeds gave there is noted by each floor in ``CASES``."""
    lineage.check_car4(case.tracker, real_data_root, case.car4_floor, on_box=case.on_box)
