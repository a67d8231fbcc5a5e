"""Predict an encoder's RL return from its metrics, calibrated on reference encoders.

Deliberately simple and honest, and meant to be replaced by a richer metric leaderboard:

* predictor: the metric whose values correlate best (largest |Pearson r|) with the reference
  encoders' mean evaluation return (over seeds), for one task and agent;
* model: an ordinary least-squares line, return = a + b · metric;
* interval: the prediction ± the largest leave-one-out error, where every fold redoes the metric
  choice and the fit without the left-out encoder (so the choice of the best metric is paid for
  in the interval). With n reference encoders this is a jackknife interval whose coverage is
  about 1 − 2/(n + 1) under exchangeability — wide with the few encoders of a small suite, as it
  should be.

No prediction is made with fewer than :data:`MIN_REFERENCE` reference encoders.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

MIN_REFERENCE = 4
METHOD = "linear fit on the best-correlated metric, ± largest leave-one-out error"


def _best_metric(x: Mapping[str, np.ndarray], y: np.ndarray) -> str | None:
    best, best_r = None, -1.0
    for name in sorted(x):
        v = x[name]
        if np.std(v) < 1e-12 or np.std(y) < 1e-12:
            continue
        r = abs(float(np.corrcoef(v, y)[0, 1]))
        if np.isfinite(r) and r > best_r:
            best, best_r = name, r
    return best


def _fit_predict(x: np.ndarray, y: np.ndarray, x_new: float) -> float:
    slope, intercept = np.polyfit(x, y, 1)
    return float(intercept + slope * x_new)


def predict_return(reference_metrics: Mapping[str, Mapping[str, float]],
                   reference_returns: Mapping[str, float],
                   new_metrics: Mapping[str, float]) -> dict[str, Any] | None:
    """Predicted return of a new encoder.

    Args:
        reference_metrics: encoder → metric → value, for the reference encoders.
        reference_returns: encoder → mean evaluation return over seeds.
        new_metrics: metric → value of the new encoder.

    Returns:
        ``{"predicted_return", "ci_low", "ci_high", "predictor", "n_reference", "method",
        "loo_errors"}``, or None when fewer than :data:`MIN_REFERENCE` reference encoders
        share a metric with the new one.
    """
    usable = [m for m in new_metrics if np.isfinite(new_metrics[m])]
    encs = sorted(e for e in reference_returns if e in reference_metrics
                  and np.isfinite(reference_returns[e])
                  and all(np.isfinite(reference_metrics[e].get(m, np.nan)) for m in usable))
    if len(encs) < MIN_REFERENCE or not usable:
        return None
    y = np.array([reference_returns[e] for e in encs], dtype=float)
    x = {m: np.array([reference_metrics[e][m] for e in encs], dtype=float) for m in usable}
    best = _best_metric(x, y)
    if best is None:
        return None
    errors = []
    for i in range(len(encs)):
        keep = np.arange(len(encs)) != i
        fold_best = _best_metric({m: v[keep] for m, v in x.items()}, y[keep])
        if fold_best is None:
            continue
        errors.append(abs(_fit_predict(x[fold_best][keep], y[keep], x[fold_best][i]) - y[i]))
    if not errors:
        return None
    pred = _fit_predict(x[best], y, float(new_metrics[best]))
    half = float(max(errors))
    return {"predicted_return": pred, "ci_low": pred - half, "ci_high": pred + half,
            "predictor": best, "n_reference": len(encs), "method": METHOD,
            "loo_errors": [float(e) for e in errors]}


def predict_from_rows(metric_rows: Iterable[Mapping[str, Any]],
                      rl_rows: Iterable[Mapping[str, Any]], encoder: str
                      ) -> list[dict[str, Any]]:
    """:func:`predict_return` for ``encoder`` for every task × agent in the reference rows
    (:class:`repbench.analysis.results.Results` rows; ``encoder``'s own RL rows, if any, are
    ignored)."""
    metric_rows, rl_rows = list(metric_rows), list(rl_rows)
    out = []
    for task, agent in sorted({(r["task"], r["agent"]) for r in rl_rows}):
        runs: dict[str, list[float]] = {}
        for r in rl_rows:
            if r["task"] == task and r["agent"] == agent and r["encoder"] != encoder:
                runs.setdefault(r["encoder"], []).append(float(r["eval_return"]))
        ref: dict[str, dict[str, float]] = {}
        new: dict[str, float] = {}
        for r in metric_rows:
            if r["task"] != task or r.get("value") is None:
                continue
            target = new if r["encoder"] == encoder else ref.setdefault(r["encoder"], {})
            target[r["metric"]] = float(r["value"])
        pred = predict_return(ref, {e: float(np.mean(v)) for e, v in runs.items()}, new)
        if pred is not None:
            out.append({"task": task, "agent": agent, "encoder": encoder, **pred})
    return out
