"""Cross-task prediction: a new task's returns predicted from its metrics alone, with the
calibration fitted on another task, committed before the new task's RL runs, then scored.

The calibration is the one the source task's leaderboard uses
(:func:`repbench.analysis.robustness.validated_method` on the source's encoders; no refitting):
a line return ~ metric through the source encoders' mean returns, its metric chosen on the
source, with the source's leave-one-family-out interval half-width.

Returns are not on one scale across tasks (the peg-in-hole pays up to ~900 per episode, a
60-step press task less), so predictions are made in units of the task's *privileged agent*
return — the return ceiling (``oracle_task`` + SAC on the task-frame state), which each task
has before any encoder's RL, because that agent collects the on-policy data: a source return
``R`` maps to ``R × P_target / P_source``, and so does the interval. The metric's own scale
is taken as it is (no refitting is the point of the test).

The test (:func:`score_predictions`), fixed before the target's RL records exist:

* ranking: Spearman ρ of the predicted vs the actual per-encoder mean returns over the
  *learned* encoders (baselines out), with the 95 % interval from resampling encoders and,
  inside each, seeds (:func:`repbench.analysis.robustness.ranking_agreement`); the prediction
  transfers if that interval lies above 0, fails if below, else inconclusive. The ranking uses
  the *unclipped* line (the source calibration clips to its return range, which would tie the
  encoders beyond it);
* intervals: how many actual mean returns (all encoders) fall inside the stated intervals,
  against the source's nominal coverage.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from repbench.analysis.calibration import (
    MIN_FAMILIES,
    Method,
    fit,
    half_width,
    held_out_errors,
    reference_table,
)
from repbench.analysis.robustness import Check, ranking_agreement
from repbench.errors import DataError

#: The ranking test's threshold: the 95 % interval of ρ must lie above this.
TRANSFER_THRESHOLD = 0.0
#: ``predictions/<task>.csv``'s columns, in order.
COLUMNS = ("task", "agent", "encoder", "family", "metric", "metric_value",
           "predicted_return", "ci_low", "ci_high", "predicted_unclipped", "source_task",
           "source_prediction", "source_half_width", "ceiling_source", "ceiling_target",
           "method", "coverage", "n_reference")


def privileged_return(records: Sequence[Mapping[str, Any]], task: str) -> float:
    """The privileged agent's evaluation return on ``task`` from its ``full_state_agent``
    record; :class:`DataError` when there is none."""
    for r in records:
        if r.get("kind") == "full_state_agent" and (r.get("task") or {}).get("name") == task:
            return float(r["values"]["eval_return"])
    raise DataError(f"no privileged-agent record of {task} (a full_state_agent record); run "
                    "the suite's datasets first (`repbench run --no-rl`)")


def predict_task(source_metric_rows: Sequence[Mapping[str, Any]],
                 source_rl_rows: Sequence[Mapping[str, Any]],
                 target_metric_rows: Sequence[Mapping[str, Any]], *,
                 source_task: str, target_task: str, agent: str,
                 families: Mapping[str, str], ceiling_source: float, ceiling_target: float,
                 choose: Callable[..., tuple[Method, Any, str | None, float]]) -> pd.DataFrame:
    """Every target encoder's predicted return (:data:`COLUMNS`), from the calibration fitted
    on ``source_task`` × ``agent``.

    ``families``: encoder → display family (``"baselines"`` or a learned family), for the
    source's folds and the target's learned/baseline split; ``choose``:
    :func:`repbench.analysis.robustness.validated_method`.
    """
    if not (np.isfinite(ceiling_source) and ceiling_source > 0 and np.isfinite(ceiling_target)):
        raise DataError(f"privileged returns {ceiling_source} ({source_task}) and "
                        f"{ceiling_target} ({target_task}) must be finite, the first > 0")
    method, *_ = choose(list(source_metric_rows), list(source_rl_rows), families, source_task,
                        agent)
    values, runs = reference_table(source_metric_rows, source_rl_rows, source_task, agent)
    target, _ = reference_table(target_metric_rows, [], target_task, agent)
    if not target:
        raise DataError(f"no metric values of {target_task}; run its metrics first")
    metrics = sorted(set.intersection(*(set(v) for v in target.values())))
    encs = sorted(e for e in runs if e in values and all(m in values[e] for m in metrics))
    y = np.array([np.mean(runs[e]) for e in encs], float)
    x = {m: np.array([values[e][m] for e in encs], float) for m in metrics}
    f = fit(x, y, method)
    if f is None:
        raise DataError(f"no metric of {source_task} varies with its {agent} return")
    groups = [families.get(e, e) for e in encs]
    if len(set(groups)) < MIN_FAMILIES:
        groups = encs
    half = half_width(held_out_errors(x, y, groups, method), method)
    scale = ceiling_target / ceiling_source
    line = replace(f, clip=False)  # the same line, unclipped: it ranks encoders beyond the range
    rows = []
    for enc in sorted(target):
        v = {m: target[enc][m] for m in f.metrics}
        src = float(f.predict(v)[0])
        raw = float(line.predict(v)[0])
        rows.append({
            "task": target_task, "agent": agent, "encoder": enc,
            "family": families.get(enc, ""), "metric": " + ".join(f.metrics),
            "metric_value": v[f.metrics[0]], "predicted_return": src * scale,
            "ci_low": (src - half) * scale, "ci_high": (src + half) * scale,
            "predicted_unclipped": raw * scale, "source_task": source_task,
            "source_prediction": src, "source_half_width": half,
            "ceiling_source": ceiling_source, "ceiling_target": ceiling_target,
            "method": method.name, "coverage": method.coverage, "n_reference": len(encs)})
    return pd.DataFrame(rows, columns=list(COLUMNS))


def read_prediction(path: str | Path) -> pd.DataFrame:
    """A prediction table (``<task id>.csv``) with the note written beside it, if any.

    ``<task id>.note`` (plain text, next to the CSV) says what the score should be read
    with — e.g. that the agents read retrained encoders — without touching the committed
    table; it lands in ``table.attrs["note"]`` and :func:`score_predictions` appends it to the
    check's detail."""
    path = Path(path)
    table = pd.read_csv(path)
    note = path.with_suffix(".note")
    if note.is_file():
        table.attrs["note"] = " ".join(note.read_text().split())
    return table


def prediction_check_name(predictions: pd.DataFrame) -> str:
    """The name of the ranking check that scores ``predictions`` (one task × agent): "<source>
    calibration predicts <task> <agent>" across tasks; within one task, where the predicted
    encoders are the ones added after the calibration (the zoo), "<task> calibration predicts
    new encoders on <task> <agent>"."""
    task, agent = str(predictions["task"].iloc[0]), str(predictions["agent"].iloc[0])
    source = str(predictions["source_task"].iloc[0])
    if source == task:
        return f"{source} calibration predicts new encoders on {task} {agent}"
    return f"{source} calibration predicts {task} {agent}"


def score_predictions(predictions: pd.DataFrame, rl_rows: Sequence[Mapping[str, Any]], *,
                      n_bootstrap: int = 2000, seed: int = 0) -> tuple[Check, pd.DataFrame]:
    """The pre-registered test of ``predictions`` (one task × agent, :data:`COLUMNS`) against
    the actual returns in ``rl_rows``: the ranking :class:`Check` over learned encoders and a
    per-encoder table (predicted, interval, actual mean over seeds, n seeds, inside)."""
    (task, agent), = predictions[["task", "agent"]].drop_duplicates().itertuples(index=False)
    actual: dict[str, list[float]] = {}
    for r in rl_rows:
        if r["task"] == task and r["agent"] == agent:
            actual.setdefault(r["encoder"], []).append(float(r["eval_return"]))
    table = predictions.copy()
    table["actual_return"] = [np.mean(actual[e]) if e in actual else np.nan
                              for e in table["encoder"]]
    table["n_seeds"] = [len(actual.get(e, [])) for e in table["encoder"]]
    table["inside"] = (table["actual_return"] >= table["ci_low"]) & \
        (table["actual_return"] <= table["ci_high"])
    learned = table[(table["family"] != "baselines") & (table["n_seeds"] > 0)]
    check = ranking_agreement(
        {e: [p] for e, p in zip(learned["encoder"], learned["predicted_unclipped"], strict=True)},
        {e: actual[e] for e in learned["encoder"]},
        check=prediction_check_name(predictions),
        kind="spearman", threshold=TRANSFER_THRESHOLD, n_bootstrap=n_bootstrap, seed=seed)
    scored = table[table["n_seeds"] > 0]
    n_in, n = int(scored["inside"].sum()), len(scored)
    check = replace(check, statistic="Spearman ρ of predicted vs actual mean returns (learned)",
                    detail=f"{check.detail}; {n_in}/{n} actual returns inside the stated "
                           f"{predictions['coverage'].iloc[0]:.0%} intervals"
                           + (f"; note: {predictions.attrs['note']}"
                              if predictions.attrs.get("note") else ""))
    return check, table
