"""negative_refresh: when the negatives are resampled at an update (round 27's switch)."""
from __future__ import annotations

import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.errors import ParameterError
from nrmlc.testing.scenes import jump_scene


def _track(**changes) -> tuple[list, list]:
    """Boxes and (negative templates, updated_positive) after every frame of the jump scene."""
    frames, truth = jump_scene(jump_frame=6)
    tracker = NRMLCTracker(seed=3, n_particles=60, redetect_count=40, update_interval=2, **changes)
    tracker.init(frames[0], truth[0])
    boxes, after = [], []
    for frame in frames[1:]:
        boxes.append(tracker.update(frame))
        after.append((tracker.negative_templates, tracker.last.updated_positive, tracker.last.error_positive))
    return boxes, after


def test_always_is_the_default_and_the_paper():
    assert TrackerParams().negative_refresh == "always" == TrackerParams.paper().negative_refresh
    with pytest.raises(ParameterError, match="negative_refresh"):
        TrackerParams(negative_refresh="never")


def test_accepted_equals_always_when_every_result_is_accepted():
    # Every result joins (no threshold, no occlusion block): the two rules refresh at the same
    # updates, so they must draw the same random numbers and give the same boxes.
    loose = dict(update_error_threshold=10.0, occlusion_detection=False)
    always, _ = _track(**loose)
    accepted, _ = _track(negative_refresh="accepted", **loose)
    np.testing.assert_array_equal(np.array(always), np.array(accepted))


@pytest.mark.parametrize("rule", ["accepted", "recognised"])
def test_negatives_stay_unless_the_rule_allows_a_refresh(rule):
    _, after = _track(negative_refresh=rule, update_error_threshold=0.0)  # no result ever joins
    frames, truth = jump_scene(jump_frame=6)
    first = NRMLCTracker(seed=3, n_particles=60, redetect_count=40)
    first.init(frames[0], truth[0])
    previous = first.negative_templates
    refreshed = 0
    for index, (negatives, joined, error_positive) in enumerate(after, start=1):
        assert not joined
        update = (index + 1) % 2 == 0
        allowed = rule == "recognised" and error_positive < 1.0
        if update and allowed:
            refreshed += not np.array_equal(negatives, previous)
        else:
            np.testing.assert_array_equal(negatives, previous)
        previous = negatives
    if rule == "recognised":
        assert refreshed > 0  # the scene's target is recognised on some update frames


def _positive_counts(**changes) -> list[int]:
    frames, truth = jump_scene(jump_frame=100)  # no jump within the scene: the target stays put
    tracker = NRMLCTracker(seed=3, n_particles=60, update_interval=3, occlusion_detection=False, **changes)
    tracker.init(frames[0], truth[0])
    counts = []
    for frame in frames[1:]:
        tracker.update(frame)
        counts.append(len(tracker.positive_templates))
    return counts


def test_positive_batch_adds_every_accepted_result_of_the_interval_at_the_update():
    # Every result accepted (threshold 10): the paper's update adds one positive per update, the
    # batch the interval's three (two at the first: frame 0 is the initial box), and only on update
    # frames (frame indices 2, 5, 8, ...).
    single = _positive_counts(update_error_threshold=10.0)
    batch = _positive_counts(update_error_threshold=10.0, positive_batch=True)
    n_positive = TrackerParams().n_positive
    for index, (one, many) in enumerate(zip(single, batch), start=1):
        updates = (index + 1) // 3
        assert one == n_positive + updates
        assert many == n_positive + max(3 * updates - 1, 0)
    # None accepted: the batch adds nothing either.
    assert set(_positive_counts(update_error_threshold=0.0, positive_batch=True)) == {n_positive}
