"""The Sec. 3.3 analysis scripts: Theorem 1 facts, solvers, and each script's main on a tiny budget."""
from __future__ import annotations

import json
from fractions import Fraction

import numpy as np
import pytest

from experiments import internals
from experiments.paper import (
    fig1_coefficients, fig2_mean_gray, fig_occlusion, stats_nonnegativity, theorem1_checks,
)
from experiments.internals import Budget
from experiments.grid import Context, run_script
from nrmlc.data import synthetic_suite
from nrmlc.workbench.run_cache import RunCache

TINY = Budget(max_frames=None, every=4, n_candidates=20, max_sequences=2, seeds=(0,), n_particles=80)


# --------------------------------------------------------------------------- exact facts
def test_paper_counterexample_exact():
    facts = theorem1_checks.paper_counterexample()
    assert facts["F_symmetric"]
    assert facts["F_strictly_diagonally_dominant"] is True
    assert facts["F_positive_definite"] is True
    assert facts["F_leading_minors"] == ["5", "21", "49"]
    assert facts["F_inverse_exact"] == [["3/7", "-2/7", "2/7"], ["-2/7", "3/7", "-2/7"], ["2/7", "-2/7", "3/7"]]
    assert facts["F_inverse_strictly_diagonally_dominant"] is False
    assert facts["F_inverse_diagonally_dominant_weak"] is False
    assert facts["c_exact"] == ["3/7", "-1/7", "3/7"]
    assert facts["c_has_negative_entry"] is True
    assert facts["c_sum_to_one_exact"] == ["3/5", "-1/5", "3/5"]
    # The paper's printed rounding of F^-1.
    assert np.allclose(facts["F_inverse"], [[0.43, -0.29, 0.29], [-0.29, 0.43, -0.29], [0.29, -0.29, 0.43]], atol=0.005)


def test_fraction_inverse_is_exact():
    F = [[Fraction(v) for v in row] for row in theorem1_checks.PAPER_F]
    inverse = theorem1_checks._fraction_inverse(F)
    product = [[sum(F[i][k] * inverse[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    assert product == [[Fraction(int(i == j)) for j in range(3)] for i in range(3)]


def test_two_by_two_sdd_inverse_is_sdd():
    found = theorem1_checks.random_matrix_search(np.random.default_rng(0), n_trials=2000)
    assert found["2"]["F_inverse_not_sdd"] == 0 and found["2"]["c_negative"] == 0
    assert found["3"]["F_inverse_not_sdd"] > 0


def test_meavg_bound_on_random_sum_to_one_vectors():
    rng = np.random.default_rng(1)
    for k in (2, 5, 8, 10):
        c = rng.standard_normal((5000, k))
        c /= c.sum(axis=1, keepdims=True)
        assert np.all(k * np.einsum("nk,nk->n", c, c) >= 1 - 1e-12)
        simplex = rng.dirichlet(np.ones(k), size=5000)
        kcc = k * np.einsum("nk,nk->n", simplex, simplex)
        assert np.all(kcc >= 1 - 1e-12)
        # The paper's 1/K^2 is loose by a factor K: the minimum 1/K is attained at c = 1/K.
        uniform = np.full(k, 1.0 / k)
        assert np.isclose(uniform @ uniform, 1.0 / k)
        assert (uniform @ uniform) / (1.0 / k**2) == pytest.approx(k)


# --------------------------------------------------------------------------- solvers
def test_sum_to_one_codes_match_direct_solve():
    rng = np.random.default_rng(2)
    A = rng.standard_normal((50, 1024, 6)) * 0.02
    G = np.einsum("nda,ndb->nab", A, A)
    for lam in (0.01, 1.0):
        inverse, raw, codes = internals.sum_to_one_codes(G, lam)
        direct = np.linalg.solve(G + lam * np.eye(6), np.ones((50, 6, 1)))[..., 0]
        assert np.allclose(raw, direct, rtol=1e-8, atol=1e-10)
        assert np.allclose(codes.sum(axis=1), 1.0)
        # The sum-to-one solution minimises c'(G + lam I)c on 1'c = 1.
        objective = np.einsum("na,nab,nb->n", codes, G + lam * np.eye(6), codes)
        other = codes + rng.standard_normal(codes.shape) * 1e-3
        other -= (other.sum(axis=1, keepdims=True) - 1) / 6
        assert np.all(objective <= np.einsum("na,nab,nb->n", other, G + lam * np.eye(6), other) + 1e-15)


def test_strictly_dd_and_row_sums():
    F = np.array(theorem1_checks.PAPER_F, dtype=float)
    assert internals.strictly_dd(F)
    assert not internals.strictly_dd(np.linalg.inv(F))
    assert internals.max_offdiag_row_sum(F) == 4.0
    assert not internals.strictly_dd(np.array([[1.0, 1.0], [1.0, 1.0]]))  # equality is not strict


def test_sampled_frames_skip_template_updates():
    frames = internals.sampled_frames(100, 5, 5)
    assert frames == list(range(5, 100, 5))
    frames = internals.sampled_frames(40, 4, 5)
    assert all((f + 1) % 5 != 0 for f in frames)
    assert frames == sorted(set(frames)) and frames[-1] < 40


# --------------------------------------------------------------------------- scripts
@pytest.fixture(scope="module")
def tiny_context(tmp_path_factory):
    root = tmp_path_factory.mktemp("analysis")
    sequences = synthetic_suite(n_frames=30, size=(120, 160), n_sequences=2)
    context = Context(figures_dir=root / "figures", cache=RunCache(root / "runs"), jobs=1, seeds=(0,),
                      sweep_seeds=(0,), _sequences=sequences)
    context.analysis_budget = TINY
    return context


def _check_output(context, out, stem, suffixes=(".png", ".json")):
    assert set(out) >= {"title", "figures", "markdown"}
    assert out["figures"] == [f"{stem}.png"]
    assert out["markdown"].startswith("### ")
    for suffix in suffixes:
        path = context.figures_dir / f"{stem}{suffix}"
        assert path.is_file() and path.stat().st_size > 0, path
    return json.loads((context.figures_dir / f"{stem}.json").read_text())


def test_theorem1_main(tiny_context):
    out = run_script(theorem1_checks, tiny_context)
    data = _check_output(tiny_context, out, "theorem1_checks")
    assert data["paper_counterexample"]["c_has_negative_entry"]
    for group in ("nearest_dictionaries", "random_subset_dictionaries"):
        for by_lambda in data[group].values():
            for counts in by_lambda.values():
                assert counts["F_inverse_sdd_and_c_negative"] == 0  # Theorem 1 holds
                assert counts["min_K_ctc"] >= 1 - 1e-9  # Cauchy-Schwarz
    assert data["meavg"]["min_K_ctc_tracker_codes"] >= 1 - 1e-9
    # Large lambda makes F (and F^-1) SDD for every candidate.
    assert all(v["10.0"]["F_inverse_sdd"] == v["10.0"]["n"] for v in data["nearest_dictionaries"].values())


def test_stats_main(tiny_context):
    out = run_script(stats_nonnegativity, tiny_context)
    data = _check_output(tiny_context, out, "stats_nonnegativity", (".png", ".json", ".csv"))
    rows = {r["lambda"]: r for r in data["by_lambda"]}
    assert set(rows) == set(internals.LAMBDAS)
    assert rows[10.0]["c_negative_share"] == 0.0
    # Our numpy closed forms reproduce the tracker's codes on the same candidates.
    assert data["tracker_agreement"]["max_abs_diff_c"] < 1e-4
    assert data["tracker_agreement"]["max_abs_diff_w"] < 1e-4


def test_fig2_main(tiny_context):
    out = run_script(fig2_mean_gray, tiny_context)
    data = _check_output(tiny_context, out, "fig2_mean_gray")
    for name in ("positive", "negative", "candidates"):
        assert 0 <= data["overall"][name]["min"] <= data["overall"][name]["max"] <= 1 / 32 + 1e-6
    assert "1/32" in out["markdown"]


def test_fig1_main(tiny_context):
    out = run_script(fig1_coefficients, tiny_context)
    data = _check_output(tiny_context, out, "fig1_coefficients")
    assert data["sequence"] == "synth-01"
    assert set(data["trackers"]) == {"no_l2", "l2"}
    for info in data["trackers"].values():
        assert sum(info["coefficients_used"]) == pytest.approx(1.0, abs=1e-6)


def test_fig_occlusion_main(tiny_context):
    out = run_script(fig_occlusion, tiny_context)
    data = _check_output(tiny_context, out, "fig_occlusion")
    stats = data["synthetic_flag_statistics"]
    assert stats["occluded_frames"] > 0 and stats["other_frames"] > 0
    assert 0 <= stats["flag_rate_occluded_frames"] <= 1
    assert data["at_frame"]["len_neg"] == data["at_frame"]["negative_templates_used"]


def test_runs_match_what_the_scripts_read(tmp_path, monkeypatch):
    """run_all computes ``runs(context)`` first; the scripts must then find every job cached.

    Self-contained: a fresh cache holds only what ``runs`` declares; a script that asks for any
    other job fails, as computing is refused once the declared jobs are in."""
    sequences = synthetic_suite(n_frames=30, size=(120, 160), n_sequences=2)
    context = Context(figures_dir=tmp_path / "figures", cache=RunCache(tmp_path / "runs"), jobs=1, seeds=(0,),
                      sweep_seeds=(0,), _sequences=sequences)
    context.analysis_budget = TINY
    modules = (theorem1_checks, stats_nonnegativity, fig2_mean_gray, fig1_coefficients, fig_occlusion)
    declared = {module.__name__: module.runs(context) for module in modules}
    assert all(declared.values()), declared
    assert context.cache.missing([job for jobs in declared.values() for job in jobs])  # nothing cached yet
    context.cache.ensure([job for jobs in declared.values() for job in jobs], jobs=1, progress=False)

    def refuse(missing, *args, **kwargs):
        raise AssertionError(f"a script needs jobs its runs() does not declare: {missing}")

    monkeypatch.setattr(context.cache, "_compute", refuse)
    for module in modules:
        assert not context.cache.missing(declared[module.__name__]), module.__name__
        run_script(module, context)


def test_paper_claims_use_the_paper_preset(tiny_context):
    from experiments.grid import describe_params
    from experiments.internals import tracker_params
    from nrmlc.tracker.params import TrackerParams

    params = tracker_params(TINY, tiny_context)
    assert params == TrackerParams.paper().replace(n_particles=TINY.n_particles)
    assert describe_params(TrackerParams.paper()).startswith("the 'paper' preset")


def test_fig1_labels_never_overlap():
    """Nearby templates share one label; distant ones get their own, at the cluster's largest code."""
    indices = np.array([0, 4, 49, 50, 51, 52, 120])
    values = np.array([0.1, 0.14, 0.14, 0.15, 0.16, 0.01, -0.3])
    labels = fig1_coefficients.label_groups(indices, values, span=10)
    assert [text for _, _, text in labels] == ["#1, #5", "#50-#53 (4)", "#121"]
    assert [y for _, y, _ in labels] == [0.14, 0.16, -0.3]
    xs = [x for x, _, _ in labels]
    assert all(b - a >= 10 for a, b in zip(xs, xs[1:]))
