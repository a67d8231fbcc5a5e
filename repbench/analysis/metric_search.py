"""The pre-registered metric search's selection rule (``studies/metric_search/
preregistration.md``): the best single metric, and the best model of at most two metrics chosen
by nested leave-one-encoder-out cross-validation on within-fold ranks; then a selection's
Spearman ρ on another task with a paired bootstrap against a baseline metric.

Inputs are plain tables: ``values`` a DataFrame indexed by encoder with one column per metric
(direction-adjusted: higher is better), ``returns`` encoder → mean return; a metric with a
missing value for an encoder is not a candidate.
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

__all__ = ["Selection", "compare_on", "loo_rank_model", "loo_rmse", "nested_selection",
           "reference_gaps", "transfer_model"]


def _ranks(x: np.ndarray) -> np.ndarray:
    return stats.rankdata(x, axis=0) / len(x)


def _fit_predict(train_x: np.ndarray, train_y: np.ndarray, test_x: np.ndarray) -> np.ndarray:
    """OLS of return on the training encoders' metric ranks; the test encoders ranked among the
    training ones (their rank is where they would fall)."""
    rx = _ranks(train_x)
    design = np.column_stack([np.ones(len(rx)), rx])
    coef, *_ = np.linalg.lstsq(design, train_y, rcond=None)
    tx = np.column_stack([
        np.searchsorted(np.sort(train_x[:, j]), test_x[:, j], side="right") / len(train_x)
        for j in range(train_x.shape[1])])
    return np.column_stack([np.ones(len(tx)), tx]) @ coef


def loo_rank_model(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Leave-one-encoder-out predictions of ``y`` from the metric columns ``x`` (rank model)."""
    out = np.empty(len(y))
    for i in range(len(y)):
        keep = np.arange(len(y)) != i
        out[i] = _fit_predict(x[keep], y[keep], x[i:i + 1])[0]
    return out


def _score(x: np.ndarray, y: np.ndarray) -> float:
    pred = loo_rank_model(x, y)
    if np.ptp(pred) == 0:
        return -1.0
    return float(stats.spearmanr(pred, y).statistic)


def _best_model(values: pd.DataFrame, y: np.ndarray, max_size: int) -> tuple[str, ...]:
    """The metric set (size ≤ ``max_size``) whose leave-one-out rank model ranks ``y`` best;
    ties go to the smaller set, then the first in column order."""
    best, best_score = (), -np.inf
    for size in range(1, max_size + 1):
        for combo in itertools.combinations(values.columns, size):
            s = _score(values[list(combo)].to_numpy(float), y)
            if s > best_score + 1e-12:
                best, best_score = combo, s
    return best


@dataclass
class Selection:
    """The rule's outcome on one task."""

    single: str
    single_rho: float
    model: tuple[str, ...]
    nested_rho: float
    nested_predictions: dict[str, float]


def nested_selection(values: pd.DataFrame, returns: Mapping[str, float], *,
                     max_size: int = 2) -> Selection:
    """The selection rule: the single metric with the largest Spearman ρ with ``returns``; and
    the model of ≤ ``max_size`` metrics chosen by an inner leave-one-out loop on all encoders,
    with its honest (nested: the choice redone without the held-out encoder) outer
    leave-one-encoder-out Spearman ρ."""
    values = values.dropna(axis=1).loc[[e for e in values.index if e in returns]]
    y = np.array([returns[e] for e in values.index], dtype=float)
    rhos = {m: float(stats.spearmanr(values[m], y).statistic) for m in values.columns}
    single = max(rhos, key=lambda m: (rhos[m], -list(values.columns).index(m)))
    outer = {}
    for i, enc in enumerate(values.index):
        keep = np.arange(len(y)) != i
        chosen = list(_best_model(values.iloc[keep], y[keep], max_size))
        x = values[chosen].to_numpy(float)
        outer[enc] = float(_fit_predict(x[keep], y[keep], x[i:i + 1])[0])
    pred = np.array([outer[e] for e in values.index])
    return Selection(single, rhos[single], _best_model(values, y, max_size),
                     float(stats.spearmanr(pred, y).statistic), outer)


def compare_on(values: pd.DataFrame, per_seed: Mapping[str, Sequence[float]], selected: str,
               baseline: str, *, n_bootstrap: int = 1000, seed: int = 0,
               confidence: float = 0.95) -> dict[str, Any]:
    """``selected``'s and ``baseline``'s Spearman ρ with the mean return on another task, and
    their difference, each with a percentile bootstrap interval over the same resamples of
    encoders and, inside each, its seeds (paired)."""
    names = [e for e in values.index if e in per_seed and len(per_seed[e])]
    a = values.loc[names, selected].to_numpy(float)
    b = values.loc[names, baseline].to_numpy(float)
    seeds = [np.asarray(per_seed[e], float) for e in names]
    y = np.array([s.mean() for s in seeds])
    rng = np.random.default_rng(seed)
    boot = np.empty((n_bootstrap, 3))
    with warnings.catch_warnings():  # a resample of few encoders can be constant: NaN, dropped
        warnings.simplefilter("ignore", stats.ConstantInputWarning)
        for k in range(n_bootstrap):
            idx = rng.integers(0, len(names), len(names))
            yb = np.array([rng.choice(seeds[i], len(seeds[i])).mean() for i in idx])
            ra = stats.spearmanr(a[idx], yb).statistic
            rb = stats.spearmanr(b[idx], yb).statistic
            boot[k] = (ra, rb, ra - rb)
    alpha = (1 - confidence) / 2
    lo, hi = np.nanquantile(boot, [alpha, 1 - alpha], axis=0)
    point = (float(stats.spearmanr(a, y).statistic), float(stats.spearmanr(b, y).statistic))
    return {"n": len(names), "selected": selected, "baseline": baseline,
            "rho_selected": point[0], "rho_selected_ci": (float(lo[0]), float(hi[0])),
            "rho_baseline": point[1], "rho_baseline_ci": (float(lo[1]), float(hi[1])),
            "difference": point[0] - point[1], "difference_ci": (float(lo[2]), float(hi[2]))}


def transfer_model(train_x: np.ndarray, train_y: np.ndarray, test_x: np.ndarray) -> np.ndarray:
    """A rank model fitted on one task applied to another: OLS of ``train_y`` on the training
    encoders' metric ranks, evaluated on the test encoders' ranks *within the test task* (the
    metrics' scales differ between tasks; their ranks do not)."""
    train_x, test_x = np.atleast_2d(train_x.T).T, np.atleast_2d(test_x.T).T
    design = np.column_stack([np.ones(len(train_x)), _ranks(train_x)])
    coef, *_ = np.linalg.lstsq(design, train_y, rcond=None)
    return np.column_stack([np.ones(len(test_x)), _ranks(test_x)]) @ coef


def loo_rmse(x: np.ndarray, y: np.ndarray) -> float:
    """Root mean squared error of :func:`loo_rank_model`'s leave-one-encoder-out predictions of
    ``y`` from the metric columns ``x``."""
    x = np.atleast_2d(np.asarray(x, float).T).T
    y = np.asarray(y, float)
    return float(np.sqrt(np.mean((loo_rank_model(x, y) - y) ** 2)))


def reference_gaps(sets: Sequence[Mapping[str, Any]], rl_records: Sequence[Mapping[str, Any]],
                   learned: Mapping[str, Sequence[str]], *, agent: str = "sac",
                   n_seeds: int = 3) -> list[str]:
    """What keeps a reference from being complete, one line each (empty when complete).

    Complete means: every learned encoder of every task in ``learned`` (task → encoders) has a
    shipped latent set (``sets``: manifest entries with ``task``, ``encoder``,
    ``encoder_weights``) and ``n_seeds`` distinct ``agent`` seeds in ``rl_records`` (records as
    written by a run) whose ``encoder_weights`` equal the shipped set's."""
    shipped = {(s["task"], s["encoder"]): s["encoder_weights"] for s in sets}
    seeds: dict[tuple[str, str], dict[Any, set[Any]]] = {}  # → weights → seeds
    for r in rl_records:
        if r["agent"]["name"] == agent:
            seeds.setdefault((r["task"]["name"], r["encoder"]["name"]), {}).setdefault(
                r.get("encoder_weights"), set()).add(r["seed"])
    gaps = []
    for task, encoders in learned.items():
        for enc in encoders:
            weights = shipped.get((task, enc))
            if weights is None:
                gaps.append(f"{task} {enc}: no shipped latents")
                continue
            runs = seeds.get((task, enc), {})
            ours = runs.get(weights, set())
            if len(ours) < n_seeds:
                other = len(set().union(*runs.values()) - ours) if runs else 0
                gaps.append(f"{task} {enc}: {len(ours)} of {n_seeds} {agent} seeds of the "
                            f"shipped weights" + (f" ({other} of other weights)" if other else ""))
    return gaps
