"""True-state diagnostics (paper Fig. 6a): are the first/second differences of z° normal?

The smoothness argument of the paper (§III.B) assumes δz° ~ N(0, αI). These diagnostics show
how far a dataset is from that: per dimension, the distribution of first differences
δ¹ = z°_{n+1} − z°_n and second differences δ² = z°_{n+1} − 2z°_n + z°_{n−1} (within episodes
only), with histograms, moments and D'Agostino–Pearson's normality test
(:func:`scipy.stats.normaltest`). Static dimensions (no movement within any episode, e.g. the
hole position) are flagged and get no statistics.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

from repbench.dataset import successor_index
from repbench.errors import DataError
from repbench.metric import check_metric_inputs

__all__ = ["true_state_differences"]


def _describe(d: np.ndarray, bins: int, static: bool) -> dict[str, Any]:
    out: dict[str, Any] = {"n": int(d.size), "mean": float(d.mean()), "std": float(d.std()),
                           "mean_square": float((d**2).mean()), "static": bool(static)}
    if static or d.size < 8:
        out.update(skew=None, excess_kurtosis=None, normaltest_stat=None,
                   normaltest_pvalue=None, histogram=None)
        return out
    test = stats.normaltest(d)
    counts, edges = np.histogram(d, bins=bins)
    out.update(skew=float(stats.skew(d)), excess_kurtosis=float(stats.kurtosis(d)),
               normaltest_stat=float(test.statistic), normaltest_pvalue=float(test.pvalue),
               histogram={"bin_edges": edges.tolist(), "counts": counts.tolist()})
    return out


def true_state_differences(z_true: np.ndarray, episode: np.ndarray, *, bins: int = 50,
                           static_rtol: float = 1e-10) -> dict[str, Any]:
    """Distribution of first and second differences of z° per dimension (paper Fig. 6a).

    Returns a JSON-serializable dict::

        {"first": [per-dim dict], "second": [per-dim dict], "static_dims": [...],
         "alpha_per_dim": [E(δ¹)² per dim], "n_dims": S}

    Each per-dimension dict has n, mean, std, mean_square, skew, excess_kurtosis,
    normaltest_stat/pvalue (large statistic / tiny p: not normal) and a histogram
    (bin_edges, counts); static dimensions (mean square of δ¹ below ``static_rtol`` times the
    largest) have ``static: True`` and None statistics.
    """
    z_true, _, episode = check_metric_inputs(z_true, z_true, episode,
                                             name="true_state_differences", min_samples=3)
    i1, j1 = successor_index(episode, None, 1)
    i2, j2 = successor_index(episode, None, 2)
    if i2.size == 0:
        raise DataError("true_state_differences: no episode has 3 successive steps")
    d1 = z_true[j1] - z_true[i1]
    d2 = z_true[j2] - 2 * z_true[i2 + 1] + z_true[i2]
    ms = (d1**2).mean(axis=0)
    static = ms <= static_rtol * max(float(ms.max()), 1e-300)
    return {
        "first": [_describe(d1[:, s], bins, bool(static[s])) for s in range(z_true.shape[1])],
        "second": [_describe(d2[:, s], bins, bool(static[s])) for s in range(z_true.shape[1])],
        "static_dims": np.flatnonzero(static).tolist(),
        "alpha_per_dim": ms.tolist(),
        "n_dims": int(z_true.shape[1]),
    }
