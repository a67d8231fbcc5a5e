"""Correlation of metrics with RL return: known answers, direction, uncertainty."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from repbench.analysis.correlation import correlate, mean_ci

ENCS = [f"e{i}" for i in range(8)]


def _returns(means: list[float], seeds: int = 3, noise: float = 0.1) -> dict[str, list[float]]:
    rng = np.random.default_rng(0)
    return {e: list(m + noise * rng.normal(size=seeds)) for e, m in zip(ENCS, means, strict=True)}


def test_monotone_metric_has_rank_correlation_one() -> None:
    values = {e: float(i) for i, e in enumerate(ENCS)}
    rets = _returns([10.0 * i for i in range(8)])
    c = correlate(values, rets, higher_is_better=True, n_bootstrap=200)
    assert c["spearman"] == pytest.approx(1.0) and c["kendall"] == pytest.approx(1.0)
    assert c["pearson"] > 0.99 and c["spearman_p"] < 1e-3 and c["n_encoders"] == 8
    # resampled encoders repeat, and ties pull a resample's rank correlation just below 1, so
    # the percentile interval ends a hair under the point estimate rather than at it
    assert 0.8 < c["spearman_ci_low"] <= c["spearman_ci_high"] and c["spearman_ci_high"] > 0.99


def test_lower_is_better_metric_is_sign_flipped() -> None:
    values = {e: -float(i) for i, e in enumerate(ENCS)}  # e.g. regression error
    rets = _returns([10.0 * i for i in range(8)])
    c = correlate(values, rets, higher_is_better=False, n_bootstrap=50)
    assert c["spearman"] == pytest.approx(1.0)


def test_point_estimates_match_scipy_on_seed_means() -> None:
    rng = np.random.default_rng(3)
    values = {e: float(v) for e, v in zip(ENCS, rng.normal(size=8), strict=True)}
    rets = _returns(list(rng.normal(size=8)), seeds=4, noise=0.5)
    c = correlate(values, rets, higher_is_better=True, n_bootstrap=50)
    x = [values[e] for e in ENCS]
    y = [np.mean(rets[e]) for e in ENCS]
    assert c["pearson"] == pytest.approx(stats.pearsonr(x, y).statistic)
    assert c["kendall_p"] == pytest.approx(stats.kendalltau(x, y).pvalue)


def test_independent_metric_has_wide_interval_around_zero() -> None:
    rng = np.random.default_rng(7)
    values = {e: float(v) for e, v in zip(ENCS, rng.normal(size=8), strict=True)}
    rets = _returns(list(rng.normal(size=8)), noise=1.0)
    c = correlate(values, rets, higher_is_better=True, n_bootstrap=300)
    assert c["spearman_ci_low"] < 0 < c["spearman_ci_high"]


def test_too_few_encoders_or_constant_metric_gives_nan() -> None:
    c = correlate({"a": 1.0, "b": 2.0}, {"a": [1.0], "b": [2.0]}, higher_is_better=True)
    assert c["n_encoders"] == 2 and np.isnan(c["spearman"])
    c = correlate({e: 1.0 for e in ENCS}, _returns(list(range(8))), higher_is_better=True)
    assert np.isnan(c["pearson"])


def test_mean_ci() -> None:
    m, lo, hi = mean_ci([1.0, 2.0, 3.0])
    assert m == 2.0 and lo < 2.0 < hi
    assert hi - m == pytest.approx(stats.sem([1, 2, 3]) * stats.t.ppf(0.975, 2))
    assert np.isnan(mean_ci([5.0])[1])


def test_vectorized_bootstrap_coefficients_match_scipy() -> None:
    from repbench.analysis.correlation import batch_coefficients

    rng = np.random.default_rng(11)
    x = rng.integers(0, 4, (40, 9)).astype(float)  # many ties
    y = rng.normal(size=(40, 9))
    y[:5] = np.round(y[:5])  # ties in y too
    got = batch_coefficients(x, y)
    for b in range(40):
        if np.ptp(x[b]) == 0:
            continue
        assert got["pearson"][b] == pytest.approx(stats.pearsonr(x[b], y[b]).statistic)
        assert got["spearman"][b] == pytest.approx(stats.spearmanr(x[b], y[b]).statistic)
        assert got["kendall"][b] == pytest.approx(stats.kendalltau(x[b], y[b]).statistic)


def test_bootstrap_is_fast(benchmark) -> None:  # type: ignore[no-untyped-def]
    """14 encoders × 10 seeds, 1000 resamples (one leaderboard cell)."""
    rng = np.random.default_rng(0)
    encs = [f"e{i}" for i in range(14)]
    values = {e: float(v) for e, v in zip(encs, rng.normal(size=14), strict=True)}
    rets = {e: list(rng.normal(size=10)) for e in encs}
    benchmark(correlate, values, rets, higher_is_better=True, n_bootstrap=1000)


def test_bootstrap_scipy_loop_reference(benchmark) -> None:  # type: ignore[no-untyped-def]
    """The obvious alternative: scipy's three statistics per resample, in a Python loop."""
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=14), rng.normal(size=(14, 10))

    def loop() -> None:
        for _ in range(1000):
            i = rng.integers(0, 14, 14)
            yb = np.array([rng.choice(y[k], 10).mean() for k in i])
            stats.pearsonr(x[i], yb), stats.spearmanr(x[i], yb), stats.kendalltau(x[i], yb)

    benchmark.pedantic(loop, rounds=2, iterations=1)
