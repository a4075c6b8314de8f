"""The tracker: interface, parameters, and the paper's problems resolved (docs/DEVIATIONS.md)."""
import numpy as np
import pytest

from nrmlc import NRMLCTracker, TrackerParams
from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.errors import ParameterError
from nrmlc.workbench.metrics import evaluate
from nrmlc.tracker import track_sequence
from nrmlc.tracker.records import Coding

from experiments.instrumented import RecordingTracker, move_to, track_instrumented

FAST = dict(n_particles=150)


@pytest.fixture(scope="module")
def sequence():
    return SyntheticSequence(SyntheticSpec(name="t", seed=3, n_frames=40))


@pytest.fixture(scope="module")
def tracked(sequence):
    return track_sequence(sequence, TrackerParams(**FAST), seed=0)


def _after_a_few_frames(sequence, **changes):
    """A tracker after a few frames, and the candidates of its last frame."""
    tracker = RecordingTracker(seed=0, **FAST, **changes)
    tracker.init(sequence.frame(0), sequence.init_box)
    for index in range(1, 8):
        tracker.update(sequence.frame(index))
    return tracker, tracker.last_coding.patches


@pytest.fixture(scope="module")
def coded_frame(sequence):
    return _after_a_few_frames(sequence)


def test_got10k_interface_tracks_the_synthetic_target(sequence, tracked):
    assert tracked.boxes.shape == (len(sequence), 4)
    np.testing.assert_allclose(tracked.boxes[0], sequence.init_box)
    scores = evaluate(tracked.boxes, sequence.groundtruth)
    # a static box would score far lower: the target moves ~4 px/frame
    static = evaluate(np.tile(sequence.init_box, (len(sequence), 1)), sequence.groundtruth)
    # measured 0.82: a loss of 0.1 fails
    assert scores.mean_overlap > 0.71 and scores.mean_overlap > static.mean_overlap + 0.2


def test_paper_defaults():
    p = TrackerParams.paper()
    assert (p.n_positive, p.n_negative, p.dictionary_sizes) == (50, 150, (5, 8, 10))
    assert (p.lam, p.beta, p.n_iterations, p.alpha) == (1.0, 0.1, 3, 2.5)
    assert (p.update_interval, p.max_positive, p.update_error_threshold, p.patch_size) == (5, 100, 0.1, 32)


def test_every_departure_of_the_default_from_the_paper_is_documented():
    """A field in which TrackerParams() differs from TrackerParams.paper() has its entry in
    docs/DEVIATIONS.md (by name, in backticks)."""
    from pathlib import Path

    deviations = (Path(__file__).resolve().parents[1] / "docs" / "DEVIATIONS.md").read_text()
    default, paper = TrackerParams().as_dict(), TrackerParams.paper().as_dict()
    differing = sorted(name for name in default if default[name] != paper[name])
    assert {"template_sampling", "redetect_count", "alpha"} <= set(differing)
    assert [name for name in differing if f"`{name}`" not in deviations] == []


def test_every_field_is_in_exactly_one_group_and_in_the_stage_order():
    """The groups (the paper's, then each addition's) hold each field of TrackerParams once, the
    paper's at most 25; STAGE_ORDER, the order as_dict gives, names each once."""
    import dataclasses

    from nrmlc.tracker.params import GROUPS, STAGE_ORDER

    grouped = [f.name for group in GROUPS.values() for f in dataclasses.fields(group)]
    assert sorted(grouped) == sorted(f.name for f in dataclasses.fields(TrackerParams))
    assert sorted(STAGE_ORDER) == sorted(grouped) and len(dataclasses.fields(GROUPS["paper"])) <= 25


def test_same_seed_same_boxes_and_different_seeds_differ(sequence, tracked):
    again = track_sequence(sequence, TrackerParams(**FAST), seed=0, n_frames=15)
    assert np.array_equal(again.boxes, tracked.boxes[:15])
    other = track_sequence(sequence, TrackerParams(**FAST), seed=1, n_frames=15)
    assert not np.array_equal(other.boxes, tracked.boxes[:15])


def test_diagnostics_are_complete_and_finite(tracked):
    d = tracked.diagnostics
    for name in ("confidence", "error_positive", "error_negative"):
        assert np.all(np.isfinite(d[name][1:])), name
    # The negative shares are figures' diagnostics: recorded only on request.
    assert "negative_share_c" not in d
    assert d["codes"].shape[1:] == (10,) and d["coefficients"].shape[1:] == (3, 10)
    # the code's positive/negative split adds up to the whole code
    np.testing.assert_allclose(d["code_sum_positive"][1:] + d["code_sum_negative"][1:], d["codes"][1:].sum(axis=1))


@pytest.mark.parametrize("changes, name", [
    (dict(dictionary_sizes=(5, 8, 300)), "dictionary_sizes"),
    (dict(lam=-1.0), "lam"),
    (dict(beta=-0.1), "beta"),
    (dict(n_particles=0), "n_particles"),
    (dict(coding="lasso"), "coding"),
    (dict(confidence="other"), "confidence"),
    (dict(motion_sigmas=(1, 2, 3)), "motion_sigmas"),
    (dict(positive_radius=20.0), "negative_radius"),
])
def test_invalid_parameters_name_the_parameter(changes, name):
    with pytest.raises(ParameterError, match=name):
        TrackerParams(**changes)


def test_unknown_parameter_is_named():
    with pytest.raises(ParameterError, match="bogus"):
        NRMLCTracker(seed=0, bogus=1)


def test_update_before_init_is_an_error():
    with pytest.raises(ParameterError, match="init"):
        NRMLCTracker().update(np.zeros((20, 20), np.float32))


def test_recentring_moves_the_estimate_every_period(sequence):
    """With no motion noise every particle is the current state, so each frame's box is where the
    estimate was put: the initial box until the first re-centring (after frame 3), then the given box."""
    params = TrackerParams(n_particles=5, motion_sigmas=(0, 0, 0, 0, 0, 0))
    target = np.array([30.0, 20.0, 24.0, 18.0])
    result = track_instrumented(sequence, params, seed=0, n_frames=8, recentre_boxes=np.tile(target, (8, 1)),
                                recentre_every=3)
    np.testing.assert_allclose(result.boxes[1:4], np.tile(sequence.init_box, (3, 1)), atol=1e-9)
    np.testing.assert_allclose(result.boxes[4:8], np.tile(target, (4, 1)), atol=1e-9)
    plain = track_instrumented(sequence, TrackerParams(**FAST), seed=0, n_frames=10, recentre_every=0)
    assert np.array_equal(plain.boxes, track_sequence(sequence, TrackerParams(**FAST), seed=0, n_frames=10).boxes)


@pytest.mark.parametrize("kwargs, match", [
    (dict(recentre_every=-1), "recentre_every"),
    (dict(recentre_every=2), "recentre_boxes"),
    (dict(recentre_every=2, recentre_boxes=np.ones((3, 3))), "recentre_boxes"),
])
def test_recentring_arguments_are_checked(sequence, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        track_instrumented(sequence, TrackerParams(**FAST), seed=0, n_frames=3, **kwargs)


def test_move_to_checks_its_box(sequence):
    tracker = NRMLCTracker(seed=0, **FAST)
    with pytest.raises(ParameterError, match="init"):
        move_to(tracker, (1, 1, 10, 10))
    tracker.init(sequence.frame(0), sequence.init_box)
    for box in ((1, 1, 0, 10), (1, np.nan, 10, 10), (1, 2, 3)):
        with pytest.raises(ParameterError, match="box"):
            move_to(tracker, box)


# -- the paper's problems (see docs/DEVIATIONS.md) -----------------------------------

def test_problem1_literal_confidence_prefers_the_worst_candidate(sequence):
    """Eq. (conf) as printed, 1/exp(-a(e_pos - e_neg)), ranks candidates in reverse (the
    paper's confidence alone: the generative term would add the same to both)."""
    tracker, patches = _after_a_few_frames(sequence, generative_weight=0.0)
    corrected = tracker.encode(patches).log_confidence
    tracker.params = tracker.params.replace(confidence="literal")
    try:
        literal = tracker.encode(patches).log_confidence
    finally:
        tracker.params = tracker.params.replace(confidence="corrected")
    np.testing.assert_allclose(literal + corrected, 0.0, atol=1e-12)
    assert np.argmax(literal) == np.argmin(corrected)


def test_problem1_literal_confidence_loses_the_target(sequence, tracked):
    literal = track_sequence(sequence, TrackerParams(confidence="literal", **FAST), seed=0)
    assert evaluate(literal.boxes, sequence.groundtruth).mean_overlap < 0.3
    assert evaluate(tracked.boxes, sequence.groundtruth).mean_overlap > 0.71  # measured 0.82


def test_problem2_printed_closed_form_does_not_sum_to_one(coded_frame):
    """c = (A'A + lam I)^-1 1 needs rescaling; the rescaled c is the constrained minimiser."""
    tracker, patches = coded_frame
    y = patches[0].astype(np.float64)
    coded = tracker.encode(patches)
    basis = tracker.templates[coded.neighbours[0, :5]].astype(np.float64).T  # (1024, 5)
    a = basis - y[:, None]
    f = a.T @ a + 1.0 * np.eye(5)
    printed = np.linalg.solve(f, np.ones(5))
    assert abs(printed.sum() - 1) > 0.5  # the printed form is far from sum-to-one
    rescaled = printed / printed.sum()
    np.testing.assert_allclose(coded.coefficients[0, 0, :5], rescaled, rtol=1e-4, atol=1e-6)
    # and it minimises ||y - Bc||^2 + lam ||c||^2 over 1'c = 1: any feasible step increases it
    objective = lambda c: np.sum((y - basis @ c) ** 2) + np.sum(c**2)
    rng = np.random.default_rng(0)
    for _ in range(20):
        step = rng.normal(size=5)
        step -= step.mean()
        assert objective(rescaled + 1e-3 * step) > objective(rescaled)


def test_problem3_algorithm1_is_at_its_fixed_point_after_one_step(coded_frame):
    """w's problem (eq. allcw) does not depend on d: T = 2, 3, 10 give the same codes."""
    tracker, patches = coded_frame
    original = tracker.params
    results = {}
    try:
        for iterations in (1, 2, 3, 10):
            tracker.params = original.replace(n_iterations=iterations)
            results[iterations] = tracker.encode(patches)
    finally:
        tracker.params = original
    for iterations in (3, 10):
        assert np.array_equal(results[iterations].codes, results[2].codes)
        assert np.array_equal(results[iterations].weights, results[2].weights)
    # T = 1 outputs d computed with the initial uniform w (step 3.1 before 3.2)
    uniform = (results[1].coefficients).mean(axis=1)
    np.testing.assert_allclose(results[1].codes, uniform, atol=1e-12)
    assert not np.allclose(results[1].codes, results[2].codes)


def test_problem4_occlusion_threshold_is_a_parameter(coded_frame):
    tracker, _ = coded_frame
    assert tracker.params.occlusion_max_negative == TrackerParams().occlusion_max_negative
    last = tracker.last
    assert last.occluded == (last.n_negative_used > tracker.params.occlusion_max_negative)


def test_problem5_errors_are_squared_distances_of_unit_vectors(coded_frame):
    tracker, patches = coded_frame
    coded = tracker.encode(patches)
    n_pos = len(tracker.positive_templates)
    i = int(np.argmax(coded.log_confidence))
    d = np.zeros(len(tracker.templates))
    d[coded.neighbours[i]] = coded.codes[i]
    y = patches[i].astype(np.float64)
    templates = tracker.templates.astype(np.float64)
    e_pos = np.sum((y - templates[:n_pos].T @ d[:n_pos]) ** 2)
    e_neg = np.sum((y - templates[n_pos:].T @ d[n_pos:]) ** 2)
    np.testing.assert_allclose([coded.error_positive[i], coded.error_negative[i]], [e_pos, e_neg], atol=1e-5)
    assert np.all((coded.error_positive >= -1e-9) & (coded.error_positive <= 4 + 1e-9))


def test_positive_set_is_capped_and_replaces_the_closest(sequence):
    tracker = RecordingTracker(seed=0, n_particles=50, n_positive=3, max_positive=4, update_interval=1,
                               update_error_threshold=4.0, occlusion_detection=False)
    tracker.init(sequence.frame(0), sequence.init_box)
    # Here the estimates stay nearest the first positive template: moved to the middle, the
    # closest row is neither the oldest nor the newest (the idea of test_propagation.py's
    # test_full_positive_set_replaces_the_closest, on real estimates).
    tracker._set_templates(tracker.positive_templates[[1, 0, 2]], tracker.negative_templates)
    counts, replaced = [], []
    for index in range(1, 7):
        before = tracker.positive_templates.copy()
        tracker.update(sequence.frame(index))
        counts.append(len(tracker.positive_templates))
        assert tracker.last.updated_positive
        coding = tracker.last_coding
        new = coding.patches[int(np.argmax(coding.log_confidence))]  # this frame's estimate
        after = tracker.positive_templates
        if len(before) < 4:  # below the cap: appended
            np.testing.assert_array_equal(after, np.vstack([before, new]))
            continue
        # At the cap: exactly one row changed, to the estimate, and it is the row that was
        # closest to the estimate (not the oldest, not the last added).
        changed = np.flatnonzero(np.any(after != before, axis=1))
        distances = ((before.astype(np.float64) - new) ** 2).sum(axis=1)
        assert changed.tolist() == [int(np.argmin(distances))], distances
        np.testing.assert_array_equal(after[changed[0]], new)
        replaced.append(int(changed[0]))
    assert counts == [4, 4, 4, 4, 4, 4]
    assert set(replaced) - {0, 3}  # a rule replacing the first or the last row would have failed


@pytest.mark.parametrize("max_positive, threshold", [(4, 4.0), (60, 4.0), (60, 0.0)])
def test_carried_template_gram_is_the_gram_of_the_templates(sequence, max_positive, threshold):
    """The Gram each update carries over (positives replaced at the cap, appended below it,
    or unchanged) equals the Gram of the template set computed afresh, up to float32 rounding."""
    from nrmlc.kernels.distance import template_gram

    tracker = NRMLCTracker(seed=0, n_particles=50, n_positive=3, max_positive=max_positive,
                           update_interval=1, update_error_threshold=threshold, occlusion_detection=False)
    tracker.init(sequence.frame(0), sequence.init_box)
    for index in range(1, 8):
        tracker.update(sequence.frame(index))
        gram = tracker.template_gram
        np.testing.assert_array_equal(gram, gram.T)
        np.testing.assert_allclose(gram, template_gram(tracker.templates), rtol=0, atol=2e-6)
        np.testing.assert_array_equal(tracker.template_sq_norms, np.diag(gram))
    assert len(tracker.positive_templates) == (4 if max_positive == 4 else 10 if threshold else 3)


def test_occlusion_blocks_positive_updates(sequence):
    """Over real frames: with detection on, the positives grow on exactly the frames not judged
    occluded (some frames must be, for the test to mean anything); with it off, on every frame.
    Three positives leave negatives in every dictionary of 5 or more atoms, so codes use them."""
    kwargs = dict(n_particles=50, n_positive=3, update_interval=1, update_error_threshold=4.0,
                  occlusion_max_negative=0, coefficient_tolerance=0.0)
    blocked = NRMLCTracker(seed=0, **kwargs)
    free = NRMLCTracker(seed=0, occlusion_detection=False, **kwargs)
    occluded = []
    for tracker in (blocked, free):
        tracker.init(sequence.frame(0), sequence.init_box)
        for index in range(1, 6):
            tracker.update(sequence.frame(index))
            if tracker is blocked:
                occluded.append(tracker.last.occluded)
    assert any(occluded), "no frame judged occluded: the test checks nothing"
    assert len(blocked.positive_templates) == 3 + occluded.count(False)
    assert len(free.positive_templates) == 3 + 5


def test_occlusion_threshold_below_zero_is_refused():
    with pytest.raises(ParameterError, match="parameter occlusion_max_negative: must be in 0..10000, got -1"):
        TrackerParams(occlusion_max_negative=-1)


def _coding_of_one(tracker: NRMLCTracker, patch: np.ndarray, negative_codes: list) -> Coding:
    """A hand-built :class:`Coding` of one candidate (``patch``) whose code is ``negative_codes`` on
    negative templates 0, 1, ... and the rest of the unit sum spread over positive templates."""
    p = tracker.params
    k, n_pos = p.k_max, len(tracker.positive_templates)
    n_neg = len(negative_codes)
    neighbours = np.concatenate([np.arange(k - n_neg), n_pos + np.arange(n_neg)]).astype(np.int64)
    codes = np.concatenate([np.full(k - n_neg, (1.0 - sum(negative_codes)) / (k - n_neg)), negative_codes])
    m = len(p.dictionary_sizes)
    return Coding(patches=patch[None, :], dots=patch[None, :].astype(np.float64) @ tracker.templates.T,
                  neighbours=neighbours[None, :], coefficients=np.tile(codes, (1, m, 1)),
                  weights=np.full((1, m), 1.0 / m), codes=codes[None, :], error_positive=np.array([0.01]),
                  error_negative=np.array([0.9]), log_confidence=np.array([-2.0]))


@pytest.mark.parametrize("used, occluded", [(2, False), (3, True)])
def test_occlusion_rule_at_its_edge(sequence, used, occluded):
    """Algorithm 2's LEN(neg*) > 2: the best code on exactly 2 negative templates (above
    ``coefficient_tolerance``, either sign) is no occlusion and the estimate joins the positives;
    on 3 it is, and the positives stay as they were. A negative code at the tolerance itself is
    not counted."""
    tracker = NRMLCTracker(seed=0, n_particles=20, n_positive=10, n_negative=20, max_positive=20,
                           update_error_threshold=0.1)
    p = tracker.params
    assert p.occlusion_max_negative == 2 == TrackerParams.paper().occlusion_max_negative
    assert p.occlusion_detection
    tracker.init(sequence.frame(0), sequence.init_box)
    frame = sequence.frame(1)
    patch = tracker.patches(frame, tracker.state[None, :])[0]
    above = [0.05, -0.03, 0.02][:used]
    coding = _coding_of_one(tracker, patch, above + [p.coefficient_tolerance, -p.coefficient_tolerance])
    result = tracker._result(coding, 0, searched=False, redetected=False)
    assert result.n_negative_used == used
    assert result.occluded is occluded
    before = tracker.positive_templates.copy()
    tracker.update_templates(frame, result, patch[None, :])
    assert result.updated_positive is not occluded
    if occluded:
        np.testing.assert_array_equal(tracker.positive_templates, before)
    else:
        assert len(tracker.positive_templates) == len(before) + 1
        np.testing.assert_array_equal(tracker.positive_templates[:-1], before)
        np.testing.assert_array_equal(tracker.positive_templates[-1], patch)


@pytest.mark.parametrize("coding", ["constrained", "plain"])
def test_other_coding_modes_track(sequence, coding):
    result = track_instrumented(sequence, TrackerParams(coding=coding, **FAST), seed=0, n_frames=20,
                                record_negative_shares=True)
    assert np.all(np.isfinite(result.boxes))
    if coding == "constrained":
        assert np.all(result.diagnostics["negative_share_c"][1:] == 0)
        assert np.all(result.diagnostics["negative_share_w"][1:] == 0)


def test_a_misspelt_parameter_gets_a_suggestion():
    from nrmlc.tracker.params import parse_param_assignment

    with pytest.raises(ParameterError, match=r"unknown parameter 'lamda'; did you mean lam\?"):
        parse_param_assignment("lamda=0.5")
    with pytest.raises(ParameterError, match=r"'n_particle'; did you mean n_particles\?"):
        TrackerParams().replace(n_particle=10)
    with pytest.raises(ParameterError, match=r"unknown parameter 'zzz' \("):
        parse_param_assignment("zzz=1")
