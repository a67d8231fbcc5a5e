"""Leaderboards are pure functions of stored results: plan → artifacts → tables → CSV/HTML.

* ``encoders.csv`` — one row per task × encoder: every metric with its CI, and per agent the RL
  return (mean and t-interval over seeds) and success rate.
* ``metrics.csv`` — one row per task × agent × metric, ranked: the metric leaderboard
  (:func:`metric_ranking`: Spearman within the learned encoders and over all encoders with
  intervals and Holm/BH-adjusted p-values, leave-one-encoder-out error, cost in seconds), then
  Pearson, Spearman and Kendall over all encoders with bootstrap CIs and p-values — "which
  metric predicts RL performance".
* ``index.html`` — one self-contained page (see :mod:`repbench.report_html`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from repbench.correlation import METHODS, correlate, mean_ci
from repbench.plan import Plan
from repbench.stages import StageSpec
from repbench.store import Store


@dataclass
class Results:
    """Everything a leaderboard shows, gathered from the store."""

    suite: Any
    metric_rows: list[dict[str, Any]] = field(default_factory=list)
    rl_rows: list[dict[str, Any]] = field(default_factory=list)
    encoder_rows: list[dict[str, Any]] = field(default_factory=list)
    diagnostics: dict[str, Any] = field(default_factory=dict)  # task → diagnostics
    provenance: dict[str, Any] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)
    figures_from_store: dict[str, Path] = field(default_factory=dict)  # name → png path
    #: (task, agent, metric) → encoder → leave-one-encoder-out predicted return
    predictions: dict[tuple[str, str, str], dict[str, float]] = field(default_factory=dict)


def collect_results(plan: Plan, store: Store) -> Results:
    """Read every finished artifact of ``plan`` (absent ones are listed in ``missing``)."""
    res = Results(plan.suite)
    metas: list[dict[str, Any]] = []
    directions: dict[str, bool] = {}

    def fetch(spec: StageSpec) -> Any:
        """The stage's artifact (its metadata kept for provenance), or None, noted missing."""
        art = store.get(spec.kind, spec.key)
        if art is None:
            res.missing.append(spec.label)
        else:
            metas.append(art.meta)
        return art

    for tp in plan.tasks:
        for enc_name, spec in tp.encoders.items():
            if (art := fetch(spec)) is None:
                continue
            info = art.read_json()
            res.encoder_rows.append({"task": tp.task, "encoder": enc_name,
                                     "latent_dim": info.get("latent_dim"),
                                     "fit_time_s": info.get("fit_time_s"),
                                     "family": info.get("family") or _family(enc_name)})
            png = art.file("reconstructions.png")
            if png.is_file():
                res.figures_from_store[f"reconstructions {enc_name}"] = png
        for (enc_name, metric_name), spec in tp.metrics.items():
            if (art := fetch(spec)) is None:
                continue
            d = art.read_json()
            directions[metric_name] = bool(d["higher_is_better"])
            res.metric_rows.append({"task": tp.task, "encoder": enc_name, "metric": metric_name,
                                    **d})
        for (enc_name, agent, seed), spec in tp.rl.items():
            if (art := fetch(spec)) is None:
                continue
            res.rl_rows.append({"task": tp.task, "encoder": enc_name, "agent": agent,
                                "seed": seed, **art.read_json()})
        diag = store.get(tp.diagnostics.kind, tp.diagnostics.key)
        if diag is not None:
            res.diagnostics[tp.task] = diag.read_json()
        for spec in (tp.random_dataset, tp.on_policy_dataset, tp.heldout_dataset,
                     tp.full_state):
            if spec is not None:
                art = store.get(spec.kind, spec.key)
                if art is not None:
                    metas.append(art.meta)
                    res.provenance.setdefault("datasets", {})[spec.label] = {
                        k: v for k, v in art.read_json().items() if k != "metadata"}
    res.provenance.update(_provenance(plan, metas))
    res.provenance["directions"] = directions
    return res


def _provenance(plan: Plan, metas: list[dict[str, Any]]) -> dict[str, Any]:
    commits = sorted({m.get("git_commit") or "unknown" for m in metas})
    versions = metas[-1]["versions"] if metas else {}
    by_stage: dict[str, float] = {}
    for m in metas:
        by_stage[m["stage"]] = by_stage.get(m["stage"], 0.0) + float(m.get("wall_time_s", 0))
    created = sorted(m.get("created", "") for m in metas)
    s = plan.suite
    return {
        "suite": s.name, "suite_source": s.source, "description": s.description,
        "rl_seeds": list(s.seeds), "dataset": s.dataset.model_dump(),
        "encoder_training": s.encoder_training.model_dump(), "rl": s.rl.model_dump(),
        "git_commits": commits, "versions": versions,
        "compute_seconds_by_stage": {k: round(v, 1) for k, v in sorted(by_stage.items())},
        "first_result": created[0] if created else None,
        "last_result": created[-1] if created else None,
    }


def _family(encoder: str) -> str:
    """An encoder's family from its class (records written before families were stored)."""
    from repbench.registry import encoders

    try:
        return str(getattr(encoders.get(encoder), "family", "learned"))
    except Exception:  # unknown or unimportable plugin: count it as learned
        return "learned"


def metric_ranking(res: Results, n_bootstrap: int = 1000, seed: int = 0
                   ) -> tuple[pd.DataFrame, dict[tuple[str, str, str], dict[str, float]]]:
    """The metric leaderboard (:func:`repbench.correlation.metric_leaderboard`) as a table,
    ranked per task × agent by the within-learned-encoders Spearman ρ, then the all-encoder ρ;
    and the leave-one-encoder-out predicted returns per (task, agent, metric)."""
    from repbench.correlation import metric_leaderboard

    families = {r["encoder"]: r.get("family") or _family(r["encoder"])
                for r in res.encoder_rows}
    for r in res.metric_rows:
        families.setdefault(r["encoder"], _family(r["encoder"]))
    rows, preds = metric_leaderboard(res.metric_rows, res.rl_rows, families,
                                     res.provenance.get("directions", {}),
                                     n_bootstrap=n_bootstrap, seed=seed)
    df = pd.DataFrame(rows)
    if not df.empty:
        df = df.sort_values(["task", "agent", "spearman_learned", "spearman_all"],
                            ascending=[True, True, False, False],
                            na_position="last").reset_index(drop=True)
    return df, preds


def add_predicted_return(enc: pd.DataFrame, ranking: pd.DataFrame,
                         predictions: dict[tuple[str, str, str], dict[str, float]]
                         ) -> pd.DataFrame:
    """Add ``<agent>_predicted_return`` (and ``<agent>_predicted_by``) to the encoder table:
    each encoder's return predicted, leave-one-encoder-out, by the metric with the lowest
    LOO error for that task and agent."""
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
        enc.loc[mask, f"{agent}_predicted_return"] = enc.loc[mask, "encoder"].map(pred)
        enc.loc[mask, f"{agent}_predicted_by"] = best
    return enc


def encoder_table(res: Results) -> pd.DataFrame:
    """One row per task × encoder (see module docstring)."""
    rows: dict[tuple[str, str], dict[str, Any]] = {}
    for r in res.encoder_rows:
        rows[(r["task"], r["encoder"])] = {"task": r["task"], "encoder": r["encoder"],
                                           "latent_dim": r["latent_dim"]}
    for r in res.metric_rows:
        row = rows.setdefault((r["task"], r["encoder"]), {"task": r["task"],
                                                          "encoder": r["encoder"]})
        row[r["metric"]] = r["value"]
        row[f"{r['metric']}_ci_low"] = r.get("ci_low")
        row[f"{r['metric']}_ci_high"] = r.get("ci_high")
    by: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for r in res.rl_rows:
        by.setdefault((r["task"], r["encoder"], r["agent"]), []).append(r)
    for (task, enc, agent), runs in sorted(by.items()):
        row = rows.setdefault((task, enc), {"task": task, "encoder": enc})
        mean, lo, hi = mean_ci([x["eval_return"] for x in runs])
        row[f"{agent}_return"], row[f"{agent}_return_ci_low"], row[f"{agent}_return_ci_high"] = (
            mean, lo, hi)
        row[f"{agent}_success"] = float(np.mean([x["eval_success_rate"] for x in runs]))
        row[f"{agent}_seeds"] = len(runs)
    df = pd.DataFrame(list(rows.values()))
    if df.empty:
        return df
    sort_col = next((c for c in df.columns if c.endswith("_return")), None)
    if sort_col:
        df = df.sort_values(["task", sort_col], ascending=[True, False], na_position="last")
    return df.reset_index(drop=True)


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


def write_leaderboards(res: Results, out_dir: Path) -> Path:
    """Write ``encoders.csv``, ``metrics.csv``, ``results.json``, figures and ``index.html``."""
    from repbench.figures import make_figures
    from repbench.report_html import render_html

    out_dir.mkdir(parents=True, exist_ok=True)
    enc = encoder_table(res)
    met = metric_table(res)
    ranking, predictions = metric_ranking(res)
    if not ranking.empty and not met.empty:  # metrics.csv: the ranking's columns, its order
        met = ranking.merge(met, on=["task", "agent", "metric"], how="left")
        enc = add_predicted_return(enc, ranking, predictions)
    res.predictions = predictions
    enc.to_csv(out_dir / "encoders.csv", index=False, float_format="%.6g")
    met.to_csv(out_dir / "metrics.csv", index=False, float_format="%.6g")
    with open(out_dir / "provenance.json", "w") as f:
        json.dump(res.provenance, f, indent=1, default=str)
    for stale in (out_dir / "figures").glob("*.png"):  # figures of an earlier write
        stale.unlink()
    figures = make_figures(res, met, out_dir / "figures")
    (out_dir / "index.html").write_text(render_html(res, enc, met, figures), encoding="utf-8")
    return out_dir
