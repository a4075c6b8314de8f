"""MTT (nrmlc.lineage.mtt) and its L21 APG solver (nrmlc.lineage.l21). Its bad box and
frame and its tracking are checked with the other template trackers' in test_lineage_template_trackers.py."""
import dataclasses

import numba
import numpy as np
import pytest

from nrmlc.errors import ParameterError
from nrmlc.testing import lineage
from nrmlc.lineage import TRACKERS
from nrmlc.lineage.l1apg import corners_to_state
from nrmlc.lineage.l21 import l21_apg, l21_apg_reference, l21_objective
from nrmlc.lineage.l1 import normalize_weights
from nrmlc.lineage.mtt import MTTParams, MTTTracker, box_corners
from nrmlc.workbench.otb_results import l1_affine_boxes

#: paraConfig_MTT.m's lambda, eta, obj_fun_th, iter_maxi.
AUTHORS = (0.01, 0.01, 1e-3, 100)


def _problem(rng, k, size, n, zero_rows=0, correlated=True):
    """Unit templates (near-duplicates when ``correlated``, as MTT's are) and unit signals near
    their span (the last ``zero_rows`` all zero, as a particle outside the frame)."""
    templates = rng.standard_normal((k, size))
    if correlated:
        templates = rng.standard_normal(size) + 0.2 * templates
    templates /= np.linalg.norm(templates, axis=1, keepdims=True)
    signals = rng.random((n, k)) @ templates + 0.3 * rng.standard_normal((n, size))
    signals /= np.linalg.norm(signals, axis=1, keepdims=True)
    if zero_rows:
        signals[-zero_rows:] = 0.0
    return np.ascontiguousarray(templates), np.ascontiguousarray(signals)


def _dense(targets):
    """``B = [D, I]`` (columns) of the template rows."""
    return np.hstack([targets.T, np.eye(targets.shape[1])])


def _kkt_violation(dictionary, signals, coefficients, lam):
    """The largest violation of the optimality conditions of min ||X - BC||_F^2 + lam sum_i ||C_i||_2:
    for each row ``i``, ``g_i + lam C_i / ||C_i|| = 0`` if ``C_i != 0``, else ``||g_i|| <= lam``,
    with ``g = 2 B'(BC - X)``."""
    gradient = 2.0 * dictionary.T @ (dictionary @ coefficients - signals)
    worst = 0.0
    for g, c in zip(gradient, coefficients):
        norm = np.linalg.norm(c)
        worst = max(worst, np.abs(g + lam * c / norm).max() if norm > 0 else np.linalg.norm(g) - lam)
    return worst


# --------------------------------------------------------------------------- the solver


@pytest.mark.parametrize("k, size, n, settings, zero_rows", [
    (10, 256, 70, AUTHORS, 0),                  # the authors' settings; stops on the objective
    (10, 1024, 24, AUTHORS, 3),                 # the authors' template size, a few particles outside
    (4, 40, 130, (0.3, 0.02, 0.0, 250), 0),     # more particles than one block; all steps
    (1, 7, 5, (0.0, 0.05, 1e-6, 400), 1),       # no penalty
    (6, 30, 64, (1.5, 0.01, 1e-4, 300), 0),     # a strong penalty: whole rows vanish
])
def test_l21_matches_the_dense_reference(k, size, n, settings, zero_rows):
    rng = np.random.default_rng(k * size + n)
    targets, signals = _problem(rng, k, size, n, zero_rows)
    lam, eta, tol, max_iter = settings
    target, trivial, steps = l21_apg(targets, signals, lam, eta, tol, max_iter)
    expected, expected_steps = l21_apg_reference(_dense(targets), signals.T, lam, eta, tol, max_iter)
    assert steps == expected_steps
    np.testing.assert_allclose(np.vstack([target.T, trivial.T]), expected, rtol=0, atol=1e-12)
    assert np.count_nonzero(target) > 0
    if zero_rows:
        assert np.all(target[-zero_rows:] == 0) and np.all(trivial[-zero_rows:] == 0)
    if lam == 1.5:
        vanished = np.all(trivial == 0, axis=0)
        assert 0 < np.count_nonzero(vanished) < size  # row sparsity, shared by every particle


def test_l21_authors_settings_stop_early_on_the_objective():
    rng = np.random.default_rng(3)
    targets, signals = _problem(rng, 10, 256, 70)
    _, _, steps = l21_apg(targets, signals, *AUTHORS)
    assert 5 < steps < AUTHORS[3]


@pytest.mark.parametrize("lam", [0.01, 0.3, 3.0])
def test_l21_converges_to_the_optimum_of_its_problem(lam):
    """With eta = 1 / (2 ||B'B||), no early stop and enough steps, the optimality conditions of
    ||X - BC||_F^2 + lam sum_i ||C_i||_2 hold."""
    rng = np.random.default_rng(4)
    targets, signals = _problem(rng, 4, 25, 12, correlated=False)
    dictionary = _dense(targets)
    eta = 0.5 / np.linalg.eigvalsh(dictionary.T @ dictionary).max()
    target, trivial, steps = l21_apg(targets, signals, lam, eta, 0.0, 20000)
    coefficients = np.vstack([target.T, trivial.T])
    assert _kkt_violation(dictionary, signals.T, coefficients, lam) < 1e-9
    rows = np.count_nonzero(np.any(coefficients != 0, axis=1))
    assert 0 < rows and (rows < len(coefficients) or lam < 1)  # a strong penalty zeroes whole rows
    # A nudge of any single row does not lower the objective.
    best = l21_objective(dictionary, signals.T, coefficients, lam)
    for row in (0, 5, 20):
        moved = coefficients.copy()
        moved[row] += 1e-4 * rng.standard_normal(moved.shape[1])
        assert l21_objective(dictionary, signals.T, moved, lam) >= best - 1e-12
    # The authors' settings stop well before the optimum, and the check above tells.
    target, trivial, _ = l21_apg(targets, signals, lam, *AUTHORS[1:])
    assert _kkt_violation(dictionary, signals.T, np.vstack([target.T, trivial.T]), lam) > 1e-3


def test_l21_edge_cases():
    rng = np.random.default_rng(5)
    targets, signals = _problem(rng, 3, 20, 4)
    target, trivial, steps = l21_apg(targets, signals, *AUTHORS[:3], 0)
    assert np.all(target == 0) and np.all(trivial == 0) and steps == 0
    target, trivial, steps = l21_apg(targets, np.zeros((2, 20)), *AUTHORS)
    assert np.all(target == 0) and np.all(trivial == 0) and steps == 1  # F stays 0: stops at once
    target, trivial, steps = l21_apg(targets, signals[:0].copy(), *AUTHORS)
    assert target.shape == (0, 3) and trivial.shape == (0, 20)


def test_l21_same_result_with_one_and_two_threads():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba was started with a single thread")
    rng = np.random.default_rng(6)
    targets, signals = _problem(rng, 10, 1024, 300, zero_rows=5)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = l21_apg(targets, signals, *AUTHORS)
        numba.set_num_threads(2)
        two = l21_apg(targets, signals, *AUTHORS)
    finally:
        numba.set_num_threads(before)
    assert one[2] == two[2]
    assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])


def test_l21_bad_input():
    targets, signals = np.ones((2, 5)), np.ones((3, 5))
    cases = [((targets, np.ones((3, 4)), *AUTHORS), "signals have 4 pixels"),
             ((targets.astype(np.float32), signals, *AUTHORS), "dtype"),
             ((np.ones((5, 2)).T, signals, *AUTHORS), "C-contiguous"),
             ((np.full((2, 5), np.inf), signals, *AUTHORS), "NaN or infinite"),
             ((targets, signals, -0.1, 0.01, 1e-3, 10), "lam"),
             ((targets, signals, 0.01, 0.0, 1e-3, 10), "eta must be > 0"),
             ((targets, signals, 0.01, 0.01, float("nan"), 10), "tol"),
             ((targets, signals, 0.01, 0.01, 1e-3, -1), "max_iter"),
             ((targets, signals, 0.01, 0.01, 1e-3, 2.5), "max_iter"),
             ((np.ones((0, 5)), signals, *AUTHORS), "at least one atom")]
    for arguments, message in cases:
        with pytest.raises(ParameterError, match=message) as info:
            l21_apg(*arguments)
        assert "\n" not in str(info.value)


# --------------------------------------------------------------------------- parameters and small steps


def test_params_are_the_authors_and_checked():
    p = MTTParams()
    assert (p.n_particles, p.template_size, p.n_templates) == (600, (32, 32), 10)
    assert p.affine_sigma == (0.005, 0.0005, 0.0005, 0.005, 4, 4)
    assert (p.lam, p.eta, p.objective_tolerance, p.max_iter) == AUTHORS
    assert (p.alpha, p.theta, p.max_weight) == (50.0, 0.6, 0.3)
    for change in (dict(n_particles=0), dict(n_particles=2.5), dict(n_templates=0), dict(n_templates=11),
                   dict(n_templates=True), dict(template_size=(32,)), dict(template_size=(1, 32)),
                   dict(template_size=(32.0, 32)), dict(affine_sigma=(1, 2)), dict(affine_sigma=(-1,) * 6),
                   dict(affine_sigma=("a",) * 6), dict(lam=-0.1), dict(lam=float("nan")), dict(eta=0.0),
                   dict(objective_tolerance=-1e-3), dict(max_iter=-1), dict(alpha=0.0), dict(theta=1.5),
                   dict(max_weight=0.0), dict(max_weight=0.05)):
        with pytest.raises(ParameterError, match="MTTParams") as info:
            MTTParams(**change)
        assert "\n" not in str(info.value)


def test_registered():
    assert TRACKERS["mtt"] == "nrmlc.lineage.mtt:MTTTracker"


@pytest.mark.parametrize("box", [(70, 51, 107, 87), (3, 4, 17, 9)])
def test_first_state_is_run_mtt_corners(box):
    x, y, w, h = box
    state = corners_to_state(box_corners(box), (32, 32))
    a11, a12, a21, a22, tr, tc = state
    np.testing.assert_allclose([a11 + a12 + tr, a21 + a22 + tc], [y, x], atol=1e-12)
    np.testing.assert_allclose([32 * a11 + a12 + tr, 32 * a21 + a22 + tc], [y + h, x], atol=1e-12)
    np.testing.assert_allclose([a11 + 32 * a12 + tr, a21 + 32 * a22 + tc], [y, x + w], atol=1e-12)
    # run_MTT.m's corners end one pixel further than the box: the toolkit's box is one larger
    np.testing.assert_array_equal(l1_affine_boxes(state[None], (32, 32))[0], (x, y, w + 1, h + 1))


def test_init_templates_are_init_templates_crops():
    """InitTemplates.m's ten corners (the box's, then r1 -1, r1 +1, r2 -1, r2 +1, r3 +1, c1 -1, c1 +1,
    c2 -1, c2 +1), each cropped and normalised as corner2image.m does."""
    rng = np.random.default_rng(15)
    frame = (rng.random((60, 70)) * 255).astype(np.uint8)
    tracker = MTTTracker(MTTParams(template_size=(8, 6)))
    tracker.init(frame, (20, 15, 24, 30))
    corners = box_corners((20, 15, 24, 30))
    moves = [(0, 0, -1), (0, 0, 1), (0, 1, -1), (0, 1, 1), (0, 2, 1), (1, 0, -1), (1, 0, 1), (1, 1, -1), (1, 1, 1)]
    for template, move in zip(tracker.templates, [None] + moves, strict=True):
        moved = corners.copy()
        if move is not None:
            moved[move[0], move[1]] += move[2]
        a11, a12, a21, a22, tr, tc = corners_to_state(moved, (8, 6))
        patch = np.empty((8, 6))
        for r in range(1, 9):
            for c in range(1, 7):
                y = np.floor(a11 * r + a12 * c + tr + 0.5)
                x = np.floor(a21 * r + a22 * c + tc + 0.5)
                patch[r - 1, c - 1] = frame[int(y) - 1, int(x) - 1]
        expected = (patch.ravel() - patch.mean()) / (patch.std(ddof=1) + 1e-14)
        np.testing.assert_allclose(template, expected / np.linalg.norm(expected), rtol=0, atol=1e-13)


def test_init_templates_are_whitened_unit_vectors():
    tracker = lineage.small_tracker(MTTTracker)
    np.testing.assert_allclose(tracker.templates.mean(axis=1), 0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(tracker.templates, axis=1), 1, rtol=1e-14)
    assert len({row.tobytes() for row in tracker.templates}) == 4
    np.testing.assert_array_equal(tracker.weights, 1.0)
    np.testing.assert_array_equal(tracker.samples, np.repeat(tracker.state[None], 40, axis=0))


def test_template_step_replaces_the_least_weighted_when_dissimilar():
    tracker = lineage.small_tracker(MTTTracker)
    size = 30
    rng = np.random.default_rng(16)
    answer = rng.standard_normal(size)
    answer -= tracker.templates[0] * (tracker.templates[0] @ answer)  # orthogonal to the strongest
    answer /= np.linalg.norm(answer)
    coefficients = np.array([0.9, 0.4, -0.2, 0.6])
    weights = np.exp(coefficients)
    median = np.median(np.array([weights[0], weights[1], 0.0, weights[3]]))
    tracker._update_templates(answer, coefficients)
    np.testing.assert_allclose(tracker.templates[2], answer / (1 + 1e-14), rtol=1e-15)
    expected = normalize_weights(np.array([weights[0], weights[1], median, weights[3]]), 0.3)
    np.testing.assert_allclose(tracker.weights, expected, rtol=1e-14)
    # a similar answer: the weights move, no template does
    templates = tracker.templates.copy()
    before = tracker.weights.copy()
    tracker._update_templates(templates[1] * 0.99 + 0.01 * templates[0], np.array([0.1, 0.8, 0.0, 0.0]))
    np.testing.assert_allclose(tracker.templates, templates, rtol=1e-13)
    np.testing.assert_allclose(tracker.weights, normalize_weights(before * np.exp([0.1, 0.8, 0.0, 0.0]), 0.3))
    np.testing.assert_allclose(np.linalg.norm(tracker.templates, axis=1), 1, rtol=1e-13)


def test_template_norm_weight_scales_each_template_to_its_weight():
    """The L1 tracker's form (``template_norm='weight'``, the departure's switch back): after a
    template step each template's norm is its weight; the shipped form keeps unit norm."""
    rng = np.random.default_rng(17)
    for form in ("unit", "weight"):
        tracker = MTTTracker(dataclasses.replace(lineage.small_params(MTTTracker), template_norm=form))
        tracker.init((np.random.default_rng(14).random((40, 50)) * 255).astype(np.uint8), (10, 12, 15, 18))
        tracker._update_templates(rng.standard_normal(tracker.templates.shape[1]), np.array([0.9, 0.4, -0.2, 0.6]))
        norms = np.linalg.norm(tracker.templates, axis=1)
        np.testing.assert_allclose(norms, tracker.weights if form == "weight" else 1.0, rtol=1e-12)
        assert form == "unit" or norms.max() < 0.5
    with pytest.raises(ParameterError, match="template_norm"):
        MTTParams(template_norm="none")
