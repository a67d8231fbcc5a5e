"""A metric computed on stored latents: the rows it reads, its extra arrays, its value checked.

One function, :func:`compute_on_latents`, used by the metric stage of a run
(:mod:`repbench.pipeline.stages`) and by ``repbench score-metric``
(:mod:`repbench.analysis.score_metric`) on the shipped reference latents, so that a metric
scored against the reference is computed exactly as the run computed the reference's own.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from repbench.errors import DataError

__all__ = ["check_finite", "compute_on_latents", "metric_rows"]


def metric_rows(rows: str, source: np.ndarray, source_names: list[str]
                ) -> tuple[np.ndarray, str]:
    """Row indices a metric declared with ``rows`` is computed on, and a description.

    ``"on_policy"`` selects the rows of the on-policy dataset. When the latents have none (a
    suite without on-policy data) it raises DataError: computed on the other rows, the metric
    would be published under its name as something else (the expert-action probe on random
    exploration). The planner refuses such a suite before any stage runs
    (:func:`repbench.pipeline.plan.build_plan`).
    """
    if rows == "all":
        return np.arange(len(source)), "all: " + " + ".join(source_names)
    if rows in source_names:
        return np.flatnonzero(source == source_names.index(rows)), rows
    raise DataError(f"the latents hold no {rows} rows (only {' + '.join(source_names)}), which "
                    f"this metric is computed on; give the suite {rows} data "
                    f"(dataset.{rows}_episodes > 0) or drop the metric")


def check_finite(result: Any, who: str) -> None:
    """A metric's value must be a finite number: NaN or infinity is not a score to publish (it
    was stored as null, counted as computed, and broke every leaderboard of the store)."""
    value = getattr(result, "value", None)
    try:
        finite = math.isfinite(float(value))
    except (TypeError, ValueError):
        finite = False
    if not finite:
        raise DataError(f"{who} returned the value {value!r}, not a finite number, so it is not "
                        "stored; fix the metric (return a finite value, or raise an error "
                        "saying why it has none)")


def compute_on_latents(fn: Any, arrays: Mapping[str, np.ndarray], *, seed: int,
                       params: Mapping[str, Any], who: str, rows: str | None = None
                       ) -> dict[str, Any]:
    """``fn``'s result on ``arrays`` (the arrays of a latents stage: ``z``, ``z_true``,
    ``episode``, ``source``, ``source_names`` and the :data:`repbench.metric.EXTRA_INPUTS` it
    names), as the metric record's ``values``: the result's dict plus ``time_s``, ``rows`` and
    ``n_rows``. ``rows`` overrides the metric's declared rows; ``seed`` seeds its generator.
    Raises DataError (naming ``who``) for latents without the rows it needs or a value that is
    not finite."""
    names = [str(n) for n in arrays.get("source_names", [])]
    source = arrays.get("source", np.zeros(len(arrays["z"]), dtype=np.int64))
    try:
        idx, rows_used = metric_rows(rows or getattr(fn, "rows", "all"), source, names)
    except DataError as exc:
        raise DataError(f"{who}: {exc}") from None
    extra = {k: arrays[k][idx] for k in getattr(fn, "extra_inputs", ()) if k in arrays}
    start = time.time()
    result = fn(arrays["z"][idx], arrays["z_true"][idx], arrays["episode"][idx],
                np.random.default_rng(seed), **extra, **params)
    check_finite(result, who)
    out = result.to_dict()
    out["time_s"] = time.time() - start
    out["rows"] = rows_used
    out["n_rows"] = int(idx.size)
    return out
