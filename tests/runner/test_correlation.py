"""Correlation of metrics with RL return: known answers, direction, uncertainty."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from repbench.correlation import correlate, mean_ci

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
