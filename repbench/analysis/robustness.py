"""Does the answer hold? Out of sample, for a second agent, at a longer budget.

Every check is a :class:`Check` (one row of ``robustness.csv``) whose verdict rule is fixed here,
before the data it judges, as :mod:`repbench.analysis.claims` does for the paper's claims:

* **Out-of-sample calibration** (:func:`calibration_checks`). Leave one *family* out
  (:func:`repbench.report.families.display_family`: the paper's VAEs, the low-KL twins, the
  ablations, contrastive, supervised, the baselines): the predictor of
  :mod:`repbench.analysis.calibration` is fitted on the other families — the metric choice
  inside the fold — and its interval is computed from those families alone (nested: the
  held-out family never sets its own width). Coverage = the share of held-out encoders whose
  actual mean return over seeds lies inside the interval, with its Clopper–Pearson 95 %
  interval. Verdict: **does not hold** if the one-sided exact binomial test of coverage < the
  nominal coverage gives p < 0.05; otherwise **holds** when the median half-width is at most
  :data:`MAX_HALF_WIDTH` (± 150 return, against a median standard error of a 3-seed mean of ~46)
  and **holds, too wide** when it is not. The method used by ``evaluate`` and the page is the
  first of :data:`repbench.analysis.calibration.CANDIDATES` (a fixed preference order) that
  holds, else the first that holds too wide, else the primary one with a warning
  (:func:`choose_method`).
* **Agreement of two rankings of the encoders** (:func:`ranking_agreement`): SAC vs DDPG
  (Spearman ρ of per-encoder mean returns, :data:`AGENT_THRESHOLD`) and 10k vs 30k steps
  (Kendall τ, :data:`BUDGET_THRESHOLD`). The interval is a percentile bootstrap that resamples
  encoders and, inside each drawn encoder, each side's seeds. **holds** if the interval's low
  end is above the threshold, **does not hold** if its high end is below it, **inconclusive**
  otherwise.
* **The same best metric** (:func:`best_metric_agreement`): the metric with the largest
  within-learned Spearman ρ under the first setting; under the second, **holds** if it is the
  best there too or its interval's high end reaches the second setting's best ρ (the two are
  not told apart) *and* its interval lies above 0 (it predicts there); **inconclusive** when
  it is the best or not told apart but its interval includes 0 (no metric is told apart, and
  the first's best is not shown to predict: until 2026-12-07 this read "holds" with that
  caveat in its detail, two statements at odds); **does not hold** otherwise.
* **Across tasks** (suites with several tasks): the encoder rankings of every pair of tasks
  (Kendall τ, :data:`TASK_THRESHOLD`: do the tasks rank the encoders alike at all?) and the
  first task's best metric on each other task (the rule above). The
  pre-registered predictions of a new task from the first task's calibration are scored in
  :mod:`repbench.analysis.transfer`.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from repbench.analysis.calibration import (
    CANDIDATES,
    DEFAULT_METHOD,
    LEGACY,
    MIN_FAMILIES,
    MIN_FIT,
    MIN_REFERENCE,
    Method,
    fit,
    half_width,
    held_out_errors,
)

__all__ = ["AGENT_THRESHOLD", "BUDGET_THRESHOLD", "MAX_HALF_WIDTH", "TASK_THRESHOLD", "Check",
           "best_metric_agreement", "calibration_checks", "choose_method", "coverage_verdict",
           "heldout_predictions", "ranking_agreement", "returns_by_encoder", "robustness_table",
           "same_trainings", "trainings_of_detail"]

ALPHA = 0.05
#: An interval wider than ± this (return units) is not an answer, whatever it covers.
MAX_HALF_WIDTH = 150.0
#: SAC and DDPG rank the encoders alike when Spearman ρ's interval lies above this.
AGENT_THRESHOLD = 0.5
#: The 10k ranking is the longer budget's when Kendall τ's interval lies above this.
BUDGET_THRESHOLD = 0.4
#: Two tasks rank the encoders alike (at all) when Kendall τ's interval lies above this.
TASK_THRESHOLD = 0.0
HOLDS, TOO_WIDE, FAILS, INCONCLUSIVE = "holds", "holds, too wide", "does not hold", \
    "inconclusive"


@dataclass(frozen=True)
class Check:
    """One row of ``robustness.csv``."""

    check: str
    statistic: str
    value: float
    ci_low: float
    ci_high: float
    verdict: str
    detail: str = ""


def coverage_verdict(covered: int, n: int, nominal: float, median_half_width: float) -> str:
    """The calibration verdict rule of the module docstring."""
    if n == 0:
        return INCONCLUSIVE
    p = stats.binomtest(covered, n, nominal, alternative="less").pvalue
    if p < ALPHA:
        return FAILS
    return HOLDS if median_half_width <= MAX_HALF_WIDTH else TOO_WIDE


def heldout_predictions(x: Mapping[str, np.ndarray], y: np.ndarray, families: Sequence[str],
                        method: Method) -> pd.DataFrame:
    """Each encoder predicted by the fit on the *other* families, with the half-width computed
    from those families alone (columns ``family, predicted, half_width, predictor``; NaN where
    the rest cannot be fitted)."""
    fam = np.asarray(list(families), object)
    out = pd.DataFrame({"family": fam, "predicted": np.nan, "half_width": np.nan,
                        "predictor": ""})
    for g in dict.fromkeys(fam.tolist()):
        held = fam == g
        keep = ~held
        if keep.sum() < MIN_FIT or np.unique(fam[keep]).size < 2:
            continue
        xk = {m: v[keep] for m, v in x.items()}
        f = fit(xk, y[keep], method)
        if f is None:
            continue
        # the interval of the fold: errors of the rest's own families held out in turn (LEGACY:
        # of each of the rest's encoders), never of the family being predicted
        inner = held_out_errors(xk, y[keep], fam[keep].tolist(), method)
        out.loc[held, "predicted"] = f.predict({m: v[held] for m, v in x.items()})
        out.loc[held, "half_width"] = half_width(inner, method)
        out.loc[held, "predictor"] = " + ".join(f.metrics)
    return out


def _nominal(method: Method, n_fold: float) -> float:
    """The coverage a method claims. :data:`LEGACY` (± the largest of n leave-one-out errors)
    is read as the n-th smallest of n errors, i.e. the conformal level n / (n + 1)."""
    return method.coverage if method.coverage is not None else n_fold / (n_fold + 1.0)


def calibration_checks(values: Mapping[str, Mapping[str, float]],
                       returns: Mapping[str, Sequence[float]], families: Mapping[str, str],
                       learned: Sequence[str] = (), *, task: str = "", agent: str = "",
                       methods: Sequence[Method] = (*CANDIDATES, LEGACY)
                       ) -> tuple[list[Check], pd.DataFrame]:
    """Leave-one-family-out coverage of every method (one :class:`Check` each) and the
    per-encoder held-out predictions behind them.

    Args:
        values: encoder → metric → value (the reference encoders' metrics).
        returns: encoder → evaluation returns over seeds.
        families: encoder → display family (the folds).
        learned: the learned encoders (for the within-learned Spearman in the detail).
    """
    metrics = sorted({m for v in values.values() for m in v})
    encs = sorted(e for e in returns if e in values and len(returns[e])
                  and all(np.isfinite(values[e].get(m, np.nan)) for m in metrics))
    # keep the metrics every encoder has, so no encoder is dropped for one missing metric
    metrics = [m for m in metrics if all(np.isfinite(values[e].get(m, np.nan)) for e in encs)]
    if len(encs) < MIN_REFERENCE + 1 or not metrics:  # a nested fold needs 3 + 1 + 1
        return [], pd.DataFrame()
    y = np.array([float(np.mean(returns[e])) for e in encs])
    se = np.array([float(np.std(returns[e], ddof=1) / math.sqrt(len(returns[e])))
                   if len(returns[e]) > 1 else np.nan for e in encs])
    x = {m: np.array([values[e][m] for e in encs], float) for m in metrics}
    fam = [families.get(e, e) for e in encs]
    unit = "families"
    if len(set(fam)) < MIN_FAMILIES:  # as calibration.predict_return does: encoders as folds
        fam, unit = list(encs), "encoders (too few families to hold one out)"
    checks, frames = [], []
    where = " ".join(s for s in (task, agent) if s)
    for method in methods:
        pred = heldout_predictions(x, y, fam, method)
        pred.insert(0, "encoder", encs)
        pred["actual"], pred["se"] = y, se
        pred["method"] = method.name
        ok = pred["predicted"].notna() & np.isfinite(pred["half_width"].astype(float))
        p = pred[ok]
        covered = int((np.abs(p["predicted"] - p["actual"]) <= p["half_width"]).sum())
        n = int(ok.sum())
        pred["covered"] = np.where(ok, np.abs(pred["predicted"] - pred["actual"])
                                   <= pred["half_width"], np.nan)
        frames.append(pred)
        n_fold = float(np.mean([np.sum(np.asarray(fam) != g) for g in fam]))
        nominal = _nominal(method, n_fold)
        if n == 0:
            continue
        ci = stats.binomtest(covered, n).proportion_ci(method="exact")
        width = float(np.median(p["half_width"]))
        rmse = float(np.sqrt(np.mean((p["predicted"] - p["actual"]) ** 2)))
        lp = p[p["encoder"].isin(learned)]
        rho = (float(stats.spearmanr(lp["predicted"], lp["actual"]).statistic)
               if len(lp) >= 3 and lp["predicted"].nunique() > 1 else float("nan"))
        se_median = (float(np.median(se[np.isfinite(se)])) if np.isfinite(se).any()
                     else float("nan"))  # one seed per encoder: no standard error
        detail = (f"{method.description}; nominal {nominal:.0%}; {covered}/{n} covered over "
                  f"{len(set(fam))} held-out {unit}; median half-width ±{width:.0f}; "
                  f"held-out RMSE {rmse:.0f} vs median SE of a mean {se_median:.0f}; "
                  f"Spearman predicted vs actual within the learned encoders {rho:.2f}")
        checks.append(Check(f"out-of-sample coverage ({method.name}){' ' + where if where else ''}",
                            "coverage of held-out families", covered / n, float(ci.low),
                            float(ci.high), coverage_verdict(covered, n, nominal, width), detail))
    return checks, pd.concat(frames, ignore_index=True)


def choose_method(checks: Sequence[Check]) -> tuple[Method, str | None]:
    """The method ``evaluate`` uses (rule of the module docstring) and a warning, if any."""
    verdicts = {c.check.split("(")[1].split(")")[0]: c.verdict for c in checks
                if c.check.startswith("out-of-sample coverage (")}
    for wanted in (HOLDS, TOO_WIDE):
        for m in CANDIDATES:
            if verdicts.get(m.name) == wanted:
                return m, (None if wanted == HOLDS else
                           f"{m.name}: coverage holds but its median interval is wider than "
                           f"±{MAX_HALF_WIDTH:.0f}")
    return DEFAULT_METHOD, (f"no calibration method's coverage held out of sample; "
                            f"{DEFAULT_METHOD.name} is used and its interval is optimistic")


def _bootstrap_agreement(a: Sequence[np.ndarray], b: Sequence[np.ndarray], kind: str,
                         rng: np.random.Generator, n_bootstrap: int) -> np.ndarray:
    """The statistic over resamples of encoders and, inside each, of each side's seeds."""
    n = len(a)
    out = []
    for _ in range(n_bootstrap):
        idx = rng.integers(0, n, n)
        if np.unique(idx).size < 3:
            continue
        ma = [rng.choice(a[i], a[i].size).mean() for i in idx]
        mb = [rng.choice(b[i], b[i].size).mean() for i in idx]
        out.append(_statistic(np.array(ma), np.array(mb), kind))
    boot = np.array(out)
    return boot[np.isfinite(boot)]


def _statistic(x: np.ndarray, y: np.ndarray, kind: str) -> float:
    if np.ptp(x) == 0 or np.ptp(y) == 0:
        return float("nan")
    if kind == "kendall":
        return float(stats.kendalltau(x, y).statistic)
    return float(stats.spearmanr(x, y).statistic)


def ranking_agreement(a: Mapping[str, Sequence[float]], b: Mapping[str, Sequence[float]], *,
                      check: str, kind: str, threshold: float, n_bootstrap: int = 2000,
                      seed: int = 0) -> Check:
    """Do two settings rank the encoders alike? ``a``, ``b``: encoder → returns over seeds;
    ``kind``: ``"spearman"`` or ``"kendall"``; the rule of the module docstring."""
    if kind not in ("spearman", "kendall"):
        raise ValueError(f"ranking_agreement: kind must be 'spearman' or 'kendall', not {kind!r}")
    encs = sorted(e for e in a if e in b and len(a[e]) and len(b[e]))
    name = "Spearman ρ" if kind == "spearman" else "Kendall τ"
    nan = float("nan")
    if len(encs) < 4:
        return Check(check, f"{name} of per-encoder mean returns", nan, nan, nan, INCONCLUSIVE,
                     f"{len(encs)} encoders in both (at least 4 needed)")
    xa = [np.asarray(a[e], float) for e in encs]
    xb = [np.asarray(b[e], float) for e in encs]
    value = _statistic(np.array([v.mean() for v in xa]), np.array([v.mean() for v in xb]), kind)
    boot = _bootstrap_agreement(xa, xb, kind, np.random.default_rng(seed), n_bootstrap)
    lo, hi = (np.quantile(boot, [0.025, 0.975]) if boot.size >= 10 else (nan, nan))
    if not (np.isfinite(lo) and np.isfinite(hi)):
        verdict = INCONCLUSIVE
    elif lo > threshold:
        verdict = HOLDS
    elif hi < threshold:
        verdict = FAILS
    else:
        verdict = INCONCLUSIVE
    return Check(check, f"{name} of per-encoder mean returns", value, float(lo), float(hi),
                 verdict, f"{len(encs)} encoders; holds if the 95 % interval is above "
                 f"{threshold:g}, fails if below")


def best_metric_agreement(first: pd.DataFrame, second: pd.DataFrame, *, check: str,
                          first_label: str, second_label: str) -> Check:
    """Is the best metric of ``first`` (a metric leaderboard: metric, spearman_learned,
    spearman_learned_ci_low/high) also the best of ``second``? The rule of the module
    docstring; the value is the first's best metric's ρ under the second."""
    nan = float("nan")
    a = first.dropna(subset=["spearman_learned"])
    b = second.dropna(subset=["spearman_learned"])
    if a.empty or b.empty:
        return Check(check, "within-learned Spearman ρ of the best metric", nan, nan, nan,
                     INCONCLUSIVE, "a metric leaderboard is empty")
    best_a = a.loc[a["spearman_learned"].idxmax()]
    best_b = b.loc[b["spearman_learned"].idxmax()]
    row = b[b["metric"] == best_a["metric"]]
    if row.empty:
        return Check(check, "within-learned Spearman ρ of the best metric", nan, nan, nan,
                     INCONCLUSIVE, f"{best_a['metric']} is not scored under {second_label}")
    r = row.iloc[0]
    same = best_a["metric"] == best_b["metric"]
    holds = same or float(r["spearman_learned_ci_high"]) >= float(best_b["spearman_learned"])
    detail = (f"best under {first_label}: {best_a['metric']} (ρ {best_a['spearman_learned']:.2f}); "
              f"best under {second_label}: {best_b['metric']} (ρ "
              f"{best_b['spearman_learned']:.2f}); {best_a['metric']} under {second_label}: "
              f"ρ {r['spearman_learned']:.2f}")
    verdict = HOLDS if holds else FAILS
    if holds and float(r["spearman_learned_ci_low"]) <= 0:
        verdict = INCONCLUSIVE  # "holds" beside "not evidence it predicts" said two things
        why = "the best there too" if same else "not told apart from the best there"
        detail += (f"; {why}, but not shown to predict return under {second_label}: its "
                   f"interval [{r['spearman_learned_ci_low']:.2f}, "
                   f"{r['spearman_learned_ci_high']:.2f}] includes 0")
    return Check(check, f"within-learned Spearman ρ of {best_a['metric']} under {second_label}",
                 float(r["spearman_learned"]), float(r["spearman_learned_ci_low"]),
                 float(r["spearman_learned_ci_high"]), verdict, detail)


def same_trainings(base_rows: Sequence[Mapping[str, Any]],
                   other_rows: Sequence[Mapping[str, Any]], task: str,
                   agent: str = "sac") -> str | None:
    """Whether the RL runs ``other_rows`` make of ``task``'s encoders (a separate run: another
    agent, a longer budget) used the very weights the board's ``agent`` runs in ``base_rows``
    used (their ``encoder_weights``), as one clause for a check's detail; None when every
    encoder's did, or when no record of either names its weights (boards made before records
    did). A retrained encoder is a different encoder, so an agreement row over runs of
    other trainings measures retraining too, and should say so."""
    base: dict[str, set[Any]] = {}
    other: dict[str, set[Any]] = {}
    for rows, into in ((base_rows, base), (other_rows, other)):
        for r in rows:
            if r["task"] == task and (into is other or r["agent"] == agent):
                into.setdefault(str(r["encoder"]), set()).add(r.get("encoder_weights"))
    same = differ = unknown = 0
    for enc, weights in other.items():
        mine = base.get(enc, set())
        if None in weights or None in mine or not mine:
            unknown += 1
        elif weights == mine and len(mine) == 1:
            same += 1
        else:
            differ += 1
    recorded = any(w is not None for ws in (*base.values(), *other.values()) for w in ws)
    if not other or same == len(other) or not recorded:  # all the same, or nothing to tell
        return None
    parts = [f"{n} {what}" for n, what in ((differ, "of another training"),
                                           (unknown, "of a training not recorded"))
             if n]
    return (f"{_TRAININGS_SAID}{same} of {len(other)} encoders "
            f"({', '.join(parts)}: retraining moves returns too)")


_TRAININGS_SAID = "its runs are of the board's trained encoders for "


def trainings_of_detail(detail: Any) -> str:
    """The share :func:`same_trainings` put in a check's detail ("0 of 10 encoders"), or ``""``
    when the other run's encoders are the board's (or nothing was recorded)."""
    _, sep, tail = str(detail).partition(_TRAININGS_SAID)
    return tail.split(" (", 1)[0] if sep else ""


def task_checks(rl_rows: Sequence[Mapping[str, Any]], ranking: pd.DataFrame | None
                ) -> list[Check]:
    """The across-tasks rows, per agent: the encoder ranking (Kendall τ) of every pair of tasks,
    and the first task's (in ``rl_rows``' order) best metric on each other task."""
    out: list[Check] = []
    tasks = rl_tasks(rl_rows)
    if not tasks:
        return out
    first = tasks[0]
    for agent in dict.fromkeys(r["agent"] for r in rl_rows):
        returns = {t: returns_by_encoder(rl_rows, t, agent) for t in tasks}
        for a, b in itertools.combinations(tasks, 2):
            if returns[a] and returns[b]:
                out.append(ranking_agreement(
                    returns[a], returns[b], check=f"{agent.upper()} ranking {a} vs {b}",
                    kind="kendall", threshold=TASK_THRESHOLD))
        if ranking is None or not returns[first]:
            continue
        for other in tasks[1:]:
            if returns[other]:
                out.append(best_metric_agreement(
                    _board(ranking, first, agent), _board(ranking, other, agent),
                    check=f"{first}'s best metric on {other} ({agent.upper()})", first_label=first,
                    second_label=other))
    return out


def rl_tasks(rl_rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The tasks with RL rows, in the rows' (the suite's) order."""
    return list(dict.fromkeys(r["task"] for r in rl_rows))


def robustness_table(checks: Sequence[Check]) -> pd.DataFrame:
    """``robustness.csv``'s rows."""
    cols = [f for f in Check.__dataclass_fields__]
    return pd.DataFrame([asdict(c) for c in checks], columns=cols)


def returns_by_encoder(rl_rows: Sequence[Mapping[str, Any]], task: str, agent: str,
                       train_steps: int | None = None) -> dict[str, list[float]]:
    """encoder → its RL returns over seeds for ``task`` × ``agent`` (at ``train_steps``)."""
    out: dict[str, list[float]] = {}
    for r in rl_rows:
        if r["task"] == task and r["agent"] == agent and (
                train_steps is None or r.get("train_steps") == train_steps):
            out.setdefault(r["encoder"], []).append(float(r["eval_return"]))
    return out


def budget_check_name(agent: str, short: int, long: int, task: str) -> str:
    """The name of the 10k-vs-longer ranking check in ``robustness.csv``."""
    return f"{agent.upper()} {steps_label(short)} vs {steps_label(long)} ranking {task}"


_BUDGETS_SAID = re.compile(r"^(\w+ at [\w/]+ steps(?:, \w+ at [\w/]+ steps)+); ")


def budgets_said(budgets: Mapping[str, Sequence[int]]) -> str:
    """``"SAC at 10k steps, DDPG at 50k steps"``: the budgets an agreement check compares when
    they differ, the start of its detail (read back by :func:`budgets_of_detail`)."""
    return ", ".join(f"{a.upper()} at {'/'.join(map(steps_label, b))} steps"
                     for a, b in budgets.items())


def budgets_of_detail(detail: Any) -> str:
    """The :func:`budgets_said` a check's detail starts with, or ``""``."""
    match = _BUDGETS_SAID.match(str(detail))
    return match.group(1) if match else ""


def steps_label(steps: int) -> str:
    """30000 → "30k"; a budget that is not a whole thousand keeps its digits."""
    return f"{steps // 1000}k" if steps >= 1000 and steps % 1000 == 0 else str(steps)


def _learned(families: Mapping[str, str]) -> list[str]:
    return [e for e, f in families.items() if f != "baselines"]


def _board(ranking: pd.DataFrame, task: str, agent: str) -> pd.DataFrame:
    if ranking is None or ranking.empty:
        return pd.DataFrame(columns=["metric", "spearman_learned"])
    return ranking[(ranking["task"] == task) & (ranking["agent"] == agent)]


def check_results(metric_rows: Sequence[Mapping[str, Any]], rl_rows: Sequence[Mapping[str, Any]],
                  families: Mapping[str, str], ranking: pd.DataFrame | None = None, *,
                  longer: Sequence[Mapping[str, Any]] = (),
                  longer_ranking: pd.DataFrame | None = None,
                  other_agent: Sequence[Mapping[str, Any]] = (),
                  other_ranking: pd.DataFrame | None = None
                  ) -> tuple[list[Check], pd.DataFrame]:
    """Every check the rows support, and the held-out predictions behind the calibration rows.

    Args:
        metric_rows, rl_rows: :class:`repbench.analysis.results.Results` rows.
        families: encoder → display family (the calibration's folds).
        ranking: the metric leaderboard of these rows (``metrics.csv``): the best-metric checks.
        longer: RL rows of the same task × agent at a longer budget (the 10k-vs-30k checks),
            with ``longer_ranking`` their metric leaderboard.
        other_agent: RL rows of another agent at the same budget (a separate run, e.g. DDPG
            beside SAC), with ``other_ranking`` their metric leaderboard: the agent-agreement
            checks, as if they were among ``rl_rows`` (no calibration rows of their own).
    """
    from repbench.analysis.calibration import reference_table

    checks: list[Check] = []
    frames: list[pd.DataFrame] = []
    pairs = sorted({(r["task"], r["agent"]) for r in rl_rows})
    for task, agent in pairs:
        values, runs = reference_table(metric_rows, rl_rows, task, agent)
        c, pred = calibration_checks(values, runs, families, _learned(families),
                                     task=task, agent=agent)
        checks += c
        if not pred.empty:
            frames.append(pred.assign(task=task, agent=agent))
    both_rows = [*rl_rows, *other_agent]
    if other_ranking is not None and not other_ranking.empty:
        ranking = other_ranking if ranking is None else pd.concat([ranking, other_ranking],
                                                                 ignore_index=True)
    both_pairs = {(r["task"], r["agent"]) for r in both_rows}
    for task in sorted({t for t, _ in pairs}):
        agents = {a for t, a in both_pairs if t == task}
        if {"sac", "ddpg"} <= agents:
            agreement = ranking_agreement(
                returns_by_encoder(both_rows, task, "sac"),
                returns_by_encoder(both_rows, task, "ddpg"),
                check=f"SAC vs DDPG ranking {task}", kind="spearman",
                threshold=AGENT_THRESHOLD)
            budgets = {a: sorted({int(r["train_steps"]) for r in both_rows
                                  if r["task"] == task and r["agent"] == a
                                  and r.get("train_steps") is not None})
                       for a in ("sac", "ddpg")}
            if budgets["sac"] != budgets["ddpg"]:  # each agent where it learns: say so
                agreement = replace(agreement,
                                    detail=f"{budgets_said(budgets)}; {agreement.detail}")
            trainings = same_trainings(rl_rows, [r for r in both_rows if r["agent"] == "ddpg"],
                                       task)
            pair = [agreement]
            if ranking is not None:
                pair.append(best_metric_agreement(
                    _board(ranking, task, "sac"), _board(ranking, task, "ddpg"),
                    check=f"SAC's best metric under DDPG {task}", first_label="SAC",
                    second_label="DDPG"))
            checks += [_say(c, trainings) for c in pair]
    for task, agent in sorted({(r["task"], r["agent"]) for r in longer}):
        steps = sorted({int(r["train_steps"]) for r in longer
                        if r["task"] == task and r["agent"] == agent})
        base = sorted({int(r["train_steps"]) for r in rl_rows
                       if r["task"] == task and r["agent"] == agent})
        if not base:
            continue
        short, long = steps_label(base[0]), steps_label(steps[-1])
        trainings = same_trainings(rl_rows, [r for r in longer if r["agent"] == agent], task,
                                   agent)
        pair = [ranking_agreement(
            returns_by_encoder(rl_rows, task, agent, base[0]),
            returns_by_encoder(longer, task, agent, steps[-1]),
            check=budget_check_name(agent, base[0], steps[-1], task), kind="kendall",
            threshold=BUDGET_THRESHOLD)]
        if ranking is not None and longer_ranking is not None:
            pair.append(best_metric_agreement(
                _board(ranking, task, agent), _board(longer_ranking, task, agent),
                check=f"{short} best metric at {long} {task} {agent}", first_label=short,
                second_label=long))
        checks += [_say(c, trainings) for c in pair]
    checks += task_checks(rl_rows, ranking)
    return checks, (pd.concat(frames, ignore_index=True) if frames else pd.DataFrame())


def _say(check: Check, clause: str | None) -> Check:
    """``check`` with ``clause`` appended to its detail (unchanged when None)."""
    return check if clause is None else replace(check, detail=f"{check.detail}; {clause}")


def validated_method(metric_rows: Sequence[Mapping[str, Any]],
                     rl_rows: Sequence[Mapping[str, Any]], families: Mapping[str, str],
                     task: str, agent: str) -> tuple[Method, Check | None, str | None, float]:
    """The calibration method ``evaluate`` uses for ``task`` × ``agent``
    (:func:`choose_method` on the reference rows): ``(method, its coverage check, a warning or
    None, the median held-out half-width)``."""
    from repbench.analysis.calibration import reference_table

    values, runs = reference_table(metric_rows, rl_rows, task, agent)
    checks, pred = calibration_checks(values, runs, families, _learned(families),
                                      methods=CANDIDATES)
    if not checks:
        return DEFAULT_METHOD, None, (
            f"the interval's coverage was not measured out of sample: the reference has "
            f"{len(runs)} encoders with RL results (at least {MIN_REFERENCE + 1} needed)"), \
            float("nan")
    method, warning = choose_method(checks)
    mine = next((c for c in checks if f"({method.name})" in c.check), None)
    width = (float(pred.loc[pred["method"] == method.name, "half_width"].median())
             if not pred.empty else float("nan"))
    return method, mine, warning, width
