"""The noise ceiling: how well *any* metric could rank the encoders, given the seeds.

An encoder's mean return over k seeds is a noisy measurement of its quality. With r₁ the
seed-to-seed Spearman ρ across encoders (seed i's returns against seed j's, averaged over every
pair of seeds), the k-seed mean has split-half reliability (Spearman–Brown)

    r_k = k·r₁ / (1 + (k − 1)·r₁)

and no metric can correlate with it above √r_k: a perfect metric correlates with true quality
at 1 and true quality correlates with the observed mean at √r_k. The interval is a percentile
bootstrap over encoders (the same encoders drawn for every seed). A task whose seeds disagree
(low r₁) cannot test any metric, whatever its sample size.

:data:`RELIABLE_R1` is the rule fixed before the data (issue 57's pilot rule): the returns
rank the encoders reliably when r₁'s interval lies above it.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy import stats

__all__ = ["RELIABLE_R1", "noise_ceiling", "spearman_brown"]

#: Seed-to-seed Spearman ρ above which a task's returns rank the encoders reliably.
RELIABLE_R1 = 0.6


def spearman_brown(r1: float, k: int) -> float:
    """Reliability of the mean of ``k`` measurements whose pairwise correlation is ``r1`` (NaN
    where it is undefined: r1 at or below −1/(k − 1))."""
    denominator = 1.0 + (k - 1) * r1
    return k * r1 / denominator if denominator > 0 else float("nan")


def _ceiling(r1: float, k: int) -> float:
    rk = spearman_brown(r1, k)
    return float(np.sqrt(rk)) if rk > 0 else 0.0  # seeds that disagree: no ceiling above 0


def _seed_to_seed(matrix: np.ndarray) -> float:
    """Mean Spearman ρ across encoders (rows) over every pair of seeds (columns)."""
    rhos = []
    for i, j in itertools.combinations(range(matrix.shape[1]), 2):
        a, b = matrix[:, i], matrix[:, j]
        if np.ptp(a) > 0 and np.ptp(b) > 0:
            rhos.append(stats.spearmanr(a, b).statistic)
    return float(np.mean(rhos)) if rhos else float("nan")


def noise_ceiling(returns: Mapping[str, Mapping[Any, float]], *, n_bootstrap: int = 1000,
                  confidence: float = 0.95, seed: int = 0) -> dict[str, Any]:
    """Seed-to-seed reliability and the Spearman–Brown ceiling of a k-seed mean.

    Args:
        returns: encoder → {seed: final evaluation return}. Only the seeds every encoder has
            are used (a seed is one measurement of every encoder), and encoders missing any
            of those are dropped.
        n_bootstrap: resamples of the encoders for the intervals.

    Returns:
        ``n_encoders``, ``n_seeds``, ``r1`` (seed-to-seed Spearman, with ``r1_ci_low`` /
        ``r1_ci_high``), ``reliability`` (r_k) and ``ceiling`` (√r_k, with ``ceiling_ci_low`` /
        ``ceiling_ci_high``); NaN where fewer than 3 encoders or 2 common seeds.
    """
    nan = float("nan")
    seeds = sorted(set.intersection(*(set(r) for r in returns.values())), key=str) \
        if returns else []
    names = [e for e in returns if all(s in returns[e] for s in seeds)]
    out: dict[str, Any] = {"n_encoders": len(names), "n_seeds": len(seeds)}
    keys = ("r1", "r1_ci_low", "r1_ci_high", "reliability", "ceiling", "ceiling_ci_low",
            "ceiling_ci_high")
    if len(names) < 3 or len(seeds) < 2:
        return out | dict.fromkeys(keys, nan)
    matrix = np.array([[float(returns[e][s]) for s in seeds] for e in names])
    k = len(seeds)
    r1 = _seed_to_seed(matrix)
    rng = np.random.default_rng(seed)
    boot = np.array([_seed_to_seed(matrix[rng.integers(0, len(names), len(names))])
                     for _ in range(n_bootstrap)])
    boot = boot[np.isfinite(boot)]
    alpha = (1.0 - confidence) / 2.0
    lo, hi = np.quantile(boot, [alpha, 1.0 - alpha]) if boot.size >= 10 else (nan, nan)
    return out | {"r1": r1, "r1_ci_low": float(lo), "r1_ci_high": float(hi),
                  "reliability": spearman_brown(r1, k), "ceiling": _ceiling(r1, k),
                  "ceiling_ci_low": _ceiling(lo, k) if np.isfinite(lo) else nan,
                  "ceiling_ci_high": _ceiling(hi, k) if np.isfinite(hi) else nan}


def ceilings(rl_rows: Any, families: Mapping[str, str], *, n_bootstrap: int = 1000,
             seed: int = 0) -> dict[tuple[str, str], dict[str, Any]]:
    """:func:`noise_ceiling` of the *learned* encoders per (task, agent) of ``rl_rows`` (plain
    rows with task, agent, encoder, seed, eval_return; as :func:`repbench.analysis.correlation.
    metric_leaderboard` reads them): the ceiling of the within-learned Spearman ρ the board
    ranks metrics by."""
    from repbench.analysis.correlation import BASELINE_FAMILY

    returns: dict[tuple[str, str], dict[str, dict[Any, float]]] = {}
    for r in rl_rows:
        if families.get(r["encoder"], "learned") == BASELINE_FAMILY:
            continue
        returns.setdefault((r["task"], r["agent"]), {}).setdefault(r["encoder"], {})[
            r.get("seed")] = float(r["eval_return"])
    return {key: dict(_cached_ceiling(tuple((e, tuple(v.items())) for e, v in per.items()),
                                      n_bootstrap, seed))  # in the rows' order, as resampled
            for key, per in sorted(returns.items())}


@functools.lru_cache(maxsize=64)
def _cached_ceiling(per: tuple[tuple[str, tuple[tuple[Any, float], ...]], ...],
                    n_bootstrap: int, seed: int) -> dict[str, Any]:
    """:func:`noise_ceiling` of one task × agent's returns, computed once per board: the metric
    ranking and the robustness checks both ask for it."""
    return noise_ceiling({e: dict(v) for e, v in per}, n_bootstrap=n_bootstrap, seed=seed)


def ceiling_check(task: str, agent: str, out: Mapping[str, Any]) -> Any:
    """The ``robustness.csv`` row of one task × agent's ceiling: value and interval are the
    ceiling √r_k; the verdict is the rule of the module docstring on r₁ (**holds**: the returns
    rank the encoders reliably; **does not hold**: r₁'s interval lies below
    :data:`RELIABLE_R1`, the returns are mostly seed noise; **inconclusive** otherwise)."""
    from repbench.analysis.robustness import FAILS, HOLDS, INCONCLUSIVE, Check

    lo, hi = out["r1_ci_low"], out["r1_ci_high"]
    verdict = HOLDS if lo >= RELIABLE_R1 else FAILS if hi < RELIABLE_R1 else INCONCLUSIVE
    return Check(
        f"{agent.upper()} returns rank the encoders reliably {task}",
        f"noise ceiling √r_k of any metric's within-learned ρ ({out['n_seeds']} seeds)",
        out["ceiling"], out["ceiling_ci_low"], out["ceiling_ci_high"], verdict,
        f"seed-to-seed Spearman r₁ {out['r1']:.2f} [{lo:.2f}, {hi:.2f}] over "
        f"{out['n_encoders']} learned encoders; reliability of the {out['n_seeds']}-seed mean "
        f"{out['reliability']:.2f}; holds if r₁'s 95 % interval is above {RELIABLE_R1}, "
        "fails if below")


def add_ceiling_columns(ranking: Any, found: Mapping[tuple[str, str], Mapping[str, Any]]
                        ) -> Any:
    """``metrics.csv``'s ceiling columns: the task × agent's ``noise_ceiling`` with its
    interval and ``seed_to_seed_r1``, and ``of_ceiling``, the metric's within-learned ρ over the
    ceiling (1 = as good as the seeds allow)."""
    if ranking.empty:
        return ranking
    ranking = ranking.copy()
    for col, key in (("noise_ceiling", "ceiling"), ("noise_ceiling_ci_low", "ceiling_ci_low"),
                     ("noise_ceiling_ci_high", "ceiling_ci_high"), ("seed_to_seed_r1", "r1")):
        ranking[col] = [found.get((t, a), {}).get(key, np.nan)
                        for t, a in zip(ranking["task"], ranking["agent"], strict=True)]
    with np.errstate(invalid="ignore", divide="ignore"):
        ranking["of_ceiling"] = ranking["spearman_learned"] / ranking["noise_ceiling"]
    return ranking
