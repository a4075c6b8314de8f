"""Numeric checks of Theorem 1 and of the argument around it (paper Sec. 3.3).

(a) The paper's 3x3 counterexample F = [[5,2,-2],[2,5,2],[-2,2,5]], exactly (fractions):
    F is strictly diagonally dominant (SDD) and positive definite, F^{-1} is not SDD,
    and c = F^{-1} 1 has a negative entry. (The paper typesets the matrix as
    "F^{-1} = (...)^{-1}" in the equation while the text calls it F.)
(b) A randomised search on real patch data for counterexamples to the paper's route
    "F SDD => F^{-1} SDD => c >= 0", with F = A'A + lambda I, A = B - y 1', B the K
    nearest templates of a candidate y (K in 5, 8, 10), recorded from tracker runs.
    Theorem 1 itself (F^{-1} PD and SDD => c > 0) is true; we count its violations
    too (must be zero).
(c) eq. (meavg): for 1'c = 1, Cauchy-Schwarz gives c'c >= 1/K (not 1/K^2 as printed).
(d) The paper's element estimates: a_ij in (-0.001, 0.003), (A'A)_ij <= 0.01.

``make theorem`` runs this; seconds on the synthetic suite.
"""
from __future__ import annotations

from fractions import Fraction

import matplotlib.pyplot as plt
import numpy as np

from experiments.grid import describe_params, json_report, script_entry
from experiments.internals import (
    LAMBDAS, N_NEAREST, PAPER_A_RANGE, PAPER_GRAM_BOUND, Budget, budget_for, collect_many, collections_for,
    limit, max_offdiag_row_sum, pooled, strictly_dd, sum_to_one_codes, tracker_params,
)
from experiments.tables import fmt, save_figure

STEM = "theorem1_checks"
#: ``report(context, data)``: writes ``<STEM>.json``, returns the report section.
report = json_report(STEM)
SIZES = (5, 8, 10)
#: Random K-subsets of the N_NEAREST nearest templates drawn per (K, lambda).
N_RANDOM_SUBSETS = 4000

SYNTHETIC_BUDGET = Budget(max_frames=30, every=5, n_candidates=100, max_sequences=3)
REAL_BUDGET = Budget(max_frames=30, every=5, n_candidates=100, max_sequences=4)

PAPER_F = [[5, 2, -2], [2, 5, 2], [-2, 2, 5]]


# --------------------------------------------------------------------------- (a)
def _fraction_inverse(matrix):
    """Exact inverse of a small matrix of Fractions (Gauss-Jordan)."""
    n = len(matrix)
    work = [[Fraction(v) for v in row] + [Fraction(int(i == j)) for j in range(n)] for i, row in enumerate(matrix)]
    for col in range(n):
        pivot = next(r for r in range(col, n) if work[r][col] != 0)
        work[col], work[pivot] = work[pivot], work[col]
        scale = work[col][col]
        work[col] = [v / scale for v in work[col]]
        for r in range(n):
            if r != col and work[r][col] != 0:
                factor = work[r][col]
                work[r] = [a - factor * b for a, b in zip(work[r], work[col])]
    return [row[n:] for row in work]


def _fraction_sdd(matrix) -> bool:
    return all(abs(row[i]) > sum(abs(v) for j, v in enumerate(row) if j != i) for i, row in enumerate(matrix))


def _leading_minors(matrix):
    """Exact leading principal minors (Sylvester: all > 0 iff PD for a symmetric matrix)."""
    minors = []
    for k in range(1, len(matrix) + 1):
        block = [[Fraction(v) for v in row[:k]] for row in matrix[:k]]
        det = Fraction(1)
        for col in range(k):
            pivot = next((r for r in range(col, k) if block[r][col] != 0), None)
            if pivot is None:
                det = Fraction(0)
                break
            if pivot != col:
                block[col], block[pivot] = block[pivot], block[col]
                det = -det
            det *= block[col][col]
            for r in range(col + 1, k):
                factor = block[r][col] / block[col][col]
                block[r] = [a - factor * b for a, b in zip(block[r], block[col])]
        minors.append(det)
    return minors


def paper_counterexample() -> dict:
    """Exact facts about the paper's 3x3 example."""
    F = [[Fraction(v) for v in row] for row in PAPER_F]
    inverse = _fraction_inverse(F)
    c = [sum(row) for row in inverse]
    minors = _leading_minors(F)
    eigenvalues = np.linalg.eigvalsh(np.array(PAPER_F, dtype=float))
    return {
        "F": PAPER_F,
        "F_symmetric": all(F[i][j] == F[j][i] for i in range(3) for j in range(3)),
        "F_strictly_diagonally_dominant": _fraction_sdd(F),
        "F_leading_minors": [str(m) for m in minors],
        "F_positive_definite": all(m > 0 for m in minors),
        "F_eigenvalues": eigenvalues.tolist(),
        "F_inverse_exact": [[str(v) for v in row] for row in inverse],
        "F_inverse": [[float(v) for v in row] for row in inverse],
        "F_inverse_strictly_diagonally_dominant": _fraction_sdd(inverse),
        "F_inverse_diagonally_dominant_weak": all(
            abs(row[i]) >= sum(abs(v) for j, v in enumerate(row) if j != i) for i, row in enumerate(inverse)),
        "c_exact": [str(v) for v in c],
        "c": [float(v) for v in c],
        "c_has_negative_entry": any(v < 0 for v in c),
        "c_sum_to_one_exact": [str(v / sum(c)) for v in c],
        "note": ("The paper writes this matrix as 'F^{-1} = (...)^{-1} = (...)' in its equation while the "
                 "text calls it F; the printed right-hand side (0.43, -0.29, 0.29, ...) is the inverse of "
                 "the displayed matrix, i.e. F^{-1} = (1/49)[[21,-14,14],[-14,21,-14],[14,-14,21]]."),
    }


def random_matrix_search(rng: np.random.Generator, n_trials: int = 20000) -> dict:
    """Random symmetric SDD matrices with positive diagonal (hence PD): how often is the
    inverse not SDD / is F^{-1} 1 not positive, for K = 2 (never, as the paper says) and 3..10."""
    out = {}
    for k in (2, 3, 5, 10):
        off = rng.uniform(-1, 1, size=(n_trials, k, k))
        off = (off + np.swapaxes(off, 1, 2)) / 2
        idx = np.arange(k)
        off[:, idx, idx] = 0
        rowsum = np.abs(off).sum(axis=2)
        diag = rowsum * (1 + rng.uniform(1e-3, 0.5, size=(n_trials, k)))
        F = off.copy()
        F[:, idx, idx] = diag
        inv = np.linalg.inv(F)
        c = inv.sum(axis=2)
        out[str(k)] = {"n": n_trials, "F_sdd": int(strictly_dd(F).sum()),
                       "F_inverse_not_sdd": int((~strictly_dd(inv)).sum()),
                       "c_negative": int((c < 0).any(axis=1).sum())}
    return out


# --------------------------------------------------------------------------- (b)-(d)
def _count(grams: np.ndarray, lam: float, eigen=None) -> dict:
    F = grams + lam * np.eye(grams.shape[-1])
    inverse, raw, codes = sum_to_one_codes(eigen if eigen is not None else grams, lam)
    f_sdd = strictly_dd(F)
    inv_sdd = strictly_dd(inverse)
    negative = (raw < 0).any(axis=-1)
    bound = max_offdiag_row_sum(grams)
    k = grams.shape[-1]
    kcc = k * np.einsum("nk,nk->n", codes, codes)
    return {
        "n": int(len(grams)),
        "F_sdd": int(f_sdd.sum()),
        "F_inverse_sdd": int(inv_sdd.sum()),
        "c_has_negative": int(negative.sum()),
        "negative_entry_share": float((raw < 0).mean()),
        "F_sdd_but_F_inverse_not_sdd": int((f_sdd & ~inv_sdd).sum()),
        "F_sdd_and_c_negative": int((f_sdd & negative).sum()),
        "F_sdd_F_inverse_not_sdd_c_negative": int((f_sdd & ~inv_sdd & negative).sum()),
        "F_inverse_sdd_and_c_negative": int((inv_sdd & negative).sum()),
        "eq_lambda_bound_holds": int((lam > bound).sum()),
        "min_K_ctc": float(kcc.min()),
        "mean_K_ctc": float(kcc.mean()),
    }, (f_sdd & ~inv_sdd), (f_sdd & negative), kcc


def _example(grams: np.ndarray, mask: np.ndarray, lam: float) -> dict | None:
    hits = np.flatnonzero(mask)
    if not hits.size:
        return None
    G = grams[hits[0]]
    F = G + lam * np.eye(len(G))
    inverse = np.linalg.inv(F)
    return {"lambda": lam, "K": len(G), "F": np.round(F, 6).tolist(), "F_inverse": np.round(inverse, 4).tolist(),
            "c": np.round(inverse.sum(axis=1), 4).tolist()}


def runs(context) -> list:
    """The recorded internals this script reads."""
    budget = budget_for(context, SYNTHETIC_BUDGET, REAL_BUDGET)
    return collections_for(context, limit(context.paper_sequences() or context.sequences(), budget), budget)


def collect(context) -> dict:
    """The numbers and what the figure needs (the JSON, the plot's inputs, the report section)."""
    budget = budget_for(context, SYNTHETIC_BUDGET, REAL_BUDGET)
    rng = np.random.default_rng(20160101)

    exact = paper_counterexample()
    random_matrices = random_matrix_search(rng)
    print("(a) paper's 3x3 example F =", PAPER_F)
    print(f"    F strictly diagonally dominant: {exact['F_strictly_diagonally_dominant']}, positive definite: "
          f"{exact['F_positive_definite']} (leading minors {', '.join(exact['F_leading_minors'])})")
    print(f"    F^-1 = {exact['F_inverse_exact']}  strictly diagonally dominant: "
          f"{exact['F_inverse_strictly_diagonally_dominant']}")
    print(f"    c = F^-1 1 = {exact['c_exact']}  negative entry: {exact['c_has_negative_entry']}")

    sequences = limit(context.paper_sequences() or context.sequences(), budget)
    collections = collect_many(context, sequences, budget)
    grams = pooled(collections, "gram")
    n_near = grams.shape[-1]

    nearest, random_subsets, examples = {}, {}, {}
    kcc_all = []
    for k in SIZES:
        block = np.ascontiguousarray(grams[:, :k, :k])
        picks = rng.integers(0, len(grams), size=N_RANDOM_SUBSETS)
        subsets = np.argsort(rng.random((N_RANDOM_SUBSETS, n_near)), axis=1)[:, :k]
        subset_grams = grams[picks[:, None, None], subsets[:, :, None], subsets[:, None, :]]
        nearest[str(k)], random_subsets[str(k)] = {}, {}
        eigen = {"nearest": np.linalg.eigh(block), "random_subset": np.linalg.eigh(subset_grams)}
        for lam in LAMBDAS:
            for name, source, table in (("nearest", block, nearest), ("random_subset", subset_grams, random_subsets)):
                counts, route, sign, kcc = _count(source, lam, eigen[name])
                table[str(k)][str(lam)] = counts
                kcc_all.append(kcc)
                for kind, mask in (("F_sdd_F_inverse_not_sdd", route), ("F_sdd_c_negative", sign)):
                    key = f"{kind}/{name}"
                    if key not in examples:
                        example = _example(source, mask, lam)
                        if example is not None:
                            examples[key] = example
    kcc_all = np.concatenate(kcc_all)

    # (c) meavg on random simplex-sum vectors too (any 1'c = 1, signs free).
    random_c = rng.standard_normal((20000, 10))
    random_c /= random_c.sum(axis=1, keepdims=True)
    random_kcc = 10 * np.einsum("nk,nk->n", random_c, random_c)

    # (d) element ranges (A over the 10 nearest templates).
    a_sample = pooled(collections, "a_sample").ravel()
    a_min, a_max = pooled(collections, "a_min"), pooled(collections, "a_max")
    g10 = grams[:, :10, :10]
    off = ~np.eye(10, dtype=bool)
    inside = (a_sample > PAPER_A_RANGE[0]) & (a_sample < PAPER_A_RANGE[1])
    elements = {
        "a_min": float(a_min.min()), "a_max": float(a_max.max()),
        "a_sample_percentiles": {q: float(np.percentile(a_sample, q)) for q in (1, 5, 50, 95, 99)},
        "share_a_inside_paper_range": float(inside.mean()),
        "gram_offdiag_min": float(g10[:, off].min()), "gram_offdiag_max": float(g10[:, off].max()),
        "gram_diag_min": float(np.diagonal(g10, axis1=1, axis2=2).min()),
        "gram_diag_max": float(np.diagonal(g10, axis1=1, axis2=2).max()),
        "share_gram_abs_le_0.01": float((np.abs(g10) <= PAPER_GRAM_BOUND).mean()),
        "max_offdiag_row_sum_K10": float(max_offdiag_row_sum(g10).max()),
        "median_offdiag_row_sum_K10": float(np.median(max_offdiag_row_sum(g10))),
    }

    frames = {c["name"]: c["frames"].tolist() for c in collections}
    result = {
        "paper_counterexample": exact,
        "random_sdd_matrices": random_matrices,
        "data": {"label": context.data_label, "sequences": [s.name for s in sequences], "seed": 0,
                 "params": describe_params(tracker_params(budget, context)),
                 "budget": budget.__dict__, "frames": frames, "n_candidates": int(len(grams)),
                 "n_nearest_recorded": int(n_near), "random_subsets_per_K_lambda": N_RANDOM_SUBSETS},
        "nearest_dictionaries": nearest,
        "random_subset_dictionaries": random_subsets,
        "examples": examples,
        "meavg": {"min_K_ctc_tracker_codes": float(kcc_all.min()), "min_K_ctc_random_sum_to_one": float(random_kcc.min()),
                  "cauchy_schwarz_bound": "c'c >= 1/K", "paper_bound": "c'c >= 1/K^2",
                  "paper_bound_loose_by_factor": "K"},
        "elements": elements,
    }
    section = {"title": "Theorem 1: numeric checks", "figures": [f"{STEM}.png"],
               "markdown": _markdown(result, context, sequences, budget)}
    return {"result": result, "plot": (nearest, random_subsets), "section": section}


def plot(data: dict, path) -> None:
    nearest, random_subsets = data["plot"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    colours = {"5": "tab:blue", "8": "tab:orange", "10": "tab:green"}
    for k, by_lambda in nearest.items():
        lams = [float(l) for l in by_lambda]
        neg = [v["c_has_negative"] / v["n"] for v in by_lambda.values()]
        axes[0].plot(lams, neg, "o-", color=colours[k], label=f"K={k} nearest")
        rneg = [v["c_has_negative"] / v["n"] for v in random_subsets[k].values()]
        axes[0].plot(lams, rneg, "x--", color=colours[k], alpha=0.6, label=f"K={k} random subset")
        f_sdd = [v["F_sdd"] / v["n"] for v in by_lambda.values()]
        inv_sdd = [v["F_inverse_sdd"] / v["n"] for v in by_lambda.values()]
        axes[1].plot(lams, f_sdd, "o-", color=colours[k], label=f"F SDD, K={k}")
        axes[1].plot(lams, inv_sdd, "s:", color=colours[k], label=f"F$^{{-1}}$ SDD, K={k}")
    for ax in axes:
        ax.set_xscale("symlog", linthresh=0.01)
        ax.set_xlabel(r"$\lambda$")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("fraction of candidates with some $c_i<0$")
    axes[1].set_ylabel("fraction strictly diagonally dominant")
    axes[0].legend(fontsize=7)
    axes[1].legend(fontsize=7)
    fig.suptitle(r"Theorem 1 on patch data: $F=A^TA+\lambda I$, $c=F^{-1}1$", fontsize=10)
    save_figure(fig, path, dpi=120)


def _markdown(result, context, sequences, budget) -> str:
    ex = result["paper_counterexample"]
    data = result["data"]
    lines = [
        "### Theorem 1: numeric checks",
        "",
        "**(a) The paper's 3x3 counterexample** (exact rational arithmetic). "
        "F = [[5,2,-2],[2,5,2],[-2,2,5]]: strictly diagonally dominant: "
        f"**{ex['F_strictly_diagonally_dominant']}**; positive definite: **{ex['F_positive_definite']}** "
        f"(leading minors {', '.join(ex['F_leading_minors'])}; eigenvalues "
        f"{', '.join(f'{v:.3g}' for v in ex['F_eigenvalues'])}). "
        f"F^-1 = (1/49)[[21,-14,14],[-14,21,-14],[14,-14,21]] (paper prints 0.43, -0.29, 0.29): strictly "
        f"diagonally dominant: **{ex['F_inverse_strictly_diagonally_dominant']}** (not even weakly: "
        f"{ex['F_inverse_diagonally_dominant_weak']}). c = F^-1 1 = ({', '.join(ex['c_exact'])}): negative entry: "
        f"**{ex['c_has_negative_entry']}** (sum-to-one: {', '.join(ex['c_sum_to_one_exact'])}). "
        "So the example refutes \"F SDD => F^-1 SDD\" and, further, \"F SDD => c >= 0\". "
        "Note: the paper's equation labels the displayed matrix F^-1 (\"F^-1 = (...)^-1\") while the text calls it F.",
        "",
    ]
    rm = result["random_sdd_matrices"]
    lines.append("Random symmetric SDD matrices with positive diagonal (20000 per K): inverse not SDD in "
                 + ", ".join(f"K={k}: {v['F_inverse_not_sdd']}" for k, v in rm.items())
                 + "; F^-1 1 with a negative entry in "
                 + ", ".join(f"K={k}: {v['c_negative']}" for k, v in rm.items())
                 + " (the paper: the implication holds only for K <= 2).")
    lines += [
        "",
        f"**(b) Randomised search on patch data** ({data['label']}; sequences {', '.join(data['sequences'])}; "
        f"tracker seed 0, {data['params']}; {budget.describe()}; {data['n_candidates']} candidates in all; "
        f"recorded frames: " + "; ".join(f"{n}: {', '.join(map(str, f))}" for n, f in data["frames"].items())
        + f"). F = A'A + lambda I with A = B - y1', B the K nearest templates (the tracker's dictionaries), and "
        f"B a random K-subset of the {N_NEAREST} nearest ({N_RANDOM_SUBSETS} draws per K and lambda). "
        "Counts: SDD = strictly diagonally dominant; c- = c has a negative entry; "
        "\"F SDD, F^-1 not\" counts counterexamples to the paper's route; "
        "\"F^-1 SDD, c-\" would contradict Theorem 1 (it must be 0).",
        "",
        "| K | lambda | n | F SDD | F^-1 SDD | c- | F SDD, F^-1 not | F SDD, c- | F^-1 SDD, c- | eq.(lambda) holds "
        "| random: F SDD, F^-1 not | random: c- |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for k, by_lambda in result["nearest_dictionaries"].items():
        for lam, v in by_lambda.items():
            r = result["random_subset_dictionaries"][k][lam]
            lines.append(f"| {k} | {lam} | {v['n']} | {v['F_sdd']} | {v['F_inverse_sdd']} | {v['c_has_negative']} | "
                         f"{v['F_sdd_but_F_inverse_not_sdd']} | {v['F_sdd_and_c_negative']} | "
                         f"{v['F_inverse_sdd_and_c_negative']} | {v['eq_lambda_bound_holds']} | "
                         f"{r['F_sdd_but_F_inverse_not_sdd']}/{r['n']} | {r['c_has_negative']}/{r['n']} |")
    total_route = sum(v["F_sdd_but_F_inverse_not_sdd"] for b in result["nearest_dictionaries"].values() for v in b.values())
    total_route_r = sum(v["F_sdd_but_F_inverse_not_sdd"] for b in result["random_subset_dictionaries"].values()
                        for v in b.values())
    total_theorem = sum(v["F_inverse_sdd_and_c_negative"] for d in ("nearest_dictionaries", "random_subset_dictionaries")
                        for b in result[d].values() for v in b.values())
    lines += [
        "",
        f"Counterexamples to \"F SDD => F^-1 SDD\" found on patch data: {total_route} (nearest dictionaries), "
        f"{total_route_r} (random subsets). Violations of Theorem 1 itself: {total_theorem} (expected 0).",
    ]
    total_sign = sum(v["F_sdd_and_c_negative"] for d in ("nearest_dictionaries", "random_subset_dictionaries")
                     for b in result[d].values() for v in b.values())
    lines.append(f"Cases where F is SDD and c = F^-1 1 still has a negative entry (like the paper's 3x3 example): "
                 f"{total_sign} in all.")
    labels = {"F_sdd_F_inverse_not_sdd": "F SDD but F^-1 not SDD", "F_sdd_c_negative": "F SDD but c has a negative entry"}
    for key, example in result["examples"].items():
        kind, source = key.split("/")
        lines.append(f"First case of '{labels[kind]}' ({source.replace('_', ' ')} dictionaries): K = {example['K']}, "
                     f"lambda = {example['lambda']}, c = F^-1 1 = {example['c']} (full F in the JSON).")
    route_negative = sum(v["F_sdd_F_inverse_not_sdd_c_negative"]
                         for d in ("nearest_dictionaries", "random_subset_dictionaries")
                         for b in result[d].values() for v in b.values())
    lines.append(f"Of the {total_route + total_route_r} cases with F SDD but F^-1 not SDD, {route_negative} have a "
                 "negative entry in c: Theorem 1's condition is sufficient, not necessary.")
    m = result["meavg"]
    lines += [
        "",
        f"**(c) eq. (meavg).** For 1'c = 1, Cauchy-Schwarz gives c'c >= (1'c)^2/K = 1/K, with equality at "
        f"c = 1/K; the paper prints 1/K^2, which is loose by a factor K (its own equality case c = 1/K gives "
        f"c'c = 1/K, not 1/K^2). Observed min of K c'c: {m['min_K_ctc_tracker_codes']:.6f} over all data codes "
        f"(every K and lambda above) and {m['min_K_ctc_random_sum_to_one']:.6f} over 20000 random sum-to-one "
        f"vectors (K = 10) - both >= 1; i.e. c'c/(1/K^2) >= K.",
        "",
    ]
    e = result["elements"]
    lines += [
        "**(d) The paper's element estimates** (A over the 10 nearest templates, unit-norm 1024-vectors). "
        f"Paper: a_ij in (-0.001, 0.003); observed a_ij range [{fmt(e['a_min'])}, {fmt(e['a_max'])}], "
        f"1st-99th percentile [{fmt(e['a_sample_percentiles'][1])}, {fmt(e['a_sample_percentiles'][99])}], "
        f"share inside the paper's interval {e['share_a_inside_paper_range']:.1%}. "
        f"Paper: (A'A)_ij <= 0.01; observed off-diagonal (A'A)_ij in [{fmt(e['gram_offdiag_min'])}, "
        f"{fmt(e['gram_offdiag_max'])}], diagonal in [{fmt(e['gram_diag_min'])}, {fmt(e['gram_diag_max'])}], "
        f"share of entries with |.| <= 0.01: {e['share_gram_abs_le_0.01']:.1%}. Max off-diagonal row sum "
        f"(eq. lambda's right-hand side, K = 10): median {fmt(e['median_offdiag_row_sum_K10'])}, max "
        f"{fmt(e['max_offdiag_row_sum_K10'])} (paper's eq. est_lambda: <= 0.01 (K-1) = 0.09).",
    ]
    return "\n".join(lines) + "\n"


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
