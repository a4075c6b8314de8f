"""L1-APG (nrmlc.lineage.l1apg) and its APG solver (nrmlc.lineage.apg). Its crop is
checked in test_lineage.py; its bad box and frame and its tracking with the other template trackers' in
test_lineage_template_trackers.py."""
import numba
import numpy as np
import pytest

import nrmlc.lineage.l1apg as l1apg
from nrmlc.errors import ParameterError
from nrmlc.testing import lineage
from nrmlc.lineage import TRACKERS
from nrmlc.lineage.apg import apg_lasso, apg_lasso_reference
from nrmlc.lineage.l1apg import (L1APGParams, L1APGTracker, box_corners, corners_to_state, images_angle,
                                 largest_occluded_region, resample_states, whiten)
from nrmlc.workbench.otb_results import l1_affine_boxes

AUTHORS_LAMBDAS = (0.01, 0.001, 1.0)


def _problem(rng, n_templates, size, n, correlated=False):
    """Unit templates (near-duplicates when ``correlated``, as L1-APG's are), the fixed template
    (the first over ``n_templates``) and unit signals near the templates' span."""
    if correlated:
        templates = rng.standard_normal(size) + 0.2 * rng.standard_normal((n_templates, size))
    else:
        templates = rng.standard_normal((n_templates, size))
    templates /= np.linalg.norm(templates, axis=1, keepdims=True)
    targets = np.ascontiguousarray(np.vstack([templates, templates[:1] / n_templates]))
    signals = rng.random((n, n_templates)) @ templates + 0.3 * rng.standard_normal((n, size))
    signals /= np.linalg.norm(signals, axis=1, keepdims=True)
    return targets, np.ascontiguousarray(signals)


def _dense(targets):
    """``APGLASSOup.m``'s dictionary ``[T, I, f]`` (columns) of the target rows ``[T; f]``."""
    size = targets.shape[1]
    return np.hstack([targets[:-1].T, np.eye(size), targets[-1:].T])


def _as_matlab(target, trivial):
    """Our (target, trivial) coefficients in ``[T, I, f]`` order."""
    return np.concatenate([target[:-1], trivial, target[-1:]])


def _kkt_violation(targets, signal, target, trivial, lambdas):
    """The largest violation of the optimality conditions of the problem APGLASSOup.m's iteration
    converges to (module docstring of nrmlc.lineage.apg)."""
    lam_target, lam_trivial, mu = lambdas
    residual = signal - target @ targets - trivial
    gradient_target = -(targets @ residual) + lam_target  # of the smooth part plus the linear weight
    gradient_trivial = -residual + mu * trivial
    active = target > 0
    violations = [np.abs(gradient_target[active]).max(initial=0.0), (-gradient_target[~active]).max(initial=0.0),
                  -target.min()]
    nonzero = trivial != 0
    violations.append(np.abs(gradient_trivial[nonzero] + lam_trivial * np.sign(trivial[nonzero])).max(initial=0.0))
    violations.append((np.abs(gradient_trivial[~nonzero]) - lam_trivial).max(initial=0.0))
    return max(violations)


@pytest.mark.parametrize("n_templates, size, n, lambdas, lipschitz, max_iter, correlated", [
    (10, 1024, 12, AUTHORS_LAMBDAS, 8.0, 5, True),       # the authors' sizes and values
    (10, 1024, 12, (0.01, 0.001, 0.0), 8.0, 5, True),    # after an occlusion: the ridge off
    (3, 40, 30, (0.05, 0.02, 0.5), 20.0, 60, False),
    (1, 7, 25, (0.2, 0.0, 2.0), 3.0, 200, False),
])
def test_apg_matches_the_dense_reference(n_templates, size, n, lambdas, lipschitz, max_iter, correlated):
    rng = np.random.default_rng(size + n)
    targets, signals = _problem(rng, n_templates, size, n, correlated)
    target, trivial = apg_lasso(targets, signals, lambdas, lipschitz, max_iter)
    dictionary = _dense(targets)
    gram = dictionary.T @ dictionary
    for k in range(n):
        expected = apg_lasso_reference(dictionary.T @ signals[k], gram, n_templates, lambdas, lipschitz, max_iter)
        np.testing.assert_allclose(_as_matlab(target[k], trivial[k]), expected, rtol=0, atol=1e-12)
    assert np.all(target >= 0) and np.count_nonzero(target) > n and np.count_nonzero(trivial) > 0


@pytest.mark.parametrize("lambdas", [AUTHORS_LAMBDAS, (0.001, 0.01, 0.0), (0.1, 0.05, 0.3)])
def test_apg_converges_to_the_optimum_of_its_problem(lambdas):
    """With a step below the inverse Lipschitz constant and enough steps, the KKT conditions of
    0.5||y - T a_T - a_I - f a_f||^2 + l1 (sum a_T + a_f) + l2 ||a_I||_1 + mu/2 ||a_I||^2, a_T, a_f >= 0, hold."""
    rng = np.random.default_rng(7)
    targets, signals = _problem(rng, 4, 30, 8)
    dictionary = _dense(targets)
    lipschitz = np.linalg.eigvalsh(dictionary.T @ dictionary).max() + lambdas[2]
    target, trivial = apg_lasso(targets, signals, lambdas, lipschitz, 20000)
    for k in range(len(signals)):
        assert _kkt_violation(targets, signals[k], target[k], trivial[k], lambdas) < 1e-9
    assert np.count_nonzero(target) > 0 and np.count_nonzero(trivial) > 0
    # The authors' five steps are not the optimum, and the check above tells.
    target, trivial = apg_lasso(targets, signals, lambdas, lipschitz, 5)
    assert max(_kkt_violation(targets, signals[k], target[k], trivial[k], lambdas) for k in range(len(signals))) > 1e-3


def test_apg_edge_cases():
    rng = np.random.default_rng(8)
    targets, signals = _problem(rng, 3, 20, 4)
    target, trivial = apg_lasso(targets, signals, AUTHORS_LAMBDAS, 8.0, 0)
    assert np.all(target == 0) and np.all(trivial == 0)
    target, trivial = apg_lasso(targets, np.zeros((2, 20)), AUTHORS_LAMBDAS, 8.0, 5)
    assert np.all(target == 0) and np.all(trivial == 0)
    target, trivial = apg_lasso(targets, signals[:0].copy(), AUTHORS_LAMBDAS, 8.0, 5)
    assert target.shape == (0, 4) and trivial.shape == (0, 20)


def test_apg_same_result_with_one_and_two_threads():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba was started with a single thread")
    rng = np.random.default_rng(9)
    targets, signals = _problem(rng, 10, 1024, 300, correlated=True)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = apg_lasso(targets, signals, AUTHORS_LAMBDAS, 8.0, 5)
        numba.set_num_threads(2)
        two = apg_lasso(targets, signals, AUTHORS_LAMBDAS, 8.0, 5)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(one[0], two[0]) and np.array_equal(one[1], two[1])


def test_apg_bad_input():
    targets, signals = np.ones((2, 5)), np.ones((3, 5))
    cases = [((targets, np.ones((3, 4)), AUTHORS_LAMBDAS, 8.0, 5), "signals have 4 pixels"),
             ((targets.astype(np.float32), signals, AUTHORS_LAMBDAS, 8.0, 5), "dtype"),
             ((np.asfortranarray(np.ones((2, 5))), signals, AUTHORS_LAMBDAS, 8.0, 5), "C-contiguous"),
             ((np.full((2, 5), np.nan), signals, AUTHORS_LAMBDAS, 8.0, 5), "NaN or infinite"),
             ((targets, signals, (0.1, 0.1), 8.0, 5), "3 numbers"),
             ((targets, signals, (0.1, -0.1, 1.0), 8.0, 5), "lambda2"),
             ((targets, signals, AUTHORS_LAMBDAS, 0.0, 5), "lipschitz must be > 0"),
             ((targets, signals, AUTHORS_LAMBDAS, 8.0, -1), "max_iter"),
             ((targets, signals, AUTHORS_LAMBDAS, 8.0, 2.5), "max_iter"),
             ((np.ones((0, 5)), signals, AUTHORS_LAMBDAS, 8.0, 5), "at least one atom")]
    for arguments, message in cases:
        with pytest.raises(ParameterError, match=message) as info:
            apg_lasso(*arguments)
        assert "\n" not in str(info.value)


# --------------------------------------------------------------------------- states, boxes, small steps


@pytest.mark.parametrize("box", [(70, 51, 107, 87), (3, 4, 17, 9), (100.0, 50.0, 2.0, 64.0)])
def test_first_state_maps_the_template_corners_to_the_box(box):
    state = corners_to_state(box_corners(box), (32, 32))
    x, y, w, h = box
    a11, a12, a21, a22, tr, tc = state
    np.testing.assert_allclose([a11 + a12 + tr, a21 + a22 + tc], [y, x], atol=1e-12)
    np.testing.assert_allclose([32 * a11 + a12 + tr, 32 * a21 + a22 + tc], [y + h - 1, x], atol=1e-12)
    np.testing.assert_allclose([a11 + 32 * a12 + tr, a21 + 32 * a22 + tc], [y, x + w - 1], atol=1e-12)
    # the toolkit's L1Aff box of the first state is the box itself
    np.testing.assert_array_equal(l1_affine_boxes(state[None], (32, 32))[0], box)


def test_whiten_is_whitening_then_normalize_templates():
    rng = np.random.default_rng(12)
    rows = rng.random((5, 50)) * 255
    rows[4] = 7.0
    out, mean, std, norm = whiten(rows.copy())
    np.testing.assert_allclose(out[:4].mean(axis=1), 0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(out[:4], axis=1), 1, rtol=1e-13)
    np.testing.assert_allclose(std[:4], rows[:4].std(axis=1, ddof=1) + 1e-14, rtol=1e-13)
    assert np.all(out[4] == 0)  # a constant patch: 0 / (0 + 1e-14), then 0 / 1e-14


def test_resample_repeats_by_rounded_share_and_pads_with_the_answer():
    states = np.arange(24, dtype=np.float64).reshape(4, 6)
    answer = np.full(6, -1.0)
    # shares 4 * (0.3, 0.5, 0.2, 0) = 1.2, 2, 0.8, 0 -> 1, 2, 1, 0: four rows, no padding
    out = resample_states(states, np.array([0.3, 0.5, 0.2, 0.0]), answer)
    np.testing.assert_array_equal(out, states[[0, 1, 1, 2]])
    # 4 * (0.125, 0.125, 0.125, 0.625) = 0.5, 0.5, 0.5, 2.5 -> MATLAB's round: 1, 1, 1, 3: cut to four
    out = resample_states(states, np.array([1.0, 1.0, 1.0, 5.0]), answer)
    np.testing.assert_array_equal(out, states[[0, 1, 2, 3]])
    # 4 * (0.1, 0.1, 0.1, 0.7) = 0.4, 0.4, 0.4, 2.8 -> 0, 0, 0, 3: one row of the answer
    out = resample_states(states, np.array([1.0, 1.0, 1.0, 7.0]), answer)
    np.testing.assert_array_equal(out, np.vstack([states[[3, 3, 3]], answer]))
    np.testing.assert_array_equal(resample_states(states, np.zeros(4), answer), np.repeat(answer[None], 4, axis=0))


def test_images_angle_and_its_signed_test():
    a, b = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    assert images_angle(a + 1e-3, b) == pytest.approx(90.0, abs=0.2)
    # sum(a - b) < eps gives 1 whatever the angle: the code's test is on the signed sum
    assert images_angle(b, a + 1e-3) == 1.0
    assert images_angle(a, a) == 1.0


def _closing_and_regions(mask):
    """MATLAB's imclose with a plus-shaped element (outside: 0 for the dilation, 1 for the
    erosion) and the areas of the 8-connected regions, by plain loops."""
    rows, cols = mask.shape
    offsets = [(0, 0), (-1, 0), (1, 0), (0, -1), (0, 1)]

    def at(image, r, c, outside):
        return image[r, c] if 0 <= r < rows and 0 <= c < cols else outside

    dilated = np.array([[any(at(mask, r + i, c + j, False) for i, j in offsets) for c in range(cols)]
                        for r in range(rows)])
    closed = np.array([[all(at(dilated, r + i, c + j, True) for i, j in offsets) for c in range(cols)]
                       for r in range(rows)])
    seen = np.zeros_like(closed)
    areas = []
    for r in range(rows):
        for c in range(cols):
            if closed[r, c] and not seen[r, c]:
                stack, area = [(r, c)], 0
                seen[r, c] = True
                while stack:
                    y, x = stack.pop()
                    area += 1
                    for i in (-1, 0, 1):
                        for j in (-1, 0, 1):
                            if 0 <= y + i < rows and 0 <= x + j < cols and closed[y + i, x + j] and not seen[y + i, x + j]:
                                seen[y + i, x + j] = True
                                stack.append((y + i, x + j))
                areas.append(area)
    return areas


def test_occlusion_map_against_plain_loops():
    rng = np.random.default_rng(13)
    for density in (0.05, 0.2, 0.5):
        trivial = np.where(rng.random((16, 12)) < density, 0.05, 0.01) * rng.choice([-1.0, 1.0], (16, 12))
        areas = _closing_and_regions(trivial > 0.03)
        assert largest_occluded_region(trivial, 0.03) == (max(areas) if areas else None)
    assert largest_occluded_region(np.zeros((8, 8)), 0.03) is None
    block = np.zeros((32, 32))
    block[:17, :17] = 0.1  # at the corner: the erosion does not eat the border
    assert largest_occluded_region(block, 0.03) == 289


def test_params_are_the_authors_and_checked():
    p = L1APGParams()
    assert (p.n_particles, p.template_size, p.n_templates) == (600, (32, 32), 10)
    assert p.affine_sigma == (0.005, 0.0005, 0.0005, 0.005, 4, 4)
    assert (p.lambda_template, p.lambda_trivial, p.mu, p.lipschitz, p.max_iter) == (0.01, 0.001, 1.0, 8.0, 5)
    assert (p.alpha, p.angle_threshold, p.template_jitter) == (50.0, 30.0, 0.6)
    assert (p.occlusion_level, p.occlusion_fraction, p.occlusion_frames) == (0.03, 0.25, 5)
    for change in (dict(n_particles=1), dict(n_particles=2.5), dict(n_templates=0), dict(n_templates=True),
                   dict(template_size=(32,)), dict(template_size=(1, 32)), dict(template_size=(32.0, 32)),
                   dict(affine_sigma=(1, 2)), dict(affine_sigma=(-1,) * 6), dict(affine_sigma=("a",) * 6),
                   dict(lambda_template=-0.1), dict(lambda_trivial=float("nan")), dict(mu=-1.0),
                   dict(lipschitz=0.0), dict(max_iter=-1), dict(alpha=0.0), dict(angle_threshold=200.0),
                   dict(template_jitter=-1.0), dict(occlusion_level=float("inf")), dict(occlusion_fraction=0.0),
                   dict(occlusion_fraction=1.5), dict(occlusion_frames=-1)):
        with pytest.raises(ParameterError, match="L1APGParams") as info:
            L1APGParams(**change)
        assert "\n" not in str(info.value)


def test_registered():
    assert TRACKERS["l1apg"] == "nrmlc.lineage.l1apg:L1APGTracker"


# --------------------------------------------------------------------------- the tracker's steps


def _sequential_choice(tracker, candidates, in_range):
    """L1TrackingBPR_APGup.m's two stages one particle at a time, with the dense APGLASSOup.m."""
    p = tracker.params
    n, size = candidates.shape
    templates = np.hstack([tracker.templates.T, tracker.fixed[:, None]])
    dictionary = np.hstack([tracker.templates.T, np.eye(size), tracker.fixed[:, None]])
    gram = dictionary.T @ dictionary
    projector = templates @ np.linalg.pinv(templates)
    bound = np.zeros(n)
    for j in range(n):
        if in_range[j] and np.abs(candidates[j]).sum() != 0:
            bound[j] = np.exp(-p.alpha * np.linalg.norm(candidates[j] - projector @ candidates[j]) ** 2)
    order = np.argsort(-bound, kind="stable")
    likelihoods, threshold, best, best_likelihood, coefficients = np.zeros(n), 0.0, None, -np.inf, None
    k = 0
    while k < n - 1 and bound[order[k]] >= threshold:
        j = order[k]
        if np.isnan(candidates[j].sum()):
            k += 1
            continue
        c = apg_lasso_reference(dictionary.T @ candidates[j], gram, p.n_templates,
                                (p.lambda_template, p.lambda_trivial, tracker.mu), p.lipschitz, p.max_iter)
        error = np.sum((candidates[j] - templates @ np.concatenate([c[:p.n_templates], c[-1:]])) ** 2)
        likelihoods[j] = np.exp(-p.alpha * error)
        threshold += likelihoods[j] / (2 * n - 1)
        if likelihoods[j] > best_likelihood:
            best, best_likelihood, coefficients = j, likelihoods[j], c
        k += 1
    return best, coefficients, likelihoods


@pytest.mark.parametrize("batch", [1, 3, 48])
def test_batched_coding_is_the_sequential_loop(monkeypatch, batch):
    monkeypatch.setattr(l1apg, "_BATCH", batch)
    tracker = lineage.small_tracker(L1APGTracker)
    rng = np.random.default_rng(15)
    n, size = 40, 30
    noise = rng.uniform(0.05, 1.5, n)[:, None] * rng.standard_normal((n, size))
    candidates = rng.random((n, tracker.params.n_templates)) @ tracker.templates + noise
    candidates[5] = 3.0  # constant: bound 0, still coded if the loop reaches it
    in_range = np.ones(n, dtype=bool)
    in_range[[2, 9, 30]] = False
    candidates[[2, 9, 30]] = np.nan
    candidates, _, _, _ = whiten(candidates)
    choice, likelihoods = tracker._code(candidates, in_range)
    best, coefficients, expected = _sequential_choice(tracker, candidates, in_range)
    coded = np.count_nonzero(expected)
    assert 3 <= coded < n - 4  # the threshold stopped the loop well before the end
    assert choice[0] == best
    np.testing.assert_allclose(likelihoods, expected, rtol=1e-9, atol=0)
    np.testing.assert_allclose(_as_matlab(choice[1], choice[2]), coefficients, rtol=0, atol=1e-12)


def test_coding_stops_where_the_bound_falls_below_the_threshold_and_skips_the_last():
    """The loop's rule: code in the bound's order while bound >= sum(likelihoods) / (2n - 1), and
    never the last particle of that order (``while n < n_sample``)."""
    tracker = lineage.small_tracker(L1APGTracker)
    p = tracker.params
    n, size = p.n_particles, p.template_size[0] * p.template_size[1]
    rng = np.random.default_rng(17)
    noise = rng.standard_normal(size)
    first = tracker.templates[0] + 0.3 * tracker.templates[1]

    def whitened(weight):
        return whiten((first + weight * noise)[None].copy())[0][0]

    def bound(candidate):
        residual = candidate - tracker._span.T @ (tracker._span @ candidate)
        return np.exp(-p.alpha * residual @ residual)

    # n identical candidates: equal bounds, each at least its likelihood, so all but the last are coded
    same = np.repeat(whitened(0.0)[None], n, axis=0)
    _, likelihoods = tracker._code(same, np.ones(n, dtype=bool))
    assert np.count_nonzero(likelihoods) == n - 1 and likelihoods[-1] == 0
    each = likelihoods[0]
    # 20 copies of it, then one worse candidate whose bound sits just above or below the threshold
    copies = 20
    threshold = copies * each / (2 * n - 1)
    for factor, coded in ((1.3, True), (0.7, False)):
        low, high = 0.0, 50.0
        for _ in range(200):  # bisection on the noise's weight: the bound falls as it grows
            middle = 0.5 * (low + high)
            low, high = (middle, high) if bound(whitened(middle)) > factor * threshold else (low, middle)
        candidates = np.full((n, size), np.nan)
        candidates[:copies] = same[0]
        candidates[copies] = whitened(low)
        in_range = np.zeros(n, dtype=bool)
        in_range[:copies + 1] = True
        _, likelihoods = tracker._code(candidates, in_range)
        np.testing.assert_array_equal(likelihoods[:copies], each)
        assert (likelihoods[copies] > 0) == coded, factor
        assert np.count_nonzero(likelihoods) == copies + coded


def test_template_step_updates_or_pauses_as_the_code_does():
    tracker = lineage.small_tracker(L1APGTracker)
    p = tracker.params
    size = p.template_size[0] * p.template_size[1]
    rng = np.random.default_rng(16)
    answer = rng.standard_normal(size)
    answer -= tracker.templates[0] * (tracker.templates[0] @ answer)  # far from the strongest template
    answer *= np.sign(answer.sum()) / np.linalg.norm(answer)
    assert answer.sum() - tracker.templates[0].sum() > 1e-3  # else images_angle's signed test answers 1
    coefficients = np.array([0.9, 0.4, 0.1, 0.6])
    small = np.zeros(size)
    small[[0, 1]] = 0.05  # one region of 2 pixels (limit: round(0.25 * 30) = 8)
    before = tracker.templates.copy()

    tracker._update_templates(answer, coefficients, small)
    np.testing.assert_allclose(tracker.templates[2], answer / (1 + 1e-14), rtol=1e-15)  # the weakest, replaced
    np.testing.assert_array_equal(np.delete(tracker.targets, 2, axis=0)[:-1], np.delete(tracker.templates, 2, axis=0))
    np.testing.assert_array_equal(tracker.targets[-1], before[0] / p.n_templates)  # the fixed template stays
    assert (tracker.occlusion_countdown, tracker.mu) == (-1, 1.0)

    # no trivial coefficient above the level: MATLAB's empty max() makes it an occlusion
    templates = tracker.templates.copy()
    tracker._update_templates(answer, coefficients, np.zeros(size))
    np.testing.assert_array_equal(tracker.templates, templates)
    assert (tracker.occlusion_countdown, tracker.mu) == (5, 0.0)
    for countdown in range(4, -1, -1):  # paused: nothing happens, the ridge stays off
        tracker._update_templates(answer, coefficients, small)
        assert (tracker.occlusion_countdown, tracker.mu) == (countdown, 0.0)
    np.testing.assert_array_equal(tracker.templates, templates)
    # after the pause a close answer restores the ridge without an update
    tracker._update_templates(tracker.templates[0].copy(), coefficients, small)
    assert (tracker.occlusion_countdown, tracker.mu) == (-1, 1.0)
    np.testing.assert_array_equal(tracker.templates, templates)
    # a region of a quarter of the template or more is an occlusion
    large = np.zeros(p.template_size)
    large[:3, :3] = 0.05
    tracker._update_templates(answer, coefficients, large.ravel())
    assert (tracker.occlusion_countdown, tracker.mu) == (5, 0.0)
    np.testing.assert_array_equal(tracker.templates, templates)


def test_init_templates_are_whitened_unit_vectors_and_the_first_is_the_box():
    tracker = lineage.small_tracker(L1APGTracker)
    p = tracker.params
    np.testing.assert_allclose(tracker.templates.mean(axis=1), 0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(tracker.templates, axis=1), 1, rtol=1e-14)
    assert len({row.tobytes() for row in tracker.templates}) == p.n_templates  # the corners were moved
    np.testing.assert_array_equal(tracker.box(), (10, 12, 15, 18))
    np.testing.assert_array_equal(tracker.samples, np.repeat(tracker.state[None], p.n_particles, axis=0))
