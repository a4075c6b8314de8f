"""How non-negative are the l2-regularised codes, as a function of lambda? (paper Sec. 3.3)

The tracker runs once per sequence (default parameters, seed 0); at sampled frames
its candidates' local Grams ``G = A'A`` are recorded (:mod:`experiments.analysis_common`).
The *same* candidates are then re-coded with numpy for every lambda of the paper's
sweep (c = F^{-1} 1 / 1'F^{-1} 1, F = A'A + lambda I, K = 5, 8, 10; w from eq. allcw
with beta = 0.1 and beta = 0), and we report:

* the share of negative entries in c and in w (and in the output code d);
* how often F^{-1} is strictly diagonally dominant (Theorem 1's hypothesis) and
  how often eq. (lambda) holds (lambda > max_i sum_{j != i} |(A'A)_ij|);
* the observed element ranges of A and A'A against the paper's estimates
  a_ij in (-0.001, 0.003) and (A'A)_ij <= 0.01.
"""
from __future__ import annotations


import matplotlib.pyplot as plt
import numpy as np

from experiments.grid import describe_params, script_entry
from experiments.internals import (
    LAMBDAS, PAPER_A_RANGE, PAPER_GRAM_BOUND, budget_for, collect_many, dictionary_weights, limit,
    max_offdiag_row_sum, pooled, strictly_dd, sum_to_one_codes, tracker_params,
)
from experiments.shared import STATS_REAL_BUDGET as REAL_BUDGET
from experiments.shared import STATS_SYNTHETIC_BUDGET as SYNTHETIC_BUDGET
from experiments.shared import stats_runs as runs  # noqa: F401 (this script's runs(context))
from experiments.tables import fmt, percentiles, save_figure, write_csv
from nrmlc.io import write_json

STEM = "stats_nonnegativity"
SIZES = (5, 8, 10)
BETAS = (0.1, 0.0)


def analyse(grams: np.ndarray, is_best: np.ndarray, lams=LAMBDAS, sizes=SIZES, betas=BETAS) -> list[dict]:
    """One row per lambda: nonnegativity statistics of the same candidates."""
    rows = []
    bound = {k: max_offdiag_row_sum(grams[:, :k, :k]) for k in sizes}
    eigen = {k: np.linalg.eigh(grams[:, :k, :k]) for k in sizes}  # reused for every lambda
    k_max = max(sizes)
    for lam in lams:
        row = {"lambda": float(lam)}
        codes_by_size = []
        negative_entries, total_entries = 0, 0
        any_negative = np.zeros(len(grams), dtype=bool)
        for k in sizes:
            block = grams[:, :k, :k]
            inverse, raw, codes = sum_to_one_codes(eigen[k], lam)
            codes_by_size.append(codes)
            negative = codes < 0
            negative_entries += int(negative.sum())
            total_entries += negative.size
            any_negative |= negative.any(axis=1)
            F = block + lam * np.eye(k)
            row[f"c_negative_share_K{k}"] = float(negative.mean())
            row[f"F_sdd_K{k}"] = float(strictly_dd(F).mean())
            row[f"F_inverse_sdd_K{k}"] = float(strictly_dd(inverse).mean())
            row[f"eq_lambda_holds_K{k}"] = float((lam > bound[k]).mean())
            row[f"est_lambda_holds_K{k}"] = float(lam >= 0.01 * (k - 1))
        row["c_negative_share"] = negative_entries / total_entries
        row["c_any_negative_share"] = float(any_negative.mean())
        row["c_negative_share_best"] = float(np.mean([(c[is_best] < 0).mean() for c in codes_by_size]))
        for beta in betas:
            w = dictionary_weights(grams[:, :k_max, :k_max], codes_by_size, beta)
            row[f"w_negative_share_beta{beta:g}"] = float((w < 0).mean())
            row[f"w_any_negative_share_beta{beta:g}"] = float((w < 0).any(axis=1).mean())
            d = np.zeros((len(grams), k_max))
            for j, codes in enumerate(codes_by_size):
                d[:, : codes.shape[1]] += w[:, j:j + 1] * codes
            row[f"d_negative_share_beta{beta:g}"] = float((d < -1e-12).mean())
        rows.append(row)
    return rows


def element_ranges(collections: list[dict], grams: np.ndarray) -> dict:
    a_sample = pooled(collections, "a_sample").ravel()
    g10 = grams[:, :10, :10]
    off = ~np.eye(10, dtype=bool)
    offdiag = g10[:, off]
    diag = np.diagonal(g10, axis1=1, axis2=2)
    row_sums = max_offdiag_row_sum(g10)
    return {
        "a_min": float(pooled(collections, "a_min").min()),
        "a_max": float(pooled(collections, "a_max").max()),
        "a_percentiles": percentiles(a_sample),
        "a_share_inside_paper_range": float(((a_sample > PAPER_A_RANGE[0]) & (a_sample < PAPER_A_RANGE[1])).mean()),
        "gram_offdiag_percentiles": percentiles(offdiag),
        "gram_diag_percentiles": percentiles(diag),
        "gram_share_abs_le_0.01": float((np.abs(g10) <= PAPER_GRAM_BOUND).mean()),
        "gram_offdiag_share_abs_le_0.01": float((np.abs(offdiag) <= PAPER_GRAM_BOUND).mean()),
        "max_offdiag_row_sum_K10_percentiles": percentiles(row_sums),
        "n_a_samples": int(a_sample.size),
        "row_sum_share_le_0.09": float((row_sums <= 0.09).mean()),
    }


def tracker_agreement(collections: list[dict], grams: np.ndarray, p) -> dict:
    """Our numpy solution at the tracker's own lambda/beta vs the codes the tracker computed."""
    coefficients = pooled(collections, "coefficients")
    weights = pooled(collections, "weights")
    codes_by_size = [sum_to_one_codes(grams[:, :k, :k], p.lam)[2] for k in p.dictionary_sizes]
    diff_c = max(float(np.abs(c - coefficients[:, j, : c.shape[1]]).max()) for j, c in enumerate(codes_by_size))
    w = dictionary_weights(grams[:, : p.k_max, : p.k_max], codes_by_size, p.beta)
    return {"lambda": p.lam, "beta": p.beta, "max_abs_diff_c": diff_c, "max_abs_diff_w": float(np.abs(w - weights).max())}


def collect(context) -> dict:
    """The numbers and what the figure needs (the JSON, the plot's inputs, the report section)."""
    budget = budget_for(context, SYNTHETIC_BUDGET, REAL_BUDGET)
    sequences = limit(context.sequences(), budget)
    params = tracker_params(budget, context)
    collections = collect_many(context, sequences, budget, params=params)
    grams = pooled(collections, "gram")
    is_best = pooled(collections, "is_best")
    rows = analyse(grams, is_best)
    ranges = element_ranges(collections, grams)
    agreement = tracker_agreement(collections, grams, params)
    frames = {c["name"]: c["frames"].tolist() for c in collections}
    result = {"data": {"label": context.data_label, "sequences": [s.name for s in sequences], "seed": 0,
                       "params": describe_params(params),
                       "budget": budget.__dict__, "frames": frames, "n_candidates": int(len(grams))},
              "by_lambda": rows, "elements": ranges, "tracker_agreement": agreement}
    section = {"title": "Non-negativity of the regularised codes vs lambda", "figures": [f"{STEM}.png"],
               "markdown": _markdown(result, budget)}
    return {"result": result, "plot": (rows, collections, grams), "section": section}


def plot(data: dict, path) -> None:
    rows, collections, grams = data["plot"]
    lams = [r["lambda"] for r in rows]
    fig, axes = plt.subplots(2, 2, figsize=(10, 7))
    ax = axes[0, 0]
    for k in SIZES:
        ax.plot(lams, [r[f"c_negative_share_K{k}"] for r in rows], "o-", label=f"c, K={k}")
    for beta in BETAS:
        ax.plot(lams, [r[f"w_negative_share_beta{beta:g}"] for r in rows], "s--", label=rf"w, $\beta$={beta:g}")
    ax.set_ylabel("share of negative entries")
    ax.set_title("negative entries vs $\\lambda$", fontsize=9)
    ax = axes[0, 1]
    for k in SIZES:
        line, = ax.plot(lams, [r[f"F_inverse_sdd_K{k}"] for r in rows], "o-", label=f"$F^{{-1}}$ SDD, K={k}")
        ax.plot(lams, [r[f"eq_lambda_holds_K{k}"] for r in rows], "x:", color=line.get_color(),
                label=f"eq. ($\\lambda$) holds, K={k}")
    ax.set_ylabel("fraction of candidates")
    ax.set_title("Theorem 1 hypothesis and eq. ($\\lambda$)", fontsize=9)
    for ax in axes[0]:
        ax.set_xscale("symlog", linthresh=0.01)
        ax.set_xlabel(r"$\lambda$")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    a_sample = pooled(collections, "a_sample").ravel()
    ax = axes[1, 0]
    ax.hist(a_sample, bins=120, color="0.5")
    ax.axvspan(*PAPER_A_RANGE, color="red", alpha=0.3, label="paper: (-0.001, 0.003)")
    ax.set_xlabel("$a_{ij}$ (A = B - y1', K = 10)")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    g10 = grams[:, :10, :10]
    off = ~np.eye(10, dtype=bool)
    ax.hist(g10[:, off].ravel(), bins=120, alpha=0.6, label="off-diagonal")
    ax.hist(np.diagonal(g10, axis1=1, axis2=2).ravel(), bins=120, alpha=0.6, label="diagonal")
    ax.axvline(PAPER_GRAM_BOUND, color="red", label="paper bound 0.01")
    ax.set_xlabel("$(A^TA)_{ij}$")
    ax.set_yscale("log")
    ax.legend(fontsize=7)
    save_figure(fig, path, dpi=120)


def _at(rows, lam):
    return next(r for r in rows if r["lambda"] == lam)


def _first_clean(rows) -> str:
    """Smallest lambda from which no c entry was negative (for every larger lambda too)."""
    clean = None
    for r in reversed(rows):
        if r["c_negative_share"] > 0:
            break
        clean = r["lambda"]
    return "none of the tested values" if clean is None else f"{clean:g}"


def _markdown(result, budget) -> str:
    data, rows, e, agree = result["data"], result["by_lambda"], result["elements"], result["tracker_agreement"]
    lines = [
        "### Non-negativity of the regularised codes vs lambda",
        "",
        f"Data: {data['label']}; sequences {', '.join(data['sequences'])}; tracker seed 0, {data['params']}; "
        f"{budget.describe()}; {data['n_candidates']} candidates, each re-coded for every "
        "lambda (same candidates, numpy closed forms c = F^-1 1 / 1'F^-1 1). Recorded frames: "
        + "; ".join(f"{n}: {f[0]}..{f[-1]} ({len(f)} frames)" for n, f in data["frames"].items()) + ".",
        f"Check against the tracker's own codes at lambda = {agree['lambda']:g}, beta = {agree['beta']:g}: "
        f"max |c_numpy - c_tracker| = {agree['max_abs_diff_c']:.1e}, max |w_numpy - w_tracker| = "
        f"{agree['max_abs_diff_w']:.1e}.",
        "",
        "The paper claims (Sec. 3.3) that lambda = 1 (and even smaller lambda) keeps c non-negative and that "
        "eq. (est_lambda) lambda >= 0.01 (K-1) suffices; columns: share of negative entries of c (K = 5, 8, 10 "
        "pooled) and of w, fraction of candidates with F^-1 strictly diagonally dominant (Theorem 1's hypothesis) "
        "and with eq. (lambda) satisfied (lambda > max row off-diagonal |A'A| sum).",
        "",
        "| lambda | c<0 share | any c^j<0 | c<0 (best cand.) | w<0, beta=0.1 | w<0, beta=0 | d<0, beta=0.1 | "
        "F^-1 SDD K=5/8/10 | eq.(lambda) K=5/8/10 | est_lambda 0.01(K-1) <= lambda, K=5/8/10 |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['lambda']:g} | {r['c_negative_share']:.3%} | {r['c_any_negative_share']:.3%} | "
            f"{r['c_negative_share_best']:.3%} | {r['w_negative_share_beta0.1']:.3%} | "
            f"{r['w_negative_share_beta0']:.3%} | {r['d_negative_share_beta0.1']:.3%} | "
            + "/".join(f"{r[f'F_inverse_sdd_K{k}']:.2f}" for k in SIZES) + " | "
            + "/".join(f"{r[f'eq_lambda_holds_K{k}']:.2f}" for k in SIZES) + " | "
            + "/".join("yes" if r[f"est_lambda_holds_K{k}"] else "no" for k in SIZES) + " |")
    ap, gp, dp, rp = e["a_percentiles"], e["gram_offdiag_percentiles"], e["gram_diag_percentiles"], \
        e["max_offdiag_row_sum_K10_percentiles"]
    lines += [
        "",
        "Element ranges (A = B - y1' over the 10 nearest templates; unit-norm 1024-vectors):",
        "",
        "| quantity | paper | observed min | p1 | p50 | p99 | observed max |",
        "|---|---|---|---|---|---|---|",
        f"| a_ij | (-0.001, 0.003) | {fmt(e['a_min'])} | {fmt(ap['p1'])} | {fmt(ap['p50'])} | {fmt(ap['p99'])} | "
        f"{fmt(e['a_max'])} |",
        f"| (A'A)_ij, i != j | <= 0.01 | {fmt(gp['p0'])} | {fmt(gp['p1'])} | {fmt(gp['p50'])} | {fmt(gp['p99'])} | "
        f"{fmt(gp['p100'])} |",
        f"| (A'A)_ii | <= 0.01 | {fmt(dp['p0'])} | {fmt(dp['p1'])} | {fmt(dp['p50'])} | {fmt(dp['p99'])} | "
        f"{fmt(dp['p100'])} |",
        f"| max_i sum_j!=i |(A'A)_ij|, K=10 | <= 0.09 (eq. est_lambda) | {fmt(rp['p0'])} | {fmt(rp['p1'])} | "
        f"{fmt(rp['p50'])} | {fmt(rp['p99'])} | {fmt(rp['p100'])} |",
        "",
        f"Share of a_ij inside the paper's (-0.001, 0.003): {e['a_share_inside_paper_range']:.1%} "
        f"(of {e['n_a_samples']} sampled entries); share of |(A'A)_ij| <= 0.01: {e['gram_share_abs_le_0.01']:.1%} "
        f"(off-diagonal only: {e['gram_offdiag_share_abs_le_0.01']:.1%}). The paper's interval is the spread of "
        "patch *means* (0.026-0.03), not of pixel differences, so it underestimates the element range, and "
        f"the row sums of eq. (lambda) exceed its estimate 0.01 (K-1) = 0.09 (K = 10) for "
        f"{1 - e['row_sum_share_le_0.09']:.1%} of candidates. lambda = 1 satisfies eq. (lambda) for "
        f"{_at(rows, 1.0)['eq_lambda_holds_K10']:.1%} of candidates at K = 10; c had no negative entry from "
        f"lambda = {_first_clean(rows)} on.",
    ]
    return "\n".join(lines) + "\n"


def report(context, data: dict) -> dict:
    """Write ``data["result"]`` as JSON; returns the report section."""
    write_json(context.output(STEM, ".json"), data["result"])
    rows = data["result"]["by_lambda"]
    write_csv(context.output(STEM, ".csv"), list(rows[0]), [list(r.values()) for r in rows])
    return data["section"]


#: ``python -m experiments.<script> [options]``: this script alone, with the options of ``make figures``.
main = script_entry(__name__)
