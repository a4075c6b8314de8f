"""The tracker's template rules, pinned to the value (docs/research/mutation.md).

Written against the mutants mutmut left alive (or could not run) in ``nrmlc/tracker/templates.py``
(the annulus sampler of Sec. 3, which only ``template_sampling='annulus'`` uses) and in
``NRMLCTracker.update_templates`` / ``NRMLCTracker._result`` (Algorithm 2, step 2.5 and the
occlusion judgement): exact template centres for known draws, every field of a frame's result
from a hand-built code, and each boundary of the update rule (LEN(neg*) against
``occlusion_max_negative``, eps_pos* against ``update_error_threshold``, ``max_positive``).
"""
import copy
import math

import numpy as np
import pytest

from nrmlc import NRMLCTracker
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.geometry import state_to_box
from nrmlc.kernels.distance import template_gram
from nrmlc.tracker.records import Coding
from nrmlc.tracker.templates import (SCM_PUSH_INIT, SCM_PUSH_UPDATE, negative_states, offsets_in_annulus,
                                     positive_states, scm_negative_states, scm_positive_states, shifted_states)


class Draws:
    """A stand-in for ``np.random.Generator`` whose ``uniform`` calls return given fractions of
    their range (``low + (high - low) * f``), one list per call, and record their arguments."""

    def __init__(self, *fractions):
        self.fractions = [np.asarray(f, dtype=np.float64) for f in fractions]
        self.calls = []

    def uniform(self, low, high, size):
        self.calls.append((low, high, size))
        f = self.fractions[len(self.calls) - 1]
        assert len(f) == size
        return low + (high - low) * f


# -- templates.py: the annulus sampler -------------------------------------------------------

def test_offsets_in_annulus_are_radius_then_angle_draws_by_hand():
    # radius^2 uniform in [inner^2, outer^2) (uniform by area), then angle uniform in [0, 2 pi).
    draws = Draws([0.0, 0.5, 0.25], [0.0, 0.25, 0.625])
    offsets = offsets_in_annulus(draws, 3, 2.0, 4.0)
    assert draws.calls == [(4.0, 16.0, 3), (0.0, 2 * np.pi, 3)]
    # radii sqrt(4), sqrt(10), sqrt(7); angles 0, pi/2, 5 pi/4
    r1, r2 = math.sqrt(10.0), math.sqrt(7.0)
    expected = [[2.0, 0.0], [0.0, r1], [-r2 / math.sqrt(2), -r2 / math.sqrt(2)]]
    np.testing.assert_allclose(offsets, expected, rtol=0, atol=1e-12)
    assert offsets.shape == (3, 2) and offsets.dtype == np.float64


def test_offsets_in_annulus_from_a_seeded_generator():
    # Generator.uniform(a, b) is a + (b - a) * random(): the same two blocks of draws.
    n, inner, outer = 200, 3.0, 7.0
    offsets = offsets_in_annulus(np.random.default_rng(11), n, inner, outer)
    u = np.random.default_rng(11).random(2 * n)
    radius = np.sqrt(inner**2 + (outer**2 - inner**2) * u[:n])
    angle = 2 * np.pi * u[n:]
    np.testing.assert_allclose(offsets, np.c_[radius * np.cos(angle), radius * np.sin(angle)], rtol=1e-12)
    distance = np.hypot(offsets[:, 0], offsets[:, 1])
    assert np.all((distance >= inner - 1e-12) & (distance < outer))
    # uniform by area: half the points inside the radius that halves the annulus' area
    median_radius = math.sqrt((inner**2 + outer**2) / 2)
    assert 0.4 < np.mean(distance < median_radius) < 0.6
    # every direction: points in all four quadrants
    assert len({(bool(x > 0), bool(y > 0)) for x, y in offsets}) == 4


def test_shifted_states_map_template_offsets_through_the_targets_warp():
    # scale 2, aspect 1.5, no rotation: the template grid is 2 px per step across, 3 down.
    state = np.array([50.0, 40.0, 2.0, 0.0, 1.5, 0.0])
    offsets = np.array([[1.0, 0.0], [0.0, 1.0], [2.0, -1.0]])
    states = shifted_states(state, offsets)
    np.testing.assert_allclose(states[:, :2], [[52.0, 40.0], [50.0, 43.0], [54.0, 37.0]], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(states[:, 2:], np.tile(state[2:], (3, 1)))
    assert np.array_equal(state, [50.0, 40.0, 2.0, 0.0, 1.5, 0.0])  # the input is not moved
    # rotated a quarter turn: a step along the grid's u axis goes down the image's y axis
    turned = np.array([10.0, 20.0, 2.0, np.pi / 2, 1.0, 0.0])
    moved = shifted_states(turned, np.array([[1.0, 0.0], [0.0, 1.0]]))
    np.testing.assert_allclose(moved[:, :2], [[10.0, 22.0], [8.0, 20.0]], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(moved[:, 2:], np.tile(turned[2:], (2, 1)))


def test_positive_states_are_the_target_then_n_minus_1_draws_within_the_radius():
    state = np.array([50.0, 40.0, 2.0, 0.0, 1.5, 0.0])
    draws = Draws([0.25, 1.0], [0.0, 0.25])
    states = positive_states(draws, state, 3, 2.0)
    assert draws.calls == [(0.0, 4.0, 2), (0.0, 2 * np.pi, 2)]
    assert states.shape == (3, 6)
    np.testing.assert_array_equal(states[0], state)  # the target itself, exactly
    # offsets (1, 0) and (0, 2) on the grid: (+2, 0) and (0, +6) px
    np.testing.assert_allclose(states[1:, :2], [[52.0, 40.0], [50.0, 46.0]], rtol=0, atol=1e-12)


def test_negative_states_are_n_draws_in_the_annulus():
    state = np.array([50.0, 40.0, 2.0, 0.0, 1.5, 0.0])
    draws = Draws([0.0, 1.0], [0.5, 0.75])
    states = negative_states(draws, state, 2, 1.0, 3.0)
    assert draws.calls == [(1.0, 9.0, 2), (0.0, 2 * np.pi, 2)]
    # offsets (-1, 0) and (0, -3) on the grid: (-2, 0) and (0, -9) px
    np.testing.assert_allclose(states[:, :2], [[48.0, 40.0], [50.0, 31.0]], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(states[:, 2:], np.tile(state[2:], (2, 1)))


def test_annulus_tracker_samples_its_templates_at_these_states():
    """``template_sampling='annulus'``: the first positives are the patches of
    positive_states(rng, state, n_positive, positive_radius) and the negatives those of
    negative_states(rng, state, n_negative, positive_radius, negative_radius), in that order."""
    sequence = SyntheticSequence(SyntheticSpec(name="m", seed=3, n_frames=3))
    tracker = NRMLCTracker(seed=4, n_particles=20, template_sampling="annulus", positive_radius=1.5,
                           negative_radius=6.0, n_positive=5, n_negative=7)
    frame = sequence.frame(0)
    tracker.init(frame, sequence.init_box)
    p, rng = tracker.params, np.random.default_rng(4)
    positives = positive_states(rng, tracker.state, 5, 1.5)
    negatives = negative_states(rng, tracker.state, 7, 1.5, 6.0)
    np.testing.assert_array_equal(tracker.positive_templates, tracker.patches(frame, positives))
    np.testing.assert_array_equal(tracker.negative_templates, tracker.patches(frame, negatives))
    assert p.template_sampling == "annulus"


class Normals:
    """A stand-in for ``np.random.Generator`` whose ``standard_normal`` calls return given arrays."""

    def __init__(self, *values):
        self.values = [np.asarray(v, dtype=np.float64) for v in values]
        self.sizes = []

    def standard_normal(self, size):
        self.sizes.append(size)
        value = self.values[len(self.sizes) - 1]
        assert value.shape == np.empty(size).shape
        return value.copy()


def test_scm_positive_states_add_sigma_times_the_draws():
    state = np.array([100.0, 80.0, 1.5, 0.0, 1.2, 0.0])
    normals = Normals([[0.5, -1.0], [2.0, 0.25]])
    states = scm_positive_states(normals, state, 2, 2.0)
    assert normals.sizes == [(2, 2)]
    np.testing.assert_array_equal(states[:, :2], [[101.0, 78.0], [104.0, 80.5]])
    np.testing.assert_array_equal(states[:, 2:], np.tile(state[2:], (2, 1)))


def test_scm_negative_states_push_each_axis_out_of_its_zone_by_hand():
    """Width 48, height 57.6 (scale 1.5, aspect 1.2, 32 px); push 0.25: zones 12 and 14.4 px.
    Offsets inside a zone move to its edge on their own side, 0 and (0, 1) to the + side."""
    state = np.array([100.0, 80.0, 1.5, 0.0, 1.2, 0.0])
    x = np.array([0.0, 1 / 96, 0.125, -0.125, 0.25, -0.25, 1.0, -2.0])  # 0, 0.5, 6, -6, 12, -12, 48, -96 px
    y = np.array([0.0, -0.1, 1.0, 0.25, -1 / 576, 0.5, -0.5, 3.0])  # 0, -5.76, 57.6, 14.4, -0.1, 28.8, ...
    normals = Normals(x, y)
    states = scm_negative_states(normals, state, 8, 32, SCM_PUSH_INIT)
    assert normals.sizes == [8, 8]
    dx = states[:, 0] - 100.0
    dy = states[:, 1] - 80.0
    np.testing.assert_allclose(dx, [12, 12, 12, -12, 12, -12, 48, -96], rtol=0, atol=1e-12)
    np.testing.assert_allclose(dy, [14.4, -14.4, 57.6, 14.4, -14.4, 28.8, -28.8, 172.8], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(states[:, 2:], np.tile(state[2:], (8, 1)))


# -- algorithm.py: _result and update_templates -----------------------------------------------

@pytest.fixture(scope="module")
def sequence():
    return SyntheticSequence(SyntheticSpec(name="m", seed=3, n_frames=4))


def _tracker(sequence, **changes):
    # 10 positives: a code's k_max = 10 rows can all be positive (the hand-built codes need it)
    settings = dict(n_particles=20, n_positive=10, n_negative=12, max_positive=12, update_error_threshold=0.1)
    tracker = NRMLCTracker(seed=0, **{**settings, **changes})
    tracker.init(sequence.frame(0), sequence.init_box)
    return tracker


def _coding(tracker, patch, negative_codes, positive_codes=None, log_confidence=-2.0):
    """Two candidates; candidate 1 (the one the tests pick) codes ``patch`` with
    ``negative_codes`` on the first negative templates (rows n_pos, n_pos + 1, ...) and
    ``positive_codes`` (default: the rest of a unit sum, spread) on positive rows 0, 1, ..."""
    p = tracker.params
    k, n_pos = p.k_max, len(tracker.positive_templates)
    n_neg = len(negative_codes)
    if positive_codes is None:
        positive_codes = [(1.0 - sum(negative_codes)) / (k - n_neg)] * (k - n_neg)
    neighbours = np.concatenate([np.arange(k - n_neg), n_pos + np.arange(n_neg)]).astype(np.int64)
    codes = np.concatenate([positive_codes, negative_codes])
    m = len(p.dictionary_sizes)
    other = np.zeros_like(codes)
    coefficients = np.stack([np.tile(other, (m, 1)), np.arange(m * k, dtype=np.float64).reshape(m, k)])
    return Coding(patches=np.vstack([patch, patch]), dots=np.zeros((2, len(tracker.templates))),
                  neighbours=np.stack([neighbours[::-1], neighbours]), coefficients=coefficients,
                  weights=np.array([np.full(m, 1.0 / m), np.arange(1.0, m + 1.0)]), codes=np.stack([other, codes]),
                  error_positive=np.array([3.0, 0.01]), error_negative=np.array([0.2, 0.9]),
                  log_confidence=np.array([-50.0, log_confidence]))


def test_result_fields_by_hand(sequence):
    tracker = _tracker(sequence)
    p = tracker.params
    patch = tracker.patches(sequence.frame(1), tracker.state[None, :])[0]
    k, n_pos = p.k_max, len(tracker.positive_templates)
    negative = [0.25, -0.125]
    positive = [0.5] + [0.375 / (k - 3)] * (k - 3)
    coding = _coding(tracker, patch, negative, positive, log_confidence=-2.0)
    result = tracker._result(coding, 1, searched=True, redetected=False)
    np.testing.assert_array_equal(result.state, tracker.state)
    assert result.state is not tracker.state
    np.testing.assert_array_equal(result.box, state_to_box(tracker.state, p.patch_size))
    assert result.confidence == math.exp(-2.0) and result.log_confidence == -2.0
    assert (result.error_positive, result.error_negative) == (0.01, 0.9)
    np.testing.assert_array_equal(result.template_indices, coding.neighbours[1])
    np.testing.assert_array_equal(result.codes, coding.codes[1])
    np.testing.assert_array_equal(result.coefficients, coding.coefficients[1])
    np.testing.assert_array_equal(result.weights, coding.weights[1])
    assert (result.n_positive_templates, result.n_templates) == (n_pos, n_pos + p.n_negative) == (10, 22)
    assert result.n_negative_used == 2 and result.occluded is False
    assert result.code_sum_positive == pytest.approx(0.875, abs=1e-15)
    assert result.code_sum_negative == 0.125
    assert result.redetect_searched is True and result.redetected is False
    assert result.updated_positive is False
    other = tracker._result(coding, 1, searched=False, redetected=True)
    assert other.redetect_searched is False and other.redetected is True
    # the copies are the result's own
    coding.codes[1, 0] = 7.0
    assert result.codes[0] == 0.5


def test_result_box_is_drawn_with_the_trackers_patch_size(sequence):
    tracker = _tracker(sequence, patch_size=16)
    patch = tracker.patches(sequence.frame(1), tracker.state[None, :])[0]
    result = tracker._result(_coding(tracker, patch, []), 1, False, False)
    np.testing.assert_array_equal(result.box, state_to_box(tracker.state, 16))
    assert result.box[2] == pytest.approx(16 * tracker.state[2])  # a 16-sample grid, not 32


@pytest.mark.parametrize("log_confidence, expected", [(709.0, math.exp(709.0)), (709.5, math.inf),
                                                       (-800.0, 0.0)])
def test_result_confidence_overflows_to_infinity_only_beyond_709(sequence, log_confidence, expected):
    tracker = _tracker(sequence)
    patch = tracker.patches(sequence.frame(1), tracker.state[None, :])[0]
    result = tracker._result(_coding(tracker, patch, [], log_confidence=log_confidence), 1, False, False)
    assert result.confidence == expected and result.log_confidence == log_confidence


@pytest.mark.parametrize("limit", [0, 1, 3])
@pytest.mark.parametrize("used", [0, 1, 2, 3, 4])
def test_occluded_exactly_when_more_negatives_are_used_than_the_limit(sequence, limit, used):
    tracker = _tracker(sequence, occlusion_max_negative=limit)
    tol = tracker.params.coefficient_tolerance
    patch = tracker.patches(sequence.frame(1), tracker.state[None, :])[0]
    # the first negative row (index n_pos itself) counts; codes at +-tol do not; signs do not matter
    codes = [0.05, -0.04, 0.03, -0.02][:used] + [tol, -tol]
    result = tracker._result(_coding(tracker, patch, codes), 1, False, False)
    assert result.n_negative_used == used
    assert result.occluded is (used > limit)


def test_a_code_on_the_first_negative_row_alone_counts(sequence):
    tracker = _tracker(sequence, occlusion_max_negative=0)
    tol = tracker.params.coefficient_tolerance
    patch = tracker.patches(sequence.frame(1), tracker.state[None, :])[0]
    result = tracker._result(_coding(tracker, patch, [np.nextafter(tol, 1.0)]), 1, False, False)
    assert result.template_indices[-1] == len(tracker.positive_templates)
    assert result.n_negative_used == 1 and result.occluded is True


def _frame_result(tracker, sequence, error_positive=0.01, negative_codes=()):
    patch = tracker.patches(sequence.frame(1), tracker.state[None, :])[0]
    result = tracker._result(_coding(tracker, patch, list(negative_codes)), 1, False, False)
    result.error_positive = error_positive
    return result, patch[None, :]


def _marked_gram(tracker):
    """Mark the current Gram (+1 everywhere) so that carried entries can be told from recomputed ones."""
    tracker.template_gram = tracker.template_gram + 1.0
    return tracker.template_gram.copy()


def _check_gram(tracker, marked, kept):
    """Rows of positives kept carry the marked Gram's entries; every other entry is fresh."""
    fresh = template_gram(tracker.templates)
    gram = tracker.template_gram
    n = len(tracker.templates)
    for i in range(n):
        for j in range(n):
            if i < len(kept) and j < len(kept) and kept[i] >= 0 and kept[j] >= 0:
                assert gram[i, j] == marked[kept[i], kept[j]], (i, j)
            else:
                assert abs(gram[i, j] - fresh[i, j]) <= 1e-5 * max(1.0, abs(fresh[i, j])), (i, j)
    np.testing.assert_array_equal(tracker.template_sq_norms, np.diag(gram))


@pytest.mark.parametrize("sampling", ["scm", "annulus"])
def test_update_appends_the_estimate_and_resamples_every_negative_around_the_state(sequence, sampling):
    tracker = _tracker(sequence, template_sampling=sampling)
    p = tracker.params
    frame = sequence.frame(1)
    tracker.state = tracker.state + np.array([3.0, -2.0, 0.0, 0.0, 0.0, 0.0])  # this frame's estimate
    result, estimate = _frame_result(tracker, sequence)
    before = tracker.positive_templates.copy()
    marked = _marked_gram(tracker)
    rng = copy.deepcopy(tracker.rng)
    tracker.update_templates(frame, result, estimate)
    assert result.updated_positive is True
    np.testing.assert_array_equal(tracker.positive_templates, np.vstack([before, estimate]))
    if sampling == "scm":
        states = scm_negative_states(rng, tracker.state, p.n_negative, p.patch_size,
                                     p.negative_push * (SCM_PUSH_UPDATE / SCM_PUSH_INIT))
    else:
        states = negative_states(rng, tracker.state, p.n_negative, p.positive_radius, p.negative_radius)
    np.testing.assert_array_equal(tracker.negative_templates, tracker.patches(frame, states))
    np.testing.assert_array_equal(tracker.templates, np.vstack([before, estimate, tracker.negative_templates]))
    _check_gram(tracker, marked, list(range(10)) + [-1])


@pytest.mark.parametrize("error, updated", [(0.1, False), (np.nextafter(0.1, 0.0), True), (0.05, True),
                                            (0.3, False)])
def test_positives_are_updated_only_below_the_error_threshold(sequence, error, updated):
    tracker = _tracker(sequence)  # update_error_threshold 0.1
    result, estimate = _frame_result(tracker, sequence, error_positive=error)
    before = tracker.positive_templates
    marked = _marked_gram(tracker)
    tracker.update_templates(sequence.frame(1), result, estimate)
    assert result.updated_positive is updated
    if updated:
        assert len(tracker.positive_templates) == 11
        _check_gram(tracker, marked, list(range(10)) + [-1])
    else:
        assert tracker.positive_templates is before
        _check_gram(tracker, marked, list(range(10)))


@pytest.mark.parametrize("detection", [True, False])
@pytest.mark.parametrize("n_used", [2, 3])
def test_an_occluded_estimate_joins_the_positives_only_with_detection_off(sequence, detection, n_used):
    tracker = _tracker(sequence, occlusion_detection=detection)  # occlusion_max_negative 2
    result, estimate = _frame_result(tracker, sequence, negative_codes=[0.05, -0.04, 0.03][:n_used])
    assert result.occluded is (n_used == 3)
    tracker.update_templates(sequence.frame(1), result, estimate)
    joined = not (detection and n_used == 3)
    assert result.updated_positive is joined
    assert len(tracker.positive_templates) == 10 + joined


@pytest.mark.parametrize("n_positive, max_positive, appended", [(10, 11, True), (10, 10, False), (11, 11, False)])
def test_appended_below_max_positive_and_replacing_at_it(sequence, n_positive, max_positive, appended):
    tracker = _tracker(sequence, n_positive=n_positive, max_positive=max_positive)
    result, estimate = _frame_result(tracker, sequence)
    tracker.update_templates(sequence.frame(1), result, estimate)
    assert len(tracker.positive_templates) == (n_positive + 1 if appended else n_positive)
    assert result.updated_positive is True


def test_at_max_positive_the_closest_positive_is_replaced(sequence):
    """Closest by squared distance (not the first, not the last, not by signed cubes): row 4 is
    the estimate plus a little noise; row 7 lies below the estimate in every pixel, so that a
    sum of cubed differences would pick it; the others above it."""
    tracker = _tracker(sequence, n_positive=10, max_positive=10)
    result, estimate = _frame_result(tracker, sequence)
    e = estimate[0].astype(np.float32)
    noise = np.random.default_rng(0).standard_normal(e.shape).astype(np.float32) * 1e-3
    shifts = [0.3, 0.6, 0.35, 0.4, noise, 0.45, 0.5, -0.5, 0.55, 0.65]
    positives = np.stack([e + shift for shift in shifts]).astype(np.float32)
    tracker._set_templates(positives, tracker.negative_templates)
    marked = _marked_gram(tracker)
    tracker.update_templates(sequence.frame(1), result, estimate)
    assert result.updated_positive is True
    after = tracker.positive_templates
    others = [0, 1, 2, 3, 5, 6, 7, 8, 9]
    np.testing.assert_array_equal(after[others], positives[others])
    np.testing.assert_array_equal(after[4], estimate[0])
    np.testing.assert_array_equal(positives[4], e + noise)  # the previous set is not changed in place
    _check_gram(tracker, marked, [0, 1, 2, 3, -1, 5, 6, 7, 8, 9])
