"""L1 (nrmlc.lineage.l1) and its lasso over target and trivial templates. Its bad box and
frame and its tracking are checked with the other template trackers' in test_lineage_template_trackers.py."""
import numba
import numpy as np
import pytest

import nrmlc.lineage.l1 as l1
from nrmlc.errors import ParameterError
from nrmlc.lineage import TRACKERS
from nrmlc.lineage.l1 import (TEMPLATE_SHIFTS, L1Params, L1Tracker, images_angle, normalize_weights,
                              trivial_lasso, trivial_lasso_reference)
from nrmlc.lineage.l1apg import box_corners, corners_to_state
from nrmlc.lineage.lasso import SPAMS_RIDGE, lasso_nonnegative

LAM = 0.01


def _problem(rng, k, size, n, duplicate_fixed=True):
    """L1's shapes: near-duplicate templates of unequal norms, the fixed template parallel to the
    first (as it is until the first is replaced), unit signals near their span, a few pure noise."""
    base = rng.standard_normal(size)
    templates = base + 0.15 * rng.standard_normal((k, size))
    templates /= np.linalg.norm(templates, axis=1, keepdims=True)
    templates[:-1] *= 0.05 + 0.25 * rng.random((k - 1, 1))
    if duplicate_fixed and k > 1:
        templates[-1] = templates[0] / np.linalg.norm(templates[0]) / (k - 1)
    signals = 5 * rng.random((n, k - 1)) @ templates[:-1] + 0.3 * rng.standard_normal((n, size)) / np.sqrt(size)
    signals[: max(1, n // 10)] = rng.standard_normal((max(1, n // 10), size))
    signals /= np.linalg.norm(signals, axis=1, keepdims=True)
    return np.ascontiguousarray(templates), np.ascontiguousarray(signals)


def _kkt_violation(targets, signal, a, e, lam, ridge):
    """Largest violation of the lasso's optimality conditions over the atoms ``[T, I]``."""
    residual = signal - a @ targets - e
    correlation = np.concatenate([targets @ residual - ridge * a, residual - ridge * e])
    coefficients = np.concatenate([a, e])
    nonzero = coefficients != 0
    return max(np.abs(correlation[nonzero] - lam * np.sign(coefficients[nonzero])).max(initial=0.0),
               (np.abs(correlation[~nonzero]) - lam).max(initial=0.0))


# ------------------------------------------------------------------ the solver


@pytest.mark.parametrize("k, size, n, ridge, seed", [
    (11, 180, 40, SPAMS_RIDGE, 0), (11, 180, 40, 0.0, 1), (4, 30, 25, SPAMS_RIDGE, 2), (1, 5, 7, 1e-3, 3),
    (2, 5, 9, SPAMS_RIDGE, 7),
    (11, 60, 20, 0.5, 4)])
def test_solver_is_optimal_and_matches_its_reference(k, size, n, ridge, seed):
    rng = np.random.default_rng(seed)
    targets, signals = _problem(rng, k, size, n, duplicate_fixed=ridge > 0)
    a, e, steps = trivial_lasso(targets, signals, LAM, ridge, return_steps=True)
    assert (steps >= 0).all()
    for i in range(n):
        assert _kkt_violation(targets, signals[i], a[i], e[i], LAM, ridge) < 1e-12
    ra, re = trivial_lasso_reference(targets, signals, LAM, ridge)
    np.testing.assert_allclose(a, ra, rtol=0, atol=1e-10)
    np.testing.assert_allclose(e, re, rtol=0, atol=1e-12)


def test_solver_matches_the_nonnegative_lasso_on_plus_and_minus_atoms():
    """An independent exact method: ``lasso.py``'s active-set solver on ``[D, -D]``, ``D = [T, I]``."""
    rng = np.random.default_rng(5)
    targets, signals = _problem(rng, 11, 60, 12)
    a, e = trivial_lasso(targets, signals, LAM)
    k, size = targets.shape
    atoms = np.hstack([targets.T, np.eye(size)])
    split = lasso_nonnegative(np.ascontiguousarray(signals.T), np.ascontiguousarray(np.hstack([atoms, -atoms])),
                              LAM, ridge=SPAMS_RIDGE)
    signed = (split[: k + size] - split[k + size:]).T
    np.testing.assert_allclose(a, signed[:, :k], rtol=0, atol=1e-9)
    np.testing.assert_allclose(e, signed[:, k:], rtol=0, atol=1e-9)


def test_solver_closed_forms():
    targets = np.ascontiguousarray(np.eye(2, 4))
    # a signal in no template's direction: only trivial coefficients, soft-thresholded
    signal = np.array([[0.0, 0.0, 0.5, -0.004]])
    a, e = trivial_lasso(targets, signal, LAM, ridge=0.0)
    np.testing.assert_array_equal(a, [[0.0, 0.0]])
    np.testing.assert_allclose(e, [[0.0, 0.0, 0.49, 0.0]], atol=1e-15)
    # the zero signal
    a, e = trivial_lasso(targets, np.zeros((1, 4)), LAM)
    assert not a.any() and not e.any()
    # one template's direction: the template and its pixel's trivial atom share the signal
    a, e = trivial_lasso(targets, np.array([[0.3, 0.0, 0.0, 0.0]]), LAM, ridge=0.0)
    assert _kkt_violation(targets, np.array([0.3, 0, 0, 0.0]), a[0], e[0], LAM, 0.0) < 1e-14
    assert a[0, 0] + e[0, 0] == pytest.approx(0.29)
    assert trivial_lasso(targets, np.zeros((0, 4)), LAM)[0].shape == (0, 2)


def test_solver_same_result_with_one_and_two_threads():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba was started with a single thread")
    targets, signals = _problem(np.random.default_rng(6), 11, 180, 300)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = trivial_lasso(targets, signals, LAM)
        numba.set_num_threads(2)
        two = trivial_lasso(targets, signals, LAM)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(one[0], two[0])
    np.testing.assert_array_equal(one[1], two[1])


@pytest.mark.parametrize("args, message", [
    ((np.ones((2, 3), dtype=np.float32), np.ones((1, 3)), LAM), "targets must have dtype float64"),
    ((np.ones((2, 3)), np.ones((1, 4)), LAM), "signals have 4 pixels, targets have 3"),
    ((np.ones((0, 3)), np.ones((1, 3)), LAM), "at least one atom"),
    ((np.ones((2, 3)), np.full((1, 3), np.nan), LAM), "signals"),
    ((np.ones((2, 3)), np.ones((1, 3)), 0.0), "lam must be > 0"),
    ((np.ones((2, 3)), np.ones((1, 3)), LAM, -1.0), "ridge"),
    ((np.asfortranarray(np.ones((2, 3))), np.ones((1, 3)), LAM), "C-contiguous"),
])
def test_solver_bad_input(args, message):
    with pytest.raises(ParameterError, match=message):
        trivial_lasso(*args)


# ------------------------------------------------------------------ the template step's parts


def test_normalize_weights_caps_at_the_share_and_sums_to_one():
    np.testing.assert_allclose(normalize_weights(np.array([1.0, 1.0, 2.0]), 0.5), [0.25, 0.25, 0.5])
    capped = normalize_weights(np.array([50.0] + [1.0] * 9), 0.3)
    assert capped.sum() == pytest.approx(1.0) and capped.max() <= 0.3
    np.testing.assert_allclose(capped[1:], capped[1])  # the others keep their ratios
    assert capped[0] == pytest.approx(0.3)
    # three capped and the rest 0: MATLAB's loop never ends; ours stops
    stuck = normalize_weights(np.array([1.0, 1.0, 1.0, 0.0]), 0.3)
    assert np.isfinite(stuck).all()


def test_images_angle_is_the_plain_angle():
    assert images_angle(np.array([1.0, 0.0]), np.array([0.0, 2.0])) == pytest.approx(90.0)
    assert images_angle(np.array([1.0, 1.0]), np.array([3.0, 3.0])) == pytest.approx(0.0, abs=1e-6)
    assert images_angle(np.array([1.0, 0.0]), np.array([-1.0, 0.0])) == pytest.approx(180.0)
    assert np.isnan(images_angle(np.zeros(2), np.ones(2)))


def test_params_are_the_authors_and_checked():
    p = L1Params()
    assert (p.n_particles, p.template_size, p.n_templates, p.lam, p.alpha, p.angle_threshold, p.weight_cap) == \
        (600, (12, 15), 10, 0.01, 30.0, 60.0, 0.3)
    assert p.affine_sigma == (0.005, 0.0005, 0.0005, 0.005, 1.0, 1.0)
    for kwargs, message in [({"n_particles": 0}, "n_particles"), ({"n_templates": 11}, "n_templates"),
                            ({"n_templates": True}, "n_templates"), ({"template_size": (1, 15)}, "template_size"),
                            ({"affine_sigma": (1.0,) * 5}, "affine_sigma"), ({"lam": 0.0}, "lam"),
                            ({"alpha": float("nan")}, "alpha"), ({"angle_threshold": 181.0}, "angle_threshold"),
                            ({"weight_cap": 0.05}, "weight_cap")]:
        with pytest.raises(ParameterError, match=f"L1Params.{message}") as caught:
            L1Params(**kwargs)
        assert "\n" not in str(caught.value)


def test_registered():
    assert TRACKERS["l1"] == "nrmlc.lineage.l1:L1Tracker"


# ------------------------------------------------------------------ the tracker


def _frame(seed=0, shape=(120, 160)):
    rng = np.random.default_rng(seed)
    return (rng.random(shape) * 255).astype(np.uint8)


def test_init_templates_follow_init_templates_m():
    frame = _frame()
    box = np.array([40.0, 30.0, 45.0, 36.0])
    tracker = L1Tracker(seed=0)
    tracker.init(frame, box)
    corners = box_corners(box)
    expected = np.array([corners_to_state(corners + shift, (12, 15)) for shift in TEMPLATE_SHIFTS])
    assert not np.array_equal(expected[1], expected[0])
    # the fixed template is the first (unweighted) over ten: unit norm / 10, at the box
    assert np.linalg.norm(tracker.fixed) == pytest.approx(0.1)
    first = l1._zmuv_unit(l1.crop_patches(frame.astype(np.float64), expected[:1], (12, 15))[0].reshape(1, -1))[0]
    np.testing.assert_allclose(tracker.fixed, first / 10, atol=1e-14)
    # after the first frame's step: weights sum to 1, none above the cap, templates scaled to them
    assert tracker.weights.sum() == pytest.approx(1.0) and tracker.weights.max() <= 0.3 + 1e-15
    np.testing.assert_allclose(np.linalg.norm(tracker.templates, axis=1), tracker.weights, rtol=1e-12)


def test_template_step_replaces_the_lightest_above_the_angle():
    tracker = L1Tracker(seed=0)
    tracker.init(_frame(), [40, 30, 45, 36])
    weights = tracker.weights.copy()
    templates = tracker.templates.copy()
    coefficients = np.linspace(0.1, 0.5, 10)
    coefficients[3] = 2.0
    orthogonal = np.zeros(180)
    orthogonal[0], orthogonal[1] = 1.0, -1.0
    orthogonal -= (orthogonal @ templates[3]) / (templates[3] @ templates[3]) * templates[3]
    orthogonal /= np.linalg.norm(orthogonal)
    tracker._update_templates(orthogonal, coefficients)
    raised = weights * np.exp(coefficients)
    lightest = int(np.argmin(raised))
    assert lightest == 0
    raised[lightest] = 0.0
    raised[lightest] = np.median(raised)
    np.testing.assert_allclose(tracker.weights, normalize_weights(raised, 0.3), rtol=1e-15)
    np.testing.assert_allclose(tracker.templates[0] / np.linalg.norm(tracker.templates[0]), orthogonal, atol=1e-12)
    # below the angle: weights move, no template changes direction
    again = tracker.templates.copy()
    tracker._update_templates(again[3] / np.linalg.norm(again[3]), coefficients)
    np.testing.assert_allclose(tracker.templates / np.linalg.norm(tracker.templates, axis=1, keepdims=True),
                               again / np.linalg.norm(again, axis=1, keepdims=True), atol=1e-12)
