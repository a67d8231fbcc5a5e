"""Which metric predicts RL performance: correlation across encoders, with uncertainty.

For one task × agent × metric we have, per encoder, a metric value m_e and the final evaluation
returns r_{e,s} over seeds s. The point estimates correlate ``sign · m_e`` with the seed mean
``mean_s r_{e,s}``, where ``sign`` is +1 for higher-is-better metrics and −1 otherwise, so a
positive correlation always means "the metric ranks encoders the way RL does". Confidence
intervals come from a two-level bootstrap: resample encoders with replacement, and within each
drawn encoder resample its seeds, then recompute each coefficient (percentile interval).
p-values are scipy's (t-test for Pearson, exact/asymptotic for Spearman and Kendall).

:func:`metric_leaderboard` builds the metric leaderboard on top: the Spearman ρ over all encoders
and within the learned encoders only (the baselines — oracle, untrained, blind — anchor any pooled
coefficient), intervals that also draw each encoder's metric from its own bootstrap replicates
(one replicate index per resample for all encoders: the replicates are paired),
Holm and Benjamini–Hochberg adjusted p-values over all metric × agent tests (statsmodels), the
leave-one-encoder-out error of predicting return from the metric, and the metric's cost.
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


def bootstrap_resamples(xs: Sequence[np.ndarray], per_seed: Sequence[np.ndarray],
                        rng: np.random.Generator, n_bootstrap: int,
                        replicates: Sequence[Sequence[np.ndarray]] | None = None
                        ) -> tuple[list[np.ndarray], np.ndarray]:
    """The two-level bootstrap behind every interval here, shared by several metrics.

    ``xs``: one array of per-encoder metric values per metric (same encoder order);
    ``per_seed``: each encoder's returns over seeds. Each resample draws encoders with
    replacement (resamples with fewer than 3 distinct encoders are dropped), then each drawn
    encoder's seeds with replacement (its return is the mean of the drawn seeds); with
    ``replicates`` (per metric, per encoder: that encoder's bootstrap replicates of the metric)
    each drawn encoder's metric value is one of its replicates — the *same* replicate index for
    every encoder of a resample. Every encoder's metric is computed on the same held-out data
    with the same seed, so replicate b of each encoder comes from the same resample of held-out
    episodes; drawing one index per resample keeps that pairing, and noise common to all
    encoders (a harder or easier draw of episodes) does not reorder them. The same encoder
    draws are used for every metric, so differences between metrics are paired. Returns
    ``(xbs, yb)``: per metric an array [B, n] and the returns [B, n].
    """
    n = len(per_seed)
    idx = rng.integers(0, n, (n_bootstrap, n))  # encoders drawn with replacement
    idx = idx[np.array([np.unique(row).size >= 3 for row in idx], dtype=bool)]
    n_seeds = max(r.size for r in per_seed)
    padded = np.array([np.resize(r, n_seeds) for r in per_seed])  # rows cycle their seeds
    sizes = np.array([r.size for r in per_seed])
    draws = (rng.random((idx.shape[0], n, n_seeds)) * sizes[idx][:, :, None]).astype(int)
    mask = np.arange(n_seeds)[None, None, :] < sizes[idx][:, :, None]
    picked = np.take_along_axis(padded[idx], draws, axis=2)
    yb = (picked * mask).sum(2) / sizes[idx]
    xbs = [np.asarray(x, dtype=float)[idx] for x in xs]
    for k, reps in enumerate(replicates or []):
        if reps is None:
            continue
        paired = replicate_matrix(reps, xs[k])
        # one replicate index per resample, shared by its encoders
        pick = np.broadcast_to((rng.random((idx.shape[0], 1)) * paired.shape[1]).astype(int),
                               idx.shape)
        xbs[k] = paired[idx, pick]
    return xbs, yb


def replicate_matrix(replicates: Sequence[Sequence[float]], values: Sequence[float]
                     ) -> np.ndarray:
    """Encoders' metric bootstrap replicates as one [n_encoders, R] array whose column b is
    replicate b of every encoder (computed on the same resample of held-out episodes, so
    columns are the draws that keep encoders paired). Non-finite replicates are dropped, an
    encoder without any gets its point value from ``values``, and shorter rows cycle to the
    longest one's length R."""
    clean = [np.asarray(r, dtype=float) for r in replicates]
    clean = [r[np.isfinite(r)] if np.isfinite(r).any() else np.asarray(values[i:i + 1], float)
             for i, r in enumerate(clean)]
    longest = max(r.size for r in clean)
    return np.array([np.resize(r, longest) for r in clean])


def correlate(metric_values: Mapping[str, float], returns: Mapping[str, Sequence[float]], *,
              higher_is_better: bool, n_bootstrap: int = 1000, confidence: float = 0.95,
              seed: int = 0, metric_replicates: Mapping[str, Sequence[float]] | None = None
              ) -> dict[str, Any]:
    """Correlate a metric with RL return across encoders.

    Args:
        metric_values: encoder → metric value.
        returns: encoder → final evaluation returns, one per seed.
        higher_is_better: the metric's direction (values are sign-flipped when False).
        n_bootstrap: bootstrap resamples for the intervals.
        metric_replicates: encoder → the metric's own bootstrap replicates
            (``extras["bootstrap_replicates"]``). When given, every bootstrap resample draws
            each encoder's metric value from its replicates, so the interval carries the
            metric's estimation noise as well as the encoder and seed sampling. Encoders
            without replicates keep their point value.

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
    (xb,), yb = bootstrap_resamples(
        [x], per_seed, rng, n_bootstrap,
        [[sign * np.asarray(metric_replicates.get(e) or [metric_values[e]], dtype=float)
          for e in names]] if metric_replicates else None)
    boot = batch_coefficients(xb, yb)
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


# -- the metric leaderboard: scopes, multiple testing, prediction, cost -------------------------
BASELINE_FAMILY = "baseline"
SCOPES = ("all", "learned")


def adjust_pvalues(pvalues: Sequence[float], method: str) -> np.ndarray:
    """Multiple-comparison adjusted p-values (statsmodels ``multipletests``); NaN stays NaN.

    ``method``: ``"holm"`` (family-wise error) or ``"fdr_bh"`` (Benjamini–Hochberg false
    discovery rate).
    """
    from statsmodels.stats.multitest import multipletests

    p = np.asarray(pvalues, dtype=float)
    out = np.full(p.shape, np.nan)
    ok = np.isfinite(p)
    if ok.any():
        out[ok] = multipletests(p[ok], method=method)[1]
    return out


def spearman_permutation_p(x: Sequence[float], y: Sequence[float], *, n_resamples: int = 9999,
                           seed: int = 0) -> float:
    """Two-sided permutation p-value of Spearman's ρ (:func:`scipy.stats.permutation_test`,
    pairings permuted). Exact when n! ≤ ``n_resamples`` (up to 7 encoders at the default),
    Monte Carlo beyond; unlike the t approximation it stays honest at 3-10 encoders (with 3,
    ρ = ±1 has p = 1/3). NaN for fewer than 3 points or a constant side."""
    xa, ya = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if xa.size < 3 or np.ptp(xa) == 0 or np.ptp(ya) == 0:
        return float("nan")

    rb = stats.rankdata(ya)
    rb = rb - rb.mean()

    def rho(a: np.ndarray, axis: int = -1) -> np.ndarray:  # y held fixed: n! pairings
        ra = stats.rankdata(a, axis=axis)
        ra = ra - ra.mean(axis=axis, keepdims=True)
        return (ra * rb).sum(axis) / np.sqrt((ra**2).sum(axis) * (rb**2).sum())

    res = stats.permutation_test((xa,), rho, permutation_type="pairings",
                                 n_resamples=n_resamples, alternative="two-sided",
                                 vectorized=True, random_state=seed)
    return float(res.pvalue)


def leave_one_out(metric_values: Mapping[str, float], mean_returns: Mapping[str, float], *,
                  higher_is_better: bool = True) -> dict[str, Any]:
    """Leave-one-encoder-out prediction of return from the metric by a straight line.

    For each encoder, a least-squares line return ~ metric is fit on the other encoders and
    predicts the left-out one. Returns ``{"predictions": {encoder: value}, "loo_rmse",
    "loo_mae", "loo_rmse_ratio"}``; the ratio divides by the RMSE of predicting each left-out
    encoder by the others' mean return (< 1: the metric predicts better than knowing nothing).
    NaN with fewer than 4 encoders (a line through 2 points extrapolates wildly). The
    direction does not change a line's predictions; ``higher_is_better`` is accepted for
    symmetry with :func:`correlate`.
    """
    names = [e for e in metric_values if e in mean_returns
             and np.isfinite(metric_values[e]) and np.isfinite(mean_returns[e])]
    nan = float("nan")
    if len(names) < 4:
        return {"predictions": {}, "loo_rmse": nan, "loo_mae": nan, "loo_rmse_ratio": nan}
    x = np.array([metric_values[e] for e in names], dtype=float)
    y = np.array([mean_returns[e] for e in names], dtype=float)
    pred, base = np.empty_like(y), np.empty_like(y)
    for i in range(len(names)):
        keep = np.arange(len(names)) != i
        base[i] = y[keep].mean()
        if np.ptp(x[keep]) == 0:
            pred[i] = base[i]
        else:
            slope, intercept = np.polyfit(x[keep], y[keep], 1)
            pred[i] = slope * x[i] + intercept
    rmse = float(np.sqrt(np.mean((pred - y) ** 2)))
    base_rmse = float(np.sqrt(np.mean((base - y) ** 2)))
    return {"predictions": dict(zip(names, pred.tolist(), strict=True)), "loo_rmse": rmse,
            "loo_mae": float(np.mean(np.abs(pred - y))),
            "loo_rmse_ratio": rmse / base_rmse if base_rmse > 0 else nan}


def metric_leaderboard(metric_rows: Sequence[Mapping[str, Any]],
                       rl_rows: Sequence[Mapping[str, Any]], families: Mapping[str, str],
                       directions: Mapping[str, bool], *, n_bootstrap: int = 1000,
                       seed: int = 0) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Which metric predicts return: one row per task × agent × metric, and LOO predictions.

    Inputs are plain records: ``metric_rows`` with task, encoder, metric, value and optional
    ``extras["bootstrap_replicates"]`` and ``time_s``; ``rl_rows`` with task, encoder, agent,
    eval_return (one per seed); ``families`` encoder → family (``"baseline"`` or a learned
    family). For both scopes, ``all`` encoders and the ``learned`` ones (family not
    ``"baseline"``), each row has the Spearman ρ with its bootstrap interval (encoders, seeds
    and each encoder's metric replicates resampled; :func:`correlate`), its permutation
    p-value (:func:`spearman_permutation_p`; scipy's t approximation is wrong at a handful of
    encoders) and the Holm and Benjamini–Hochberg adjusted p-values over all metric × agent
    tests of the task and scope; then the leave-one-encoder-out error over all encoders
    (:func:`leave_one_out`) and the metric's mean compute time per encoder in seconds.
    Inference is at the seed level: an encoder's return is the mean of its seeds' evaluation
    returns, and the bootstrap resamples seeds, never episodes.

    Returns ``(rows, predictions)`` with ``predictions[(task, agent, metric)]`` =
    encoder → LOO-predicted return.
    """
    returns: dict[tuple[str, str], dict[str, list[float]]] = {}
    for r in rl_rows:
        returns.setdefault((r["task"], r["agent"]), {}).setdefault(r["encoder"], []).append(
            float(r["eval_return"]))
    values: dict[tuple[str, str], dict[str, float]] = {}
    reps: dict[tuple[str, str], dict[str, list[float]]] = {}
    cost: dict[tuple[str, str], list[float]] = {}
    cost_cpu: dict[tuple[str, str], list[float]] = {}
    for r in metric_rows:
        key = (r["task"], r["metric"])
        values.setdefault(key, {})[r["encoder"]] = float(r["value"])
        rep = (r.get("extras") or {}).get("bootstrap_replicates")
        if rep:
            reps.setdefault(key, {})[r["encoder"]] = [float(v) for v in rep if v is not None]
        if r.get("time_s") is not None:
            cost.setdefault(key, []).append(float(r["time_s"]))
        if r.get("stage_cpu_s") is not None:
            cost_cpu.setdefault(key, []).append(float(r["stage_cpu_s"]))
    rows: list[dict[str, Any]] = []
    predictions: dict[tuple[str, str, str], dict[str, float]] = {}
    for (task, agent), ret in sorted(returns.items()):
        for (t2, metric), vals in sorted(values.items()):
            if t2 != task:
                continue
            hib = bool(directions.get(metric, True))
            row: dict[str, Any] = {"task": task, "agent": agent, "metric": metric}
            for scope in SCOPES:
                keep = {e: v for e, v in vals.items()
                        if scope == "all" or families.get(e, "learned") != BASELINE_FAMILY}
                c = correlate(keep, ret, higher_is_better=hib, n_bootstrap=n_bootstrap,
                              seed=seed, metric_replicates=reps.get((task, metric)))
                row[f"n_{scope}"] = c["n_encoders"]
                for k in ("", "_ci_low", "_ci_high"):
                    row[f"spearman_{scope}{k}"] = c[f"spearman{k}"]
                both = [e for e in keep if e in ret and len(ret[e]) and np.isfinite(keep[e])]
                row[f"spearman_{scope}_p"] = spearman_permutation_p(
                    [keep[e] for e in both], [float(np.mean(ret[e])) for e in both], seed=seed)
            means = {e: float(np.mean(r)) for e, r in ret.items() if len(r)}
            loo = leave_one_out(vals, means, higher_is_better=hib)
            predictions[(task, agent, metric)] = loo.pop("predictions")
            row.update(loo)
            times = cost.get((task, metric), [])
            row["cost_s"] = float(np.mean(times)) if times else float("nan")
            cpu = cost_cpu.get((task, metric), [])
            row["cost_cpu_s"] = float(np.mean(cpu)) if cpu else float("nan")
            rows.append(row)
    for task in sorted({r["task"] for r in rows}):
        idx = [i for i, r in enumerate(rows) if r["task"] == task]
        for scope in SCOPES:
            p = [rows[i][f"spearman_{scope}_p"] for i in idx]
            for method, col in (("holm", "holm"), ("fdr_bh", "bh")):
                for i, q in zip(idx, adjust_pvalues(p, method), strict=True):
                    rows[i][f"spearman_{scope}_p_{col}"] = float(q)
    return rows, predictions
