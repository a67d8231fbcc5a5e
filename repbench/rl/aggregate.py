"""RL returns aggregated over seeds, the field's way: mean and interquartile mean (IQM) with
stratified-bootstrap 95 % intervals from `rliable <https://github.com/google-research/rliable>`_
(Agarwal et al. 2021).

Seeds are the unit of inference: each seed contributes one score (its mean evaluation return
over the fixed evaluation episodes), never its episodes as if they were independent samples.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from repbench.errors import ConfigError

#: The statistics :func:`aggregate_seeds` reports, in order.
STATISTICS = ("mean", "iqm")


def aggregate_seeds(per_seed: Mapping[str, Sequence[float]], *, reps: int = 2000,
                    seed: int = 0, confidence: float = 0.95) -> dict[str, dict[str, Any]]:
    """Mean and IQM over seeds with stratified-bootstrap intervals, per entry (encoder).

    Args:
        per_seed: name → one score per seed (e.g. mean evaluation return of each RL seed).
        reps: bootstrap resamples.
        seed: bootstrap seed (results are deterministic in it).
        confidence: interval size.

    Returns:
        name → ``{"mean", "mean_ci_low", "mean_ci_high", "iqm", "iqm_ci_low", "iqm_ci_high",
        "n_seeds"}``. With a single seed the intervals collapse to the point (and say so by
        being equal); with none the entry is left out.
    """
    from rliable import library as rly
    from rliable import metrics as rm

    if not isinstance(reps, int) or reps < 1:
        raise ConfigError(f"aggregate_seeds: reps={reps!r} must be a positive int")
    scores = {name: np.asarray(v, np.float64).reshape(-1, 1) for name, v in per_seed.items()
              if len(v)}
    for name, s in scores.items():
        if not np.isfinite(s).all():
            raise ConfigError(f"aggregate_seeds: the scores of {name!r} are not all finite")
    if not scores:
        return {}

    def statistics(s: np.ndarray) -> np.ndarray:
        return np.array([rm.aggregate_mean(s), rm.aggregate_iqm(s)])

    # rliable 1.2's StratifiedBootstrap draws its indices from numpy's *global* generator and
    # ignores ``random_state``: seed the global state for the call and restore it afterwards.
    saved = np.random.get_state()
    np.random.seed(seed)
    try:
        point, interval = rly.get_interval_estimates(
            scores, statistics, reps=reps, confidence_interval_size=confidence)
    finally:
        np.random.set_state(saved)
    out: dict[str, dict[str, Any]] = {}
    for name, s in scores.items():
        row: dict[str, Any] = {"n_seeds": len(s)}
        for i, stat in enumerate(STATISTICS):
            row[stat] = float(point[name][i])
            row[f"{stat}_ci_low"] = float(interval[name][0, i])
            row[f"{stat}_ci_high"] = float(interval[name][1, i])
        out[name] = row
    return out
