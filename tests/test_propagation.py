"""Template sampling (SCM / annulus), particle propagation (condensation / best), the
state's range, the log-domain confidence, presets and the API's input checks."""
import math
import re
from pathlib import Path
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.errors import ParameterError
from nrmlc.geometry import clamp_states, state_to_box
from nrmlc.tracker import track_sequence
from nrmlc.tracker.params import MAX_ALPHA
from nrmlc.tracker.templates import (SCM_PUSH_INIT, SCM_PUSH_UPDATE, scm_negative_states,
                                     scm_positive_states, target_size)

from experiments.instrumented import RecordingTracker, move_to

REPO_ROOT = Path(__file__).resolve().parent.parent

FAST = dict(n_particles=120)


@pytest.fixture(scope="module")
def sequence():
    return SyntheticSequence(SyntheticSpec(name="p", seed=5, n_frames=25))


# -- SCM template sampling ---------------------------------------------------------

def test_scm_positive_centres_are_gaussian_with_the_given_sigma():
    state = np.array([100.0, 80.0, 1.5, 0.0, 1.2, 0.0])
    states = scm_positive_states(np.random.default_rng(0), state, 20000, 1.0)
    offsets = states[:, :2] - state[:2]
    np.testing.assert_allclose(offsets.std(axis=0), 1.0, rtol=0.03)
    np.testing.assert_allclose(offsets.mean(axis=0), 0.0, atol=0.03)
    assert np.array_equal(states[:, 2:], np.tile(state[2:], (20000, 1)))


@pytest.mark.parametrize("push", [SCM_PUSH_INIT, SCM_PUSH_UPDATE])
def test_scm_negatives_keep_out_of_the_push_zone_on_both_axes(push):
    state = np.array([100.0, 80.0, 1.5, 0.0, 1.2, 0.0])
    width, height = target_size(state, 32)
    assert (width, height) == pytest.approx((48.0, 57.6))
    states = scm_negative_states(np.random.default_rng(1), state, 20000, 32, push)
    dx, dy = (states[:, :2] - state[:2]).T
    assert np.all(np.abs(dx) >= push * width - 1e-9) and np.all(np.abs(dy) >= push * height - 1e-9)
    # The pushed samples sit exactly on the zone's edge, on their own side, in SCM's proportion.
    on_edge = np.isclose(np.abs(dx), push * width)
    expected = 2 * 0.5 * (1 + math.erf(push / np.sqrt(2))) - 1  # P(|N(0, 1)| <= push)
    assert on_edge.mean() == pytest.approx(expected, abs=0.01)
    # Outside the zone the offsets are N(0, w^2): their spread is the target's size.
    assert np.std(dx) == pytest.approx(width, rel=0.05)


def test_template_sampling_switch_changes_the_templates_and_annulus_keeps_the_radii(sequence):
    scm = NRMLCTracker(seed=0, **FAST)
    annulus = NRMLCTracker(seed=0, template_sampling="annulus", **FAST)
    for tracker in (scm, annulus):
        tracker.init(sequence.frame(0), sequence.init_box)
    p = scm.params
    assert scm.templates.shape == annulus.templates.shape == (p.n_positive + p.n_negative, 1024)
    assert not np.array_equal(scm.negative_templates, annulus.negative_templates)


# -- propagation -------------------------------------------------------------------

def _tracker_after_one_frame(sequence, **changes):
    tracker = NRMLCTracker(seed=0, **{**FAST, **changes})
    tracker.init(sequence.frame(0), sequence.init_box)
    tracker.update(sequence.frame(1))
    return tracker


def test_condensation_resamples_in_proportion_to_the_confidence(sequence):
    tracker = _tracker_after_one_frame(sequence, motion_sigmas=(0, 0, 0, 0, 0, 0))
    particles = tracker.particles.copy()
    particles[:, 0] += np.arange(len(particles)) * 0.01  # distinct, all inside the frame
    tracker.particles = particles.copy()
    heavy = 17
    weights = np.full(len(particles), -np.inf)
    weights[heavy] = 0.0
    tracker.log_weights = weights
    drawn = tracker.sample_particles()
    assert np.array_equal(drawn, np.tile(particles[heavy], (len(particles), 1)))
    # Two particles with weights 1 : 3 are drawn about 1 : 3.
    weights[:] = -np.inf
    weights[[3, 9]] = [0.0, np.log(3.0)]
    tracker.log_weights = weights
    counts = [0, 0]
    for _ in range(20):
        drawn = tracker.sample_particles()
        counts[0] += np.sum(np.all(drawn == particles[3], axis=1))
        counts[1] += np.sum(np.all(drawn == particles[9], axis=1))
    assert counts[0] + counts[1] == 20 * len(particles)
    assert counts[1] / counts[0] == pytest.approx(3.0, rel=0.15)


def test_best_propagation_draws_every_particle_around_the_estimate(sequence):
    tracker = _tracker_after_one_frame(sequence, propagation="best", motion_sigmas=(0, 0, 0, 0, 0, 0))
    drawn = tracker.sample_particles()
    assert np.array_equal(drawn, np.tile(tracker.state, (len(drawn), 1)))


def test_condensation_estimate_is_the_most_confident_particle(sequence):
    tracker = _tracker_after_one_frame(sequence)
    best = int(np.argmax(tracker.log_weights))
    np.testing.assert_array_equal(tracker.state, tracker.particles[best])


def test_move_to_restarts_the_particle_cloud(sequence):
    tracker = _tracker_after_one_frame(sequence, motion_sigmas=(0, 0, 0, 0, 0, 0))
    box = np.array([30.0, 40.0, 20.0, 25.0])
    move_to(tracker, box)
    drawn = tracker.sample_particles()
    np.testing.assert_allclose(state_to_box(drawn[0], 32), box)
    assert np.array_equal(drawn, np.tile(drawn[0], (len(drawn), 1)))


def test_relative_translation_noise_scales_with_the_target():
    spec_small = SyntheticSpec(name="s", seed=1, n_frames=3)
    sequence = SyntheticSequence(spec_small)
    spreads = []
    for box in ((60, 60, 16, 16), (60, 60, 64, 64)):
        tracker = NRMLCTracker(seed=0, n_particles=4000, translation_noise="relative", propagation="best",
                               motion_sigmas=(2.0, 2.0, 0, 0, 0, 0), translation_floor=0.0)
        tracker.init(sequence.frame(0), box)
        spreads.append(np.std(tracker.sample_particles()[:, 0]))
    # 2 template pixels: 2 * 16/32 = 1 px and 2 * 64/32 = 4 px.
    assert spreads == pytest.approx([1.0, 4.0], rel=0.06)


@pytest.mark.parametrize("propagation", ["condensation", "best"])
def test_propagation_modes_are_deterministic_per_seed(sequence, propagation):
    runs = [track_sequence(sequence, TrackerParams(propagation=propagation, **FAST), seed=s, n_frames=12)
            for s in (4, 4, 5)]
    assert np.array_equal(runs[0].boxes, runs[1].boxes)
    assert not np.array_equal(runs[0].boxes, runs[2].boxes)


# -- the state's range ---------------------------------------------------------------

@given(st.lists(st.floats(-1e6, 1e6), min_size=6, max_size=6), st.floats(1e-6, 1e6), st.floats(1e-6, 1e6))
def test_clamped_states_stay_in_the_frame(values, scale, aspect):
    states = np.array([[values[0], values[1], scale, values[3], aspect, values[5]]])
    clamp_states(states, (120, 160), 4.0, 32)
    cx, cy, s, _, a, _ = states[0]
    assert 0 <= cx <= 159 and 0 <= cy <= 119
    assert 4.0 - 1e-9 <= 32 * s <= 320 + 1e-9 and 4.0 - 1e-9 <= 32 * s * a <= 320 + 1e-9


def test_wild_motion_keeps_boxes_bounded(sequence):
    params = TrackerParams(n_particles=60, motion_sigmas=(1000.0, 1000.0, 1.0, 3.0, 1.0, 0.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warnings either
        result = track_sequence(sequence, params, seed=0, n_frames=10)
    height, width = sequence.frame(0).shape[:2]
    assert np.all(np.isfinite(result.boxes))
    assert np.all(result.boxes[:, 2:] <= 2 * 2 * max(height, width))  # a rotated box's extent
    centres = result.boxes[:, :2] - 1 + result.boxes[:, 2:] / 2
    assert np.all((centres[:, 0] >= -1e-6) & (centres[:, 0] <= width - 1 + 1e-6))


# -- confidence in the log domain ------------------------------------------------------

@pytest.mark.parametrize("alpha", [2.5, 1e4, MAX_ALPHA])
def test_any_alpha_ranks_by_the_error_difference_without_overflow(sequence, alpha):
    # exp(alpha * 4) overflows float64 from alpha = 178 on: the log domain must hold up to the bound.
    # Without the generative term, whose own ranking tests/test_generative.py checks.
    tracker = RecordingTracker(seed=0, alpha=alpha, generative_weight=0.0, **FAST)
    tracker.init(sequence.frame(0), sequence.init_box)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tracker.update(sequence.frame(1))
        tracker.sample_particles()
    coding = tracker.last_coding
    difference = coding.error_positive - coding.error_negative
    assert np.array_equal(tracker.state, tracker.particles[int(np.argmin(difference))])
    assert np.isfinite(tracker.last.log_confidence)


# -- presets and limits ------------------------------------------------------------------

def test_presets():
    paper = TrackerParams.paper()
    assert paper.template_sampling == "annulus" and paper.propagation == "condensation"
    # Every extension beyond the paper is off in the paper preset.
    assert (paper.redetect_count, paper.generative_weight) == (0, 0)
    assert TrackerParams.preset("default") == TrackerParams()
    assert TrackerParams.paper(alpha=3.0).alpha == 3.0
    with pytest.raises(ParameterError, match="preset 'nope'"):
        TrackerParams.preset("nope")


@pytest.mark.parametrize("changes, name", [
    (dict(n_particles=10_000_000), "n_particles"),
    (dict(n_negative=200_000), "n_negative"),
    (dict(negative_radius=1e300), "negative_radius"),
    (dict(motion_sigmas=(4, 4, 50, 0, 0, 0)), "motion_sigmas"),
    (dict(template_sampling="disc"), "template_sampling"),
    (dict(propagation="kalman"), "propagation"),
    (dict(translation_noise="km"), "translation_noise"),
    (dict(positive_sigma=-1.0), "positive_sigma"),
    (dict(negative_push=3.0), "negative_push"),
    (dict(redetect_count=-1), "redetect_count"),
    (dict(redetect_count=2.5), "redetect_count"),
    (dict(redetect_factor=0.5), "redetect_factor"),
    (dict(redetect_accept=0.0), "redetect_accept"),
    (dict(redetect_accept=float("nan")), "redetect_accept"),
])
def test_exhausting_or_unknown_parameters_are_refused_by_name(changes, name):
    with pytest.raises(ParameterError, match=f"parameter {name}"):
        TrackerParams(**changes)


# -- the API's input checks -------------------------------------------------------------

def test_frames_of_another_size_and_boxes_of_the_wrong_type_are_refused(sequence):
    tracker = NRMLCTracker(seed=0, **FAST)
    frame = sequence.frame(0)
    for box in ("10,10,20,20", {"x": 1, "y": 1, "w": 20, "h": 20}, 5, None):
        with pytest.raises(ParameterError, match="box"):
            tracker.init(frame, box)
    tracker.init(frame, sequence.init_box)
    with pytest.raises(ParameterError, match="init\\(\\) saw"):
        tracker.update(frame[:-2])
    with pytest.raises(ParameterError, match="box"):
        move_to(tracker, "1,2,3,4")


def test_pil_rgb_frames_track_like_numpy_frames(sequence):
    Image = pytest.importorskip("PIL.Image")
    from nrmlc.data.image import to_gray_float32

    frames = [sequence.color_frame(i) for i in range(6)]  # BGR uint8
    pil = [Image.fromarray(np.ascontiguousarray(f[:, :, ::-1])) for f in frames]
    gray = [np.asarray(p.convert("L")) for p in pil]
    by_pil = NRMLCTracker(seed=0, **FAST)
    by_gray = NRMLCTracker(seed=0, **FAST)
    by_pil.init(pil[0], sequence.init_box)
    by_gray.init(gray[0], sequence.init_box)
    for p, g in zip(pil[1:], gray[1:]):
        assert np.array_equal(by_pil.update(p), by_gray.update(g))
    assert to_gray_float32(gray[0]).shape == frames[0].shape[:2]


def test_param_tuples_with_empty_elements_are_refused():
    from nrmlc.tracker.params import parse_param_assignment

    assert parse_param_assignment("dictionary_sizes=5, 8") == ("dictionary_sizes", (5, 8))
    with pytest.raises(ParameterError, match="dictionary_sizes"):
        parse_param_assignment("dictionary_sizes=5,,8")


# -- positive replacement ----------------------------------------------------------------

def test_full_positive_set_replaces_the_closest(sequence):
    tracker = NRMLCTracker(seed=0, n_positive=3, max_positive=5,
                           update_error_threshold=4.0, occlusion_detection=False, **FAST)
    tracker.init(sequence.frame(0), sequence.init_box)
    result, _, _ = tracker.step(sequence.frame(1))
    noise = np.random.default_rng(0).standard_normal((3, 1024)).astype(np.float32) / 32
    first = tracker.positive_templates
    positives = np.vstack([first, noise[0], first[1] + 0.5 * noise[1]])
    tracker._set_templates(positives, tracker.negative_templates)
    # The new result is nearest to the first frame's template 1, then to later template 4.
    new = first[1] + 0.1 * noise[2]
    tracker.update_templates(sequence.frame(1), result, new[None, :])
    replaced = 1
    assert np.array_equal(tracker.positive_templates[replaced], new)
    untouched = [i for i in range(5) if i != replaced]
    assert np.array_equal(tracker.positive_templates[untouched], positives[untouched])


@pytest.mark.parametrize("name", ["patch_normalization", "dictionaries", "wide_share", "wide_factor",
                                  "estimate_count", "velocity_damping", "antialias", "keep_initial_positives",
                                  "scale_prior", "illumination_window", "features", "gray_weight",
                                  "held_scale_prior", "held_scale_prior_side", "hold_scale_lost_frames",
                                  "shrunk_negatives", "grown_negatives", "negative_refresh", "positive_batch",
                                  "patch_blocks", "expert_choice"])
def test_fields_measured_and_not_adopted_are_refused_with_a_pointer(name):
    from nrmlc.tracker.params import REMOVED_PARAMETERS, parse_param_assignment

    pattern = rf"unknown parameter '{name}'.*parameters measured and removed: {re.escape(REMOVED_PARAMETERS)}\)$"
    with pytest.raises(ParameterError, match=pattern):
        TrackerParams().replace(**{name: 0.5})
    with pytest.raises(ParameterError, match=pattern):
        parse_param_assignment(f"{name}=0.5")
    record = REPO_ROOT / REMOVED_PARAMETERS.split("#")[0]
    assert f"`{name}`" in record.read_text().split("## Parameters measured and removed")[1]
