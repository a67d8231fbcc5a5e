"""Leaderboards are pure functions of result records: records → :class:`Results` → tables →
CSV/HTML. Which records a suite's leaderboard shows is decided by the caller (the runner selects
them by identity, :mod:`repbench.analysis.results`); nothing here reads a plan or the store.

* ``encoders.csv`` — one row per task × encoder: how it was trained (fit time in wall and CPU
  seconds, epochs run, the epoch kept by early stopping and its held-out loss), every metric
  with its CI, and per agent the RL return over seeds (mean and interquartile mean, each with a
  stratified-bootstrap 95 % interval from rliable; seeds are the unit) and success rate.
* ``metrics.csv`` — one row per task × agent × metric, ranked: the metric leaderboard
  (:func:`metric_ranking`: Spearman within the learned encoders and over all encoders with
  intervals and Holm/BH-adjusted p-values, leave-one-encoder-out error, cost in wall and CPU
  seconds), then Pearson, Spearman and Kendall over all encoders with bootstrap CIs and
  p-values — "which metric predicts RL performance".
* ``claims.csv`` — the paper's claims checked against these records, each with its statistic,
  interval and verdict (:mod:`repbench.analysis.claims`).
* ``robustness.csv`` — does the answer hold: the out-of-sample coverage of the calibrated
  return prediction per method, and, where the records have them, SAC vs DDPG and 10k vs
  longer-budget agreement, each with its interval and a verdict fixed before the data
  (:mod:`repbench.analysis.robustness`).
* ``index.html`` — one self-contained page (see :mod:`repbench.report.report_html`).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from repbench.analysis.correlation import METHODS, correlate
from repbench.analysis.results import Results, build_results, write_records
from repbench.report.families import _families
from repbench.rl.aggregate import aggregate_seeds

__all__ = ["BOARD_LOCK", "Results", "board_lock", "build_results", "encoder_table",
           "metric_table", "write_leaderboards"]

#: The lock file a leaderboard write holds in its folder (:func:`board_lock`).
BOARD_LOCK = ".repbench-board.lock"


#: How each encoder was trained (from its encoder record; empty for untrained baselines).
#: ``fit_time_s`` is the fit's wall time, ``fit_cpu_s`` the CPU seconds of the whole encoder
#: stage (fit, output checks, figure), which a paused or crowded run does not inflate.
ENCODER_TRAINING_COLUMNS = ("fit_time_s", "fit_cpu_s", "epochs_run", "best_epoch",
                            "heldout_loss")


def encoder_table(res: Results) -> pd.DataFrame:
    """One row per task × encoder (see module docstring)."""
    rows: dict[tuple[str, str], dict[str, Any]] = {}
    for r in res.encoder_rows:
        rows[(r["task"], r["encoder"])] = {
            "task": r["task"], "encoder": r["encoder"], "latent_dim": r["latent_dim"],
            **{k: r.get(k) for k in ENCODER_TRAINING_COLUMNS}}
    for r in res.metric_rows:
        row = rows.setdefault((r["task"], r["encoder"]), {"task": r["task"],
                                                          "encoder": r["encoder"]})
        row[r["metric"]] = r["value"]
        row[f"{r['metric']}_ci_low"] = r.get("ci_low")
        row[f"{r['metric']}_ci_high"] = r.get("ci_high")
    by: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for r in res.rl_rows:
        by.setdefault((r["task"], r["encoder"], r["agent"]), []).append(r)
    aggregated = aggregate_seeds({f"{t}|{e}|{a}": [x["eval_return"] for x in runs]
                                  for (t, e, a), runs in by.items()})
    for (task, enc, agent), runs in sorted(by.items()):
        row = rows.setdefault((task, enc), {"task": task, "encoder": enc})
        agg = aggregated[f"{task}|{enc}|{agent}"]
        for stat, col in (("mean", f"{agent}_return"), ("iqm", f"{agent}_return_iqm")):
            row[col], row[f"{col}_ci_low"], row[f"{col}_ci_high"] = (
                agg[stat], agg[f"{stat}_ci_low"], agg[f"{stat}_ci_high"])
        row[f"{agent}_success"] = float(np.mean([x["eval_success_rate"] for x in runs]))
        row[f"{agent}_seeds"] = len(runs)
    for p in res.predictions:  # repbench evaluate --metrics-only
        row = rows.setdefault((p["task"], p["encoder"]), {"task": p["task"],
                                                          "encoder": p["encoder"]})
        a = p["agent"]
        row[f"{a}_predicted_return"] = p["predicted_return"]
        row[f"{a}_predicted_return_ci_low"] = p["ci_low"]
        row[f"{a}_predicted_return_ci_high"] = p["ci_high"]
        row[f"{a}_predicted_from"] = p["predictor"]
    if res.stale:  # older plugin versions: shown, marked, never dropped
        for key, row in rows.items():
            row["stale"] = "; ".join(res.stale.get(key, []))
    df = pd.DataFrame(list(rows.values()))
    if df.empty:
        return df
    sort_col = next((c for c in df.columns if c.endswith("_return")), None)
    if sort_col:
        df = df.sort_values(["task", sort_col], ascending=[True, False], na_position="last")
    return df.reset_index(drop=True)


def metric_ranking(res: Results, n_bootstrap: int = 1000, seed: int = 0
                   ) -> tuple[pd.DataFrame, dict[tuple[str, str, str], dict[str, float]]]:
    """The metric leaderboard (:func:`repbench.analysis.correlation.metric_leaderboard`) as a table,
    ranked per task × agent by the within-learned-encoders Spearman ρ, then the all-encoder ρ;
    and the leave-one-encoder-out predicted returns per (task, agent, metric)."""
    from repbench.analysis.correlation import metric_leaderboard
    from repbench.analysis.noise_ceiling import add_ceiling_columns, ceilings

    families = _families(res)
    rows, preds = metric_leaderboard(res.metric_rows, res.rl_rows, families,
                                     res.provenance.get("directions", {}),
                                     n_bootstrap=n_bootstrap, seed=seed)
    df = pd.DataFrame(rows)
    if not df.empty:
        df = df.sort_values(["task", "agent", "spearman_learned", "spearman_all"],
                            ascending=[True, True, False, False],
                            na_position="last").reset_index(drop=True)
        df = add_ceiling_columns(df, ceilings(res.rl_rows, families, n_bootstrap=n_bootstrap,
                                              seed=seed))
        groups = res.provenance.get("groups", {})
        df.insert(3, "group", df["metric"].map(lambda m: metric_group(m, groups)))
    return df, preds


def metric_group(name: str, groups: Mapping[str, str] | None = None) -> str:
    """``observable`` or ``privileged`` (:data:`repbench.metric.GROUPS`): what the metric reads;
    ``groups[name]`` where given (a scored metric's group from ``repbench score-metric``, kept
    in the provenance as ``"groups"``: a plain-file metric is in no registry), else the
    registered metric's; ``unknown`` for a metric that is not installed here."""
    from repbench.errors import RepbenchError
    from repbench.registry import metrics

    if groups and name in groups:
        return str(groups[name])
    try:
        return str(getattr(metrics.get(name), "group", "privileged"))
    except RepbenchError:
        return "unknown"


def add_loo_predicted_return(enc: pd.DataFrame, ranking: pd.DataFrame,
                             predictions: dict[tuple[str, str, str], dict[str, float]]
                             ) -> pd.DataFrame:
    """Add ``<agent>_loo_predicted_return`` and ``<agent>_loo_predicted_by`` to the encoder
    table: each encoder's return predicted, leave-one-encoder-out, by the metric with the
    lowest LOO error for that task and agent (the metric leaderboard's best predictor)."""
    if enc.empty or ranking.empty or "loo_rmse" not in ranking:
        return enc
    enc = enc.copy()
    for (task, agent), grp in ranking.groupby(["task", "agent"]):
        grp = grp[np.isfinite(grp["loo_rmse"])]
        if grp.empty:
            continue
        best = str(grp.sort_values("loo_rmse").iloc[0]["metric"])
        pred = predictions.get((str(task), str(agent), best), {})
        mask = enc["task"] == task
        enc.loc[mask, f"{agent}_loo_predicted_return"] = enc.loc[mask, "encoder"].map(pred)
        enc.loc[mask, f"{agent}_loo_predicted_by"] = best
    return enc


def metric_table(res: Results, n_bootstrap: int = 1000, seed: int = 0) -> pd.DataFrame:
    """One row per task × agent × metric with correlations to RL return."""
    returns: dict[tuple[str, str], dict[str, list[float]]] = {}
    for r in res.rl_rows:
        returns.setdefault((r["task"], r["agent"]), {}).setdefault(r["encoder"], []).append(
            float(r["eval_return"]))
    values: dict[tuple[str, str], dict[str, float]] = {}
    for r in res.metric_rows:
        values.setdefault((r["task"], r["metric"]), {})[r["encoder"]] = float(r["value"])
    directions = res.provenance.get("directions", {})
    rows = []
    for (task, agent), ret in sorted(returns.items()):
        for (t2, metric), vals in sorted(values.items()):
            if t2 != task:
                continue
            c = correlate(vals, ret, higher_is_better=directions.get(metric, True),
                          n_bootstrap=n_bootstrap, seed=seed)
            rows.append({"task": task, "agent": agent, "metric": metric,
                         "higher_is_better": directions.get(metric, True), **c})
    cols = ["task", "agent", "metric", "higher_is_better", "n_encoders"] + [
        f"{m}{s}" for m in METHODS for s in ("", "_ci_low", "_ci_high", "_p")]
    df = pd.DataFrame(rows, columns=cols)
    if not df.empty:
        df = df.sort_values(["task", "agent", "spearman"], ascending=[True, True, False],
                            na_position="last").reset_index(drop=True)
    return df


def paper_claims(res: Results, ranking: pd.DataFrame) -> pd.DataFrame:
    """The paper's claims (:func:`repbench.analysis.claims.check_claims`) for every task × agent
    with RL results, as one table."""
    from repbench.analysis.claims import check_claims, claims_table

    if ranking.empty:
        return pd.DataFrame()
    families = _families(res)
    tables = [claims_table(check_claims(res.metric_rows, res.rl_rows, ranking, families,
                                        res.provenance.get("directions", {}), task=str(task),
                                        agent=str(agent)), str(task), str(agent))
              for (task, agent), _ in ranking.groupby(["task", "agent"])]
    return pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()


def robustness_checks(res: Results, ranking: pd.DataFrame, longer: Results | None = None,
                      agent_run: Results | None = None,
                      predictions: Sequence[pd.DataFrame] = ()) -> pd.DataFrame:
    """The "Does the answer hold?" checks (:func:`repbench.analysis.robustness.check_results`)
    as ``robustness.csv``'s table; the held-out predictions behind them go to
    ``res.robustness["heldout"]`` for the predicted-vs-actual figure.

    ``longer``: the results of the same task × agent trained for longer (a leaderboard's
    records, :func:`repbench.pipeline.runner.longer_results`): the 10k-vs-longer rows.
    ``agent_run``: another agent's results at this budget
    (:func:`repbench.pipeline.runner.agent_run_results`): the SAC-vs-DDPG rows.
    ``predictions``: pre-registered cross-task predictions (``predictions/<task>.csv``,
    :mod:`repbench.analysis.transfer`); each one whose task × agent has RL rows is scored.
    Metrics joined from ``repbench score-metric`` folders (``res.provenance["scores"]``) are
    left out of the calibration checks, which stay those of ``repbench evaluate``.
    """
    from repbench.analysis.noise_ceiling import ceiling_check, ceilings
    from repbench.analysis.robustness import check_results, robustness_table
    from repbench.analysis.transfer import score_predictions
    from repbench.report.families import encoder_families

    longer_rows = longer.rl_rows if longer is not None else ()
    longer_ranking = metric_ranking(longer)[0] if longer is not None else None
    other_rows = agent_run.rl_rows if agent_run is not None else ()
    other_ranking = metric_ranking(agent_run)[0] if agent_run is not None else None
    # the calibration (coverage rows, held-out predictions) is the one `evaluate` uses: the
    # board's own metrics only; metrics joined from `--scores` are ranked, not calibrated on
    scored_names = {m for s in res.provenance.get("scores", []) for m in s.get("metrics", [])}
    own_rows = [r for r in res.metric_rows if r["metric"] not in scored_names]
    checks, heldout = check_results(own_rows, res.rl_rows, encoder_families(res), ranking,
                                    longer=longer_rows, longer_ranking=longer_ranking,
                                    other_agent=other_rows, other_ranking=other_ranking)
    scored: dict[str, pd.DataFrame] = {}  # check name -> scored table
    have_rl = {(r["task"], r["agent"], r["encoder"]) for r in res.rl_rows}
    for pred in predictions:  # scored once any predicted encoder has RL rows
        if any((t, a, e) in have_rl for t, a, e in zip(pred["task"], pred["agent"],
                                                        pred["encoder"], strict=True)):
            check, table = score_predictions(pred, res.rl_rows)
            scored[check.check] = table
            checks.append(check)
    checks += [ceiling_check(task, agent, out)
               for (task, agent), out in ceilings(res.rl_rows, _families(res)).items()
               if math.isfinite(out["r1_ci_low"])]
    table = robustness_table(checks)
    res.robustness = {"checks": table, "heldout": heldout, "longer_rl": list(longer_rows),
                      "other_agent_rl": list(other_rows), "predictions": scored}
    return table


def write_leaderboards(res: Results, out_dir: Path, longer: Results | None = None,
                       agent_run: Results | None = None,
                       predictions: Sequence[pd.DataFrame] = (),
                       copy_records: bool = True) -> Path:
    """Write ``encoders.csv``, ``metrics.csv``, ``claims.csv``, ``robustness.csv``,
    ``provenance.json``, figures,
    ``index.html`` and the records they were computed from (``records/``; with
    ``copy_records=False`` they stay where they are and ``provenance.json`` names their folders).

    ``longer`` (the same task × agent at a longer budget) adds the budget rows to
    ``robustness.csv``, ``agent_run`` (another agent at this budget) the agent-agreement rows;
    their records stay where they are (their folders go in the provenance); ``predictions``
    (pre-registered cross-task predictions) are scored in ``robustness.csv``.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    with board_lock(out_dir):
        return _write_leaderboards(res, out_dir, longer, agent_run, predictions, copy_records)


@contextlib.contextmanager
def board_lock(out_dir: Path) -> Iterator[None]:
    """Hold an exclusive lock on the leaderboard folder ``out_dir`` (``flock`` on its
    :data:`BOARD_LOCK` file): two writes of one board run one after the other instead of
    interleaving their records, figures and temporary files. The kernel drops the lock with a
    process that dies."""
    try:
        import fcntl
    except ImportError:  # no flock (Windows): unguarded, as before
        yield
        return
    fd = os.open(out_dir / BOARD_LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


def _write_leaderboards(res: Results, out_dir: Path, longer: Results | None,
                        agent_run: Results | None, predictions: Sequence[pd.DataFrame],
                        copy_records: bool) -> Path:
    from repbench.report.figures import make_figures
    from repbench.report.report_html import render_html

    enc = encoder_table(res)
    met = metric_table(res)
    ranking, res.loo_predictions = metric_ranking(res)
    if not ranking.empty and not met.empty:  # metrics.csv: the ranking's columns, its order
        met = ranking.merge(met, on=["task", "agent", "metric"], how="left")
        enc = add_loo_predicted_return(enc, ranking, res.loo_predictions)
    claims = paper_claims(res, ranking)
    robustness = robustness_checks(res, ranking, longer, agent_run, predictions)
    enc.to_csv(out_dir / "encoders.csv", index=False, float_format="%.6g")
    met.to_csv(out_dir / "metrics.csv", index=False, float_format="%.6g")
    claims.to_csv(out_dir / "claims.csv", index=False, float_format="%.6g")
    robustness.to_csv(out_dir / "robustness.csv", index=False, float_format="%.6g")
    if copy_records:
        write_records(res.records, out_dir / "records")
    with open(out_dir / "provenance.json", "w") as f:
        json.dump(res.provenance, f, indent=1, default=str)
    kept = {p.resolve() for p in res.figures_from_store.values()}  # a rebuild's own copies
    for stale in (out_dir / "figures").glob("*.*"):  # figures of an earlier write
        if stale.suffix in (".png", ".svg") and stale.resolve() not in kept:
            stale.unlink()
    figures = make_figures(res, met, out_dir / "figures")
    written = {p.resolve() for p in figures.values()}
    for source in kept - written:  # a one-task name, now copied under its "<enc>_<task>" name
        if source.parent == (out_dir / "figures").resolve():
            source.unlink(missing_ok=True)
    (out_dir / "index.html").write_text(render_html(res, enc, met, figures, claims),
                                        encoding="utf-8")
    return out_dir
