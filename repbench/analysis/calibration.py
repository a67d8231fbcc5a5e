"""Predict an encoder's RL return from its metrics, calibrated on reference encoders.

A *fit* chooses the metric (or two) from the reference encoders alone and draws a least-squares
line (plane) return ~ metric(s) through them:

* one metric: the one whose values correlate best (largest |Pearson r|) with the reference
  encoders' mean evaluation return over seeds;
* two metrics: that one, then the one that lowers the residual sum of squares of the two-metric
  least-squares fit most.

Predictions of the family methods are clipped to the range of the reference returns (a return
outside what any reference encoder reached is an extrapolation of a line, not a prediction).

The interval of a prediction comes from *leave one family out* residuals (a cross-validation
"CV+"-style interval with families as folds): every reference encoder is predicted by the fit
made without its whole family (the metric choice included), and the half-width is the
⌈c (n + 1)⌉-th smallest of those n absolute errors, for nominal coverage c. A new encoder is
treated as a new family — the question a researcher asks of an encoder nobody has scored. The
older interval, ± the largest leave-one-*encoder*-out error (:data:`LEGACY`), is kept for the
comparison in :mod:`repbench.analysis.robustness`, which measures every method's coverage on
held-out families and chooses the one :func:`predict_from_rows` uses (:data:`CANDIDATES`, in
the order fixed before the data; the rule is :func:`repbench.analysis.robustness.choose_method`).

No prediction is made with fewer than :data:`MIN_REFERENCE` reference encoders.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

MIN_REFERENCE = 4
#: The fewest encoders a fold's line is fitted on (a held-out fit of MIN_REFERENCE - 1).
MIN_FIT = MIN_REFERENCE - 1
#: Families are the folds only when there are at least this many (one held out, two left so
#: that the metric choice inside the fold is not made on one family); else encoders are.
MIN_FAMILIES = 3


@dataclass(frozen=True)
class Method:
    """One way of predicting a return with an interval.

    ``n_metrics`` metrics are chosen inside every fit; ``coverage`` is the interval's nominal
    coverage (``None`` for :data:`LEGACY`, whose coverage is not stated by construction);
    ``folds`` says whose residuals set the width: ``"family"`` (leave one family out, the
    c-quantile) or ``"encoder_max"`` (leave one encoder out, the largest error).
    """

    name: str
    n_metrics: int
    coverage: float | None
    folds: str
    clip: bool = True

    @property
    def description(self) -> str:
        what = "best-correlated metric" if self.n_metrics == 1 else \
            f"{self.n_metrics} metrics chosen forward"
        if self.folds == "encoder_max":
            return f"linear fit on the {what}, ± largest leave-one-encoder-out error"
        return (f"linear fit on the {what}, {self.coverage:.0%} interval from leave-one-family-"
                "out errors")


#: The methods :mod:`repbench.analysis.robustness` checks, in the order of preference fixed
#: before the held-out data were seen (the first whose coverage holds with an informative
#: width is the one used).
CANDIDATES: tuple[Method, ...] = (
    Method("family_cv_1metric_80", 1, 0.8, "family"),
    Method("family_cv_2metrics_80", 2, 0.8, "family"),
    Method("family_cv_1metric_90", 1, 0.9, "family"),
)
#: The interval `evaluate` used before its coverage was measured.
LEGACY = Method("loo_max_1metric", 1, None, "encoder_max", clip=False)
DEFAULT_METHOD = CANDIDATES[0]
METHOD = DEFAULT_METHOD.description  # kept for callers that printed the method's text


@dataclass(frozen=True)
class Fit:
    """A fitted predictor: the chosen metrics and the least-squares coefficients."""

    metrics: tuple[str, ...]
    coef: np.ndarray  # intercept first
    y_range: tuple[float, float]
    clip: bool

    def predict(self, values: Mapping[str, np.ndarray] | Mapping[str, float]) -> np.ndarray:
        x = np.column_stack([np.ones(np.size(values[self.metrics[0]]))]
                            + [np.atleast_1d(np.asarray(values[m], float)) for m in self.metrics])
        yhat = x @ self.coef
        return np.clip(yhat, *self.y_range) if self.clip else yhat


def _abs_pearson(v: np.ndarray, y: np.ndarray) -> float:
    if np.std(v) < 1e-12 or np.std(y) < 1e-12:
        return -1.0
    r = abs(float(np.corrcoef(v, y)[0, 1]))
    return r if np.isfinite(r) else -1.0


def _lstsq(cols: Sequence[np.ndarray], y: np.ndarray) -> tuple[np.ndarray, float]:
    x = np.column_stack([np.ones(y.size), *cols])
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    return coef, float(np.sum((x @ coef - y) ** 2))


def fit(x: Mapping[str, np.ndarray], y: np.ndarray, method: Method = DEFAULT_METHOD
        ) -> Fit | None:
    """Choose ``method.n_metrics`` metrics from ``x`` (metric → values, aligned with ``y``) and
    fit the line; None when no metric varies with ``y``."""
    names = sorted(x)
    scores = [(_abs_pearson(np.asarray(x[m], float), y), m) for m in names]
    first = max(scores, key=lambda s: (s[0], [-ord(c) for c in s[1]]), default=(-1.0, ""))
    if first[0] < 0:
        return None
    chosen = [first[1]]
    while len(chosen) < method.n_metrics:
        best: tuple[float, str] | None = None
        for m in names:
            if m in chosen or np.std(x[m]) < 1e-12:
                continue
            _, sse = _lstsq([x[c] for c in (*chosen, m)], y)
            if best is None or sse < best[0] - 1e-12:
                best = (sse, m)
        if best is None:
            break
        chosen.append(best[1])
    coef, _ = _lstsq([np.asarray(x[m], float) for m in chosen], y)
    return Fit(tuple(chosen), coef, (float(np.min(y)), float(np.max(y))), method.clip)


def held_out_errors(x: Mapping[str, np.ndarray], y: np.ndarray, groups: Sequence[str],
                    method: Method = DEFAULT_METHOD) -> np.ndarray:
    """Each encoder's absolute error when predicted by the fit made without its group
    (``method.folds == "family"``: its family; ``"encoder_max"``: itself alone). NaN where the
    rest cannot be fitted (fewer than :data:`MIN_FIT` encoders or one family left)."""
    groups = np.asarray(list(groups) if method.folds == "family" else range(y.size), object)
    err = np.full(y.size, np.nan)
    for g in dict.fromkeys(groups.tolist()):
        out = groups == g
        keep = ~out
        if keep.sum() < MIN_FIT or np.unique(groups[keep]).size < 2:
            continue
        f = fit({m: v[keep] for m, v in x.items()}, y[keep], method)
        if f is not None:
            err[out] = np.abs(f.predict({m: v[out] for m, v in x.items()}) - y[out])
    return err


def half_width(errors: np.ndarray, method: Method) -> float:
    """The interval's half-width from held-out errors: the ⌈c (n + 1)⌉-th smallest (infinite
    when that exceeds n), or the largest for :data:`LEGACY`."""
    e = np.sort(np.asarray(errors, float)[np.isfinite(errors)])
    if e.size == 0:
        return float("nan")
    if method.coverage is None:
        return float(e[-1])
    k = math.ceil(method.coverage * (e.size + 1))
    return float(e[k - 1]) if k <= e.size else float("inf")


def predict_return(reference_metrics: Mapping[str, Mapping[str, float]],
                   reference_returns: Mapping[str, float],
                   new_metrics: Mapping[str, float],
                   families: Mapping[str, str] | None = None,
                   method: Method = DEFAULT_METHOD) -> dict[str, Any] | None:
    """Predicted return of a new encoder.

    Args:
        reference_metrics: encoder → metric → value, for the reference encoders.
        reference_returns: encoder → mean evaluation return over seeds.
        new_metrics: metric → value of the new encoder.
        families: encoder → family of the reference encoders (the folds of the interval);
            each encoder is its own family when omitted or when the reference has fewer than
            :data:`MIN_FAMILIES` families.
        method: how to fit and how wide the interval is (:data:`CANDIDATES`, :data:`LEGACY`).

    Returns:
        ``{"predicted_return", "ci_low", "ci_high", "predictor", "n_reference", "method",
        "coverage", "heldout_errors"}``, or None when fewer than :data:`MIN_REFERENCE`
        reference encoders share a metric with the new one.
    """
    usable = [m for m in new_metrics if np.isfinite(new_metrics[m])]
    encs = sorted(e for e in reference_returns if e in reference_metrics
                  and np.isfinite(reference_returns[e])
                  and all(np.isfinite(reference_metrics[e].get(m, np.nan)) for m in usable))
    if len(encs) < MIN_REFERENCE or not usable:
        return None
    y = np.array([reference_returns[e] for e in encs], dtype=float)
    x = {m: np.array([reference_metrics[e][m] for e in encs], dtype=float) for m in usable}
    f = fit(x, y, method)
    if f is None:
        return None
    groups = [(families or {}).get(e, e) for e in encs]
    if len(set(groups)) < MIN_FAMILIES:  # too few families to hold one out: encoders as folds
        groups = encs
    errors = held_out_errors(x, y, groups, method)
    half = half_width(errors, method)
    if not np.isfinite(half) and not math.isinf(half):
        return None
    pred = float(f.predict({m: float(new_metrics[m]) for m in f.metrics})[0])
    return {"predicted_return": pred, "ci_low": pred - half, "ci_high": pred + half,
            "predictor": " + ".join(f.metrics), "n_reference": len(encs),
            "method": method.description, "method_name": method.name,
            "coverage": method.coverage,
            "heldout_errors": [float(e) for e in errors if np.isfinite(e)]}


def reference_table(metric_rows: Iterable[Mapping[str, Any]],
                    rl_rows: Iterable[Mapping[str, Any]], task: str, agent: str,
                    exclude: str | None = None
                    ) -> tuple[dict[str, dict[str, float]], dict[str, list[float]]]:
    """(encoder → metric → value, encoder → returns over seeds) of one task × agent, from
    :class:`repbench.analysis.results.Results` rows, without ``exclude``'s RL rows."""
    runs: dict[str, list[float]] = {}
    for r in rl_rows:
        if r["task"] == task and r["agent"] == agent and r["encoder"] != exclude:
            runs.setdefault(r["encoder"], []).append(float(r["eval_return"]))
    values: dict[str, dict[str, float]] = {}
    for r in metric_rows:
        if r["task"] == task and r.get("value") is not None:
            values.setdefault(r["encoder"], {})[r["metric"]] = float(r["value"])
    return values, runs


def predict_from_rows(metric_rows: Iterable[Mapping[str, Any]],
                      rl_rows: Iterable[Mapping[str, Any]], encoder: str,
                      families: Mapping[str, str] | None = None,
                      method: Method | None = None,
                      choose: Callable[..., tuple[Method, Any, str | None, float]] | None = None
                      ) -> list[dict[str, Any]]:
    """:func:`predict_return` for ``encoder`` for every task × agent in the reference rows
    (:class:`repbench.analysis.results.Results` rows; ``encoder``'s own RL rows, if any, are
    ignored).

    With ``families``, no ``method`` and ``choose`` (``choose(metric_rows, rl_rows, families,
    task, agent)``, i.e. :func:`repbench.analysis.robustness.validated_method`), each task ×
    agent uses the method whose coverage holds out of sample on the reference encoders, and
    the prediction carries that
    measurement: ``measured_coverage`` with ``coverage_ci``, ``median_half_width`` and
    ``method_warning``.
    """
    metric_rows, rl_rows = list(metric_rows), list(rl_rows)
    out = []
    for task, agent in sorted({(r["task"], r["agent"]) for r in rl_rows}):
        values, runs = reference_table(metric_rows, rl_rows, task, agent, exclude=encoder)
        new = values.pop(encoder, {})
        chosen, measured, warning, width = method or DEFAULT_METHOD, None, None, float("nan")
        if method is None and families and choose is not None:
            ref_rows = [r for r in rl_rows if r["encoder"] != encoder]
            chosen, measured, warning, width = choose(
                [r for r in metric_rows if r["encoder"] != encoder], ref_rows, families,
                task, agent)
        pred = predict_return(values, {e: float(np.mean(v)) for e, v in runs.items()}, new,
                              families, chosen)
        if pred is None:
            continue
        if measured is not None:
            pred.update(measured_coverage=measured.value,
                        coverage_ci=(measured.ci_low, measured.ci_high),
                        median_half_width=width)
        pred["method_warning"] = warning
        out.append({"task": task, "agent": agent, "encoder": encoder, **pred})
    return out

