"""ASLA (nrmlc.lineage.asla) and its non-negative lasso (nrmlc.lineage.lasso)."""
import numba
import numpy as np
import pytest

from nrmlc.data import SyntheticSequence, SyntheticSpec
from nrmlc.errors import ParameterError
from nrmlc.lineage import TRACKERS
from nrmlc.lineage.asla import (ASLAParams, ASLATracker, normalize_rows, patch_indices, replaced_exemplar,
                                subspace_coefficients)
from nrmlc.lineage.lasso import (SPAMS_RIDGE, lasso_nonnegative, lasso_nonnegative_gram, lasso_nonnegative_reference,
                                 lasso_objective)
from nrmlc.workbench.metrics import evaluate


def _problem(rng, m, p, n, correlated=False):
    """Non-negative signals and unit atoms; ``correlated``: ASLA-like near-duplicate atoms."""
    if correlated:
        bases = rng.random((m, 9))
        D = np.repeat(bases, p // 9, axis=1) + 0.02 * rng.random((m, p // 9 * 9))
    else:
        D = rng.standard_normal((m, p))
    D /= np.linalg.norm(D, axis=0)
    X = np.abs(D[:, :5] @ rng.random((5, n))) + 0.1 * rng.random((m, n)) if correlated else rng.standard_normal((m, n))
    X /= np.linalg.norm(X, axis=0)
    return np.ascontiguousarray(X), np.ascontiguousarray(D)


def _kkt_violation(X, D, A, lam, ridge=0.0):
    """The largest violation of the optimality conditions of each column's problem."""
    gradient = D.T @ (X - D @ A) - lam - ridge * A  # minus the smooth part's gradient, minus lam
    active = A > 0
    return max(np.abs(gradient[active]).max(initial=0.0), gradient[~active].max(initial=0.0), -A.min())


@pytest.mark.parametrize("m, p, n, correlated, ridge", [
    (40, 25, 30, False, 0.0),
    (40, 25, 30, False, SPAMS_RIDGE),
    (256, 90, 40, True, SPAMS_RIDGE),  # ASLA's sizes and near-duplicate atoms
    (256, 90, 40, True, 0.0),
])
def test_lasso_matches_reference(m, p, n, correlated, ridge):
    rng = np.random.default_rng(p + n)
    X, D = _problem(rng, m, p, n, correlated)
    lam = 0.01
    A = lasso_nonnegative(X, D, lam, ridge=ridge)
    reference = lasso_nonnegative_reference(X, D, lam, ridge=ridge)
    ours, theirs = lasso_objective(X, D, A, lam, ridge), lasso_objective(X, D, reference, lam, ridge)
    assert np.all(ours <= theirs + 1e-12)
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-10)
    np.testing.assert_allclose(A, reference, rtol=0, atol=1e-6)
    assert (A > 0).sum(axis=0).max() >= 3  # not a trivial answer
    assert _kkt_violation(X, D, A, lam, ridge) < 1e-9


def test_lasso_degenerate_problems_give_zero():
    rng = np.random.default_rng(0)
    X, D = _problem(rng, 30, 12, 4)
    X[:, 0] = 0.0
    A = lasso_nonnegative(X, D, 0.01)
    assert np.all(A[:, 0] == 0.0)
    # lam at the largest correlation: zero is optimal
    lam = float((D.T @ X).max())
    assert np.all(lasso_nonnegative(X, D, lam) == 0.0)
    # all correlations negative: zero whatever lam
    assert np.all(lasso_nonnegative(np.ascontiguousarray(-np.abs(D[:, :1])), np.abs(D), 1e-9) == 0.0)


def test_lasso_single_atom_is_the_soft_threshold():
    rng = np.random.default_rng(1)
    D = np.ascontiguousarray(rng.standard_normal((20, 1)))
    X = np.ascontiguousarray(rng.standard_normal((20, 50)))
    lam = 0.3
    expected = np.maximum(D[:, 0] @ X - lam, 0.0) / (D[:, 0] @ D[:, 0])
    np.testing.assert_allclose(lasso_nonnegative(X, D, lam)[0], expected, rtol=1e-13, atol=1e-15)


def test_lasso_duplicate_atoms_reach_the_optimum():
    rng = np.random.default_rng(2)
    X, unique = _problem(rng, 30, 10, 20)
    D = np.ascontiguousarray(unique[:, [0, 1, 2, 0, 3, 4, 1, 5, 6, 7, 8, 9, 0]])
    A = lasso_nonnegative(X, D, 0.02)
    expected = lasso_objective(X, unique, lasso_nonnegative_reference(X, unique, 0.02), 0.02)
    np.testing.assert_allclose(lasso_objective(X, D, A, 0.02), expected, rtol=0, atol=1e-10)
    assert _kkt_violation(X, D, A, 0.02) < 1e-9


def test_lasso_overcomplete_dictionary_against_support_enumeration():
    rng = np.random.default_rng(3)
    X, D = _problem(rng, 6, 10, 15)  # more atoms than dimensions: D'D is singular
    A = lasso_nonnegative(X, D, 0.05)
    reference = lasso_nonnegative_reference(X, D, 0.05)
    np.testing.assert_allclose(lasso_objective(X, D, A, 0.05), lasso_objective(X, D, reference, 0.05),
                               rtol=0, atol=1e-10)
    assert _kkt_violation(X, D, A, 0.05) < 1e-9


def test_spams_ridge_splits_duplicates_equally():
    """With SPAMS' ridge the problem is strictly convex: duplicate atoms get equal coefficients."""
    rng = np.random.default_rng(4)
    X, unique = _problem(rng, 30, 6, 10)
    D = np.ascontiguousarray(unique[:, [0, 1, 2, 3, 4, 5, 0]])
    A = lasso_nonnegative(X, D, 0.01, ridge=SPAMS_RIDGE)
    assert np.any(A[0] > 1e-3)
    # the split direction has curvature 1e-10 only, so rounding moves it by ~1e-16 / 1e-10
    np.testing.assert_allclose(A[0], A[6], rtol=0, atol=1e-5)
    reference = lasso_nonnegative_reference(X, D, 0.01, ridge=SPAMS_RIDGE)
    np.testing.assert_allclose(A[0] + A[6], reference[0] + reference[6], rtol=0, atol=1e-9)
    np.testing.assert_allclose(lasso_objective(X, D, A, 0.01, SPAMS_RIDGE),
                               lasso_objective(X, D, reference, 0.01, SPAMS_RIDGE), rtol=0, atol=1e-12)


def test_lasso_same_result_with_one_and_two_threads():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba was started with a single thread")
    rng = np.random.default_rng(5)
    X, D = _problem(rng, 256, 90, 700, correlated=True)
    gram = D.T @ D + SPAMS_RIDGE * np.eye(90)
    gram = 0.5 * (gram + gram.T)
    correlations = np.ascontiguousarray(X.T @ D)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = lasso_nonnegative_gram(gram, correlations, 0.01)
        numba.set_num_threads(2)
        two = lasso_nonnegative_gram(gram, correlations, 0.01)
    finally:
        numba.set_num_threads(before)
    assert np.array_equal(one, two)


def test_lasso_bad_input():
    X, D = np.ones((5, 3)), np.eye(5)
    with pytest.raises(ParameterError, match="X has 5 rows, D has 4"):
        lasso_nonnegative(X, np.ones((4, 2)), 0.1)
    with pytest.raises(ParameterError, match="lam must be > 0"):
        lasso_nonnegative(X, D, 0.0)
    with pytest.raises(ParameterError, match="lam"):
        lasso_nonnegative(X, D, float("nan"))
    with pytest.raises(ParameterError, match="dtype"):
        lasso_nonnegative(X.astype(np.float32), D, 0.1)
    with pytest.raises(ParameterError, match="C-contiguous"):
        lasso_nonnegative(np.asfortranarray(np.ones((5, 3))), D, 0.1)
    bad = X.copy()
    bad[0, 0] = np.inf
    with pytest.raises(ParameterError, match="NaN or infinite"):
        lasso_nonnegative(bad, D, 0.1)
    with pytest.raises(ParameterError, match="ridge"):
        lasso_nonnegative(X, D, 0.1, ridge=-1.0)
    with pytest.raises(ParameterError, match="symmetric"):
        lasso_nonnegative_gram(np.array([[1.0, 0.5], [0.0, 1.0]]), np.ones((3, 2)), 0.1)
    with pytest.raises(ParameterError, match="columns"):
        lasso_nonnegative_gram(np.eye(2), np.ones((3, 3)), 0.1)
    with pytest.raises(ParameterError) as info:
        lasso_nonnegative(X[:2], D, 0.1)
    assert "\n" not in str(info.value)


# --------------------------------------------------------------------------- ASLA


def test_params_are_the_authors_and_checked():
    p = ASLAParams()
    assert (p.n_particles, p.affine_sigma, p.lasso_lambda, p.template_side) == (600, (4, 4, 0.01, 0, 0.005, 0), 0.01, 32)
    assert (p.patch_side, p.patch_step, p.patches_per_side, p.n_exemplars) == (16, 8, 3, 10)
    assert (p.batch_size, p.max_basis, p.forgetting, p.intensity_scale, p.lasso_ridge) == (5, 10, 1.0, 255.0, 1e-10)
    for change in (dict(n_particles=0), dict(n_particles=2.5), dict(affine_sigma=(1, 2)), dict(affine_sigma=(-1,) * 6),
                   dict(affine_sigma=('a',) * 6),
                   dict(lasso_lambda=0.0), dict(lasso_ridge=-1e-3), dict(template_side=1), dict(patch_side=40),
                   dict(patch_step=5), dict(n_exemplars=1), dict(batch_size=0), dict(max_basis=0),
                   dict(forgetting=0.0), dict(forgetting=1.5), dict(intensity_scale=0.0), dict(n_exemplars=True)):
        with pytest.raises(ParameterError, match="ASLAParams"):
            ASLAParams(**change)


def test_registered():
    assert TRACKERS["asla"] == "nrmlc.lineage.asla:ASLATracker"


def test_patch_layout_is_img2patch():
    index = patch_indices(32, 16, 8)
    assert index.shape == (9, 256)
    image = np.arange(32 * 32).reshape(32, 32)
    # img2patch.m: column blocks outer, row blocks inner
    np.testing.assert_array_equal(image.ravel()[index[1]].reshape(16, 16), image[8:24, 0:16])
    np.testing.assert_array_equal(image.ravel()[index[3]].reshape(16, 16), image[0:16, 8:24])
    np.testing.assert_array_equal(image.ravel()[index[8]].reshape(16, 16), image[16:32, 16:32])


def test_normalize_rows_adds_eps():
    rows = normalize_rows(np.array([[3.0, 4.0], [0.0, 0.0]]))
    np.testing.assert_allclose(rows[0], [0.6, 0.8], rtol=1e-15)
    assert np.all(rows[1] == 0.0)


def test_subspace_coefficients_are_the_lasso_over_basis_and_identity():
    """run_ASLA.m's reconstruction: mexLasso(x - mean, [basis, I]), basis part (Gram written by hand)."""
    rng = np.random.default_rng(6)
    basis = np.linalg.qr(rng.random((40, 4)))[0]
    centred = basis @ np.array([0.3, -0.2, 0.1, 0.05]) + 0.05 * rng.standard_normal(40)
    centred[:6] += 0.4  # an "occlusion" the identity atoms absorb
    ours = subspace_coefficients(centred, basis, 0.01, SPAMS_RIDGE)
    D = np.ascontiguousarray(np.hstack([basis, np.eye(40)]))
    full = lasso_nonnegative_reference(centred[:, None], D, 0.01, ridge=SPAMS_RIDGE)[:, 0]
    assert ours.shape == (4,) and np.count_nonzero(ours) >= 1 and np.count_nonzero(full[4:]) >= 6
    np.testing.assert_allclose(ours, full[:4], rtol=0, atol=1e-8)


def test_replaced_exemplar_probabilities():
    """run_ASLA.m's loop: exemplar i (0-based, 1..E-1) with probability 2^i / (2^E - 2), never the first."""
    for n_exemplars in (10, 4):
        draws = (np.arange(200_000) + 0.5) / 200_000  # uniform quadrature of [0, 1)
        counts = np.bincount([replaced_exemplar(u, n_exemplars) for u in draws], minlength=n_exemplars)
        expected = np.array([0.0] + [2.0 ** i for i in range(1, n_exemplars)]) / (2.0 ** n_exemplars - 2)
        np.testing.assert_allclose(counts / draws.size, expected, atol=2e-5)
    # the interval edges: [c(i-1), c(i)) -> i, 1-based
    assert replaced_exemplar(0.0, 10) == 1
    assert replaced_exemplar(2 / 1022 - 1e-12, 10) == 1
    assert replaced_exemplar(2 / 1022 + 1e-12, 10) == 2
    assert replaced_exemplar(510 / 1022 + 1e-12, 10) == 9
    assert replaced_exemplar(510 / 1022 - 1e-12, 10) == 8
    assert replaced_exemplar(0.3, 2) == 1


def _track(sequence, n_frames, seed=0):
    tracker = ASLATracker(seed=seed)
    tracker.init(sequence.color_frame(0), sequence.init_box)
    boxes = [np.asarray(sequence.init_box, dtype=np.float64)]
    for index in range(1, n_frames):
        box = tracker.update(sequence.color_frame(index))
        assert box.shape == (4,) and box.dtype == np.float64
        boxes.append(box)
    return tracker, np.array(boxes)


@pytest.fixture(scope="module")
def synthetic():
    return SyntheticSequence(SyntheticSpec(name="asla", seed=1, n_frames=40))


@pytest.fixture(scope="module")
def tracked(synthetic):
    return _track(synthetic, 40)


def test_tracks_a_moving_target(synthetic, tracked):
    tracker, boxes = tracked
    overlap = evaluate(boxes, synthetic.groundtruth).mean_overlap
    static = evaluate(np.repeat(boxes[:1], len(boxes), axis=0), synthetic.groundtruth).mean_overlap
    assert static < 0.2  # the target moves away from its first box
    assert overlap > 0.6, (overlap, static)


def test_model_after_tracking(synthetic, tracked):
    tracker, _ = tracked
    assert tracker.templates.shape == (10, 1024)
    np.testing.assert_allclose(np.linalg.norm(tracker.templates, axis=1), 1.0, rtol=1e-12)
    # the first exemplar is never replaced: it is still the normalised, clipped first patch
    first = ASLATracker()
    first.init(synthetic.color_frame(0), synthetic.init_box)
    np.testing.assert_array_equal(tracker.templates[0], normalize_rows(first.exemplars[0][None].copy())[0])
    assert tracker.subspace.basis.shape[1] == 10
    # 30 model frames: 6 updates, each replacing one of exemplars 1..9 by a reconstruction
    assert len(tracker.batch) == 0


def test_same_seed_same_boxes(synthetic, tracked):
    _, boxes = tracked
    _, again = _track(synthetic, 18, seed=0)
    np.testing.assert_array_equal(again, boxes[:18])
    _, other = _track(synthetic, 18, seed=1)
    assert not np.array_equal(other, boxes[:18])
