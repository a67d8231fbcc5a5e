"""Which metric predicts RL performance: correlation across encoders, with uncertainty.

For one task × agent × metric we have, per encoder, a metric value m_e and the final evaluation
returns r_{e,s} over seeds s. The point estimates correlate ``sign · m_e`` with the seed mean
``mean_s r_{e,s}``, where ``sign`` is +1 for higher-is-better metrics and −1 otherwise, so a
positive correlation always means "the metric ranks encoders the way RL does". Confidence
intervals come from a two-level bootstrap: resample encoders with replacement, and within each
drawn encoder resample its seeds, then recompute each coefficient (percentile interval).
p-values are scipy's (t-test for Pearson, exact/asymptotic for Spearman and Kendall).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy import stats

METHODS = ("pearson", "spearman", "kendall")


def _coefficients(x: np.ndarray, y: np.ndarray) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}
    if np.ptp(x) == 0 or np.ptp(y) == 0:
        return {m: (float("nan"), float("nan")) for m in METHODS}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = stats.pearsonr(x, y)
        out["pearson"] = (float(r.statistic), float(r.pvalue))
        r = stats.spearmanr(x, y)
        out["spearman"] = (float(r.statistic), float(r.pvalue))
        r = stats.kendalltau(x, y)
        out["kendall"] = (float(r.statistic), float(r.pvalue))
    return out


def _pearson_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Pearson r of each row pair of ``x`` and ``y`` (shape [B, n]); NaN for constant rows."""
    xc = x - x.mean(axis=1, keepdims=True)
    yc = y - y.mean(axis=1, keepdims=True)
    den = np.sqrt((xc**2).sum(1) * (yc**2).sum(1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, (xc * yc).sum(1) / den, np.nan)


def _kendall_rows(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Kendall τ-b of each row pair (ties handled as scipy does)."""
    iu = np.triu_indices(x.shape[1], k=1)
    sx = np.sign(x[:, :, None] - x[:, None, :])[:, iu[0], iu[1]]
    sy = np.sign(y[:, :, None] - y[:, None, :])[:, iu[0], iu[1]]
    den = np.sqrt((sx**2).sum(1) * (sy**2).sum(1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, (sx * sy).sum(1) / den, np.nan)


def batch_coefficients(x: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
    """Pearson, Spearman and Kendall τ-b for each row of ``x``, ``y`` (shape [B, n]),
    vectorized over rows; equal to scipy's per-row statistics."""
    rx = stats.rankdata(x, axis=1)
    ry = stats.rankdata(y, axis=1)
    return {"pearson": _pearson_rows(x, y), "spearman": _pearson_rows(rx, ry),
            "kendall": _kendall_rows(x, y)}


def correlate(metric_values: Mapping[str, float], returns: Mapping[str, Sequence[float]], *,
              higher_is_better: bool, n_bootstrap: int = 1000, confidence: float = 0.95,
              seed: int = 0) -> dict[str, Any]:
    """Correlate a metric with RL return across encoders.

    Args:
        metric_values: encoder → metric value.
        returns: encoder → final evaluation returns, one per seed.
        higher_is_better: the metric's direction (values are sign-flipped when False).
        n_bootstrap: bootstrap resamples for the intervals.

    Returns:
        ``{"n_encoders", "<method>", "<method>_p", "<method>_ci_low", "<method>_ci_high"}`` for
        pearson, spearman and kendall; NaN where fewer than 3 encoders or no variation.
    """
    names = [e for e in metric_values if e in returns and len(returns[e]) > 0
             and np.isfinite(metric_values[e]) and np.all(np.isfinite(returns[e]))]
    sign = 1.0 if higher_is_better else -1.0
    out: dict[str, Any] = {"n_encoders": len(names)}
    nan = float("nan")
    if len(names) < 3:
        for m in METHODS:
            out.update({m: nan, f"{m}_p": nan, f"{m}_ci_low": nan, f"{m}_ci_high": nan})
        return out
    x = sign * np.array([metric_values[e] for e in names], dtype=float)
    per_seed = [np.asarray(returns[e], dtype=float) for e in names]
    y = np.array([r.mean() for r in per_seed])
    for m, (c, p) in _coefficients(x, y).items():
        out[m], out[f"{m}_p"] = c, p
    rng = np.random.default_rng(seed)
    n = len(names)
    idx = rng.integers(0, n, (n_bootstrap, n))  # encoders drawn with replacement
    keep = np.array([np.unique(row).size >= 3 for row in idx], dtype=bool)
    idx = idx[keep]
    # within each drawn encoder, its seeds drawn with replacement: mean of a seed resample
    n_seeds = max(r.size for r in per_seed)
    padded = np.array([np.resize(r, n_seeds) for r in per_seed])  # rows cycle their seeds
    sizes = np.array([r.size for r in per_seed])
    draws = (rng.random((idx.shape[0], n, n_seeds)) * sizes[idx][:, :, None]).astype(int)
    mask = np.arange(n_seeds)[None, None, :] < sizes[idx][:, :, None]
    picked = np.take_along_axis(padded[idx], draws, axis=2)
    yb = (picked * mask).sum(2) / sizes[idx]
    boot = batch_coefficients(x[idx], yb)
    alpha = (1.0 - confidence) / 2.0
    for m in METHODS:
        finite = boot[m][np.isfinite(boot[m])]
        if finite.size >= 10:
            lo, hi = np.quantile(finite, [alpha, 1.0 - alpha])
            out[f"{m}_ci_low"], out[f"{m}_ci_high"] = float(lo), float(hi)
        else:
            out[f"{m}_ci_low"] = out[f"{m}_ci_high"] = nan
    return out


def mean_ci(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float, float]:
    """Mean and Student-t confidence interval (NaN interval for fewer than 2 values)."""
    a = np.asarray(values, dtype=float)
    if a.size == 0:
        return float("nan"), float("nan"), float("nan")
    mean = float(a.mean())
    if a.size < 2 or np.ptp(a) == 0:
        return mean, (mean if a.size >= 2 else float("nan")), (mean if a.size >= 2
                                                                else float("nan"))
    half = float(stats.sem(a) * stats.t.ppf(0.5 + confidence / 2.0, a.size - 1))
    return mean, mean - half, mean + half
