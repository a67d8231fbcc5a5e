"""The metric leaderboard: scopes, multiple-testing corrections, metric noise, LOO prediction."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import stats

from repbench.analysis.correlation import (
    adjust_pvalues,
    correlate,
    leave_one_out,
    metric_leaderboard,
    spearman_permutation_p,
)


def test_adjusted_pvalues_are_statsmodels_holm_and_bh() -> None:
    p = [0.01, 0.04, 0.03, float("nan")]
    holm = adjust_pvalues(p, "holm")
    bh = adjust_pvalues(p, "fdr_bh")
    # Holm: sorted 0.01*3, max(0.03*2, prev), max(0.04*1, prev); BH: min over k of p_(k) m / k
    np.testing.assert_allclose(holm[:3], [0.03, 0.06, 0.06])
    np.testing.assert_allclose(bh[:3], [0.03, 0.04, 0.04])
    assert np.isnan(holm[3]) and np.isnan(bh[3])


def test_leave_one_out_of_a_linear_metric_is_exact() -> None:
    vals = {f"e{i}": float(i) for i in range(6)}
    rets = {f"e{i}": 10.0 + 3.0 * i for i in range(6)}
    loo = leave_one_out(vals, rets)
    assert loo["loo_rmse"] == pytest.approx(0.0, abs=1e-9)
    assert loo["loo_rmse_ratio"] == pytest.approx(0.0, abs=1e-9)
    assert loo["predictions"]["e5"] == pytest.approx(25.0)


def test_leave_one_out_of_noise_is_no_better_than_the_mean() -> None:
    rng = np.random.default_rng(0)
    ratios = []
    for _ in range(20):
        vals = {f"e{i}": float(v) for i, v in enumerate(rng.normal(size=10))}
        rets = {f"e{i}": float(v) for i, v in enumerate(rng.normal(size=10))}
        ratios.append(leave_one_out(vals, rets)["loo_rmse_ratio"])
    # an unrelated metric fits a spurious slope: LOO error at or above the mean's
    assert np.median(ratios) > 1.0


def test_metric_replicates_widen_the_interval() -> None:
    encs = [f"e{i}" for i in range(10)]
    vals = {e: float(i) for i, e in enumerate(encs)}
    rets = {e: [float(i), float(i) + 0.5, float(i) - 0.5] for i, e in enumerate(encs)}
    plain = correlate(vals, rets, higher_is_better=True, n_bootstrap=500)
    noisy_reps = {e: list(float(i) + 8.0 * np.random.default_rng(i).normal(size=100))
                  for i, e in enumerate(encs)}
    noisy = correlate(vals, rets, higher_is_better=True, n_bootstrap=500,
                      metric_replicates=noisy_reps)
    assert noisy["spearman"] == plain["spearman"]  # the point estimate is unchanged
    width = lambda c: c["spearman_ci_high"] - c["spearman_ci_low"]  # noqa: E731
    assert width(noisy) > 2 * width(plain)


def test_noise_shared_by_all_encoders_does_not_widen_the_interval() -> None:
    """Replicate b of every encoder comes from the same resample of held-out episodes: a shift
    common to all encoders in replicate b leaves their ranking, and so the interval, as it is."""
    encs = [f"e{i}" for i in range(10)]
    vals = {e: float(i) for i, e in enumerate(encs)}
    rets = {e: [float(i), float(i) + 0.5, float(i) - 0.5] for i, e in enumerate(encs)}
    shift = 8.0 * np.random.default_rng(0).normal(size=100)
    shared = {e: list(float(i) + shift) for i, e in enumerate(encs)}
    plain = correlate(vals, rets, higher_is_better=True, n_bootstrap=500)
    common = correlate(vals, rets, higher_is_better=True, n_bootstrap=500,
                       metric_replicates=shared)
    for key in ("spearman_ci_low", "spearman_ci_high", "kendall_ci_low", "kendall_ci_high"):
        assert common[key] == pytest.approx(plain[key], abs=1e-12), key


def _records() -> tuple[list[dict], list[dict], dict[str, str]]:
    """Baselines anchor the correlation; within the learned encoders the metric is reversed."""
    enc_value_return = {"oracle": (10.0, 100.0), "blind": (0.0, 0.0),
                        "vae_a": (5.0, 40.0), "vae_b": (6.0, 35.0), "vae_c": (7.0, 30.0),
                        "vae_d": (8.0, 25.0), "vae_e": (9.0, 20.0)}
    metric_rows, rl_rows = [], []
    for e, (v, r) in enc_value_return.items():
        metric_rows.append({"task": "T", "encoder": e, "metric": "m", "value": v, "time_s": 2.0,
                            "stage_cpu_s": 1.0 + v,  # vae_a..e: 6..10, oracle 11, blind 1
                            "extras": {"bootstrap_replicates": [v - 0.1, v, v + 0.1]}})
        metric_rows.append({"task": "T", "encoder": e, "metric": "cost_only", "value": -v,
                            "time_s": 0.5})
        for s in range(3):
            rl_rows.append({"task": "T", "encoder": e, "agent": "sac", "seed": s,
                            "eval_return": r + s - 1.0})
    families = {"oracle": "baseline", "blind": "baseline"}
    return metric_rows, rl_rows, families


def test_within_family_scope_excludes_the_baselines_that_anchor_the_correlation() -> None:
    metric_rows, rl_rows, families = _records()
    rows, preds = metric_leaderboard(metric_rows, rl_rows, families,
                                     {"m": True, "cost_only": False}, n_bootstrap=200)
    m = next(r for r in rows if r["metric"] == "m")
    assert m["n_all"] == 7 and m["n_learned"] == 5
    # oracle and blind make the pooled ρ positive: Σd² = 40 over 7 ranks, 1 − 6·40/(7·48)
    assert m["spearman_all"] == pytest.approx(2 / 7)
    assert m["spearman_learned"] == pytest.approx(-1.0)  # reversed among the VAEs
    assert m["cost_s"] == pytest.approx(2.0)
    assert m["cost_cpu_s"] == pytest.approx((6 + 7 + 8 + 9 + 10 + 11 + 1) / 7)
    for scope in ("all", "learned"):
        assert m[f"spearman_{scope}_p_holm"] >= m[f"spearman_{scope}_p"]
        assert m[f"spearman_{scope}_p_bh"] >= m[f"spearman_{scope}_p"]
    assert set(preds[("T", "sac", "m")]) == set(families) | {f"vae_{c}" for c in "abcde"}
    # lower-is-better "cost_only" is the sign-flipped m: same correlations
    c = next(r for r in rows if r["metric"] == "cost_only")
    assert c["spearman_learned"] == pytest.approx(m["spearman_learned"])
    assert np.isnan(c["cost_cpu_s"])  # its rows carry no CPU time: unknown, not 0


def test_costs_in_cpu_seconds_come_from_the_records_timings() -> None:
    """``fit_cpu_s`` (encoders.csv) and the metrics' ``stage_cpu_s`` are the CPU seconds each
    stage's record holds, unlike ``fit_time_s``, the fit's wall time."""
    from pathlib import Path

    from repbench.analysis.results import build_results, load_records

    records = load_records(Path(__file__).parents[2] / "leaderboards" / "smoke" / "records")
    cpu = {(r["kind"], r["task"]["name"], (r.get("encoder") or {}).get("name"),
            (r.get("metric") or {}).get("name")): r["timings"]["cpu_time_s"] for r in records}
    res = build_results(records)
    assert res.encoder_rows and res.metric_rows
    for row in res.encoder_rows:
        assert row["fit_cpu_s"] == cpu[("encoder", row["task"], row["encoder"], None)] > 0
    for row in res.metric_rows:
        key = ("metric", row["task"], row["encoder"], row["metric"])
        assert row["stage_cpu_s"] == cpu[key] > 0
    assert build_results([{**r, "timings": {}} for r in records]).encoder_rows[0][
        "fit_cpu_s"] is None


def test_permutation_p_is_exact_for_few_encoders() -> None:
    # 3 encoders in perfect order: 2 of the 3! = 6 pairings give |ρ| = 1, so p = 1/3 (scipy's
    # t approximation says 0)
    assert spearman_permutation_p([1, 2, 3], [10, 20, 30]) == pytest.approx(1 / 3)
    assert spearman_permutation_p([1, 2, 3, 4, 5], [2, 4, 6, 8, 10]) == pytest.approx(2 / 120)
    x, y = [1, 2, 3, 4, 5, 6], [1, 3, 2.5, 4, 9, 7]
    rho = stats.spearmanr(x, y).statistic
    perms = [stats.spearmanr(p, y).statistic for p in itertools.permutations(x)]
    ref = np.mean(np.abs(perms) >= abs(rho) - 1e-12)  # brute force over all 720 pairings
    assert spearman_permutation_p(x, y) == pytest.approx(ref)
