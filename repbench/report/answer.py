"""The answer panel at the top of the leaderboard page: per task × agent, which metric predicts
RL return best and whether the paper's metrics do, then the pre-registered transfers and the
robustness verdicts, the central figure and a compact encoder × task return matrix.

Every number comes from the tables the page shows in full further down (``claims.csv``,
``robustness.csv``, ``encoders.csv``); nothing here computes a statistic of its own.
"""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Any

import pandas as pd

from repbench.analysis.robustness import budgets_of_detail, trainings_of_detail
from repbench.report.html_parts import VERDICT_COLORS as _VERDICT_COLORS
from repbench.report.html_parts import figure as _figure
from repbench.report.html_parts import fmt as _fmt
from repbench.report.html_parts import fmt2 as _fmt2

#: The central figure, shown in the panel (and not again among the figures).
CENTRAL_FIGURE = "Which metric predicts return, task by task"
BEST_LEARNED = "Which metric predicts return best (learned encoders)?"
#: The paper's own metrics: (short name, the claim of :mod:`repbench.analysis.claims`).
PAPER_METRICS = (
    ("mine", "MI between latent and true state (mine) correlates positively with return"),
    ("ksg", "MI between latent and true state (ksg) correlates positively with return"),
    ("regression", "Regression error latent → true state correlates negatively with return"),
)
COVERAGE_PREFIX = "out-of-sample coverage"


def best_metric_name(statistic: str) -> str:
    """The metric a best-metric claim names (``"highest ...: task_cmi"`` → ``task_cmi``)."""
    return statistic.rsplit(": ", 1)[-1].strip()


def _estimate(r: Any, fmt: Any) -> str:
    return (f"{fmt(r['value'])} <span class='ci'>[{fmt(r['ci_low'])}, "
            f"{fmt(r['ci_high'])}]</span>")


def _verdict(verdict: Any, colors: dict[str, str]) -> str:
    v = str(verdict)
    return f"<b style='background:{colors.get(v, '')};padding:0 4px'>{html.escape(v)}</b>"


def ceiling_rows(checks: pd.DataFrame | None) -> dict[tuple[str, str], dict[str, Any]]:
    """(task, agent) → the noise-ceiling row of ``robustness.csv``
    (:func:`repbench.analysis.noise_ceiling.ceiling_check`)."""
    if checks is None or checks.empty:
        return {}
    out = {}
    for r in checks.to_dict("records"):
        name = str(r["check"])
        if " returns rank the encoders reliably " in name:
            agent, task = name.split(" returns rank the encoders reliably ")
            out[(task, agent.lower())] = r
    return out


def _ceiling_cell(best: Any, ceiling: Any, fmt: Any) -> str:
    """The noise ceiling [95 %] and, below it, the share of it the best metric reaches."""
    if ceiling is None:
        return "<td>–</td>"
    share = float(best["value"]) / float(ceiling["value"]) if ceiling["value"] else math.nan
    said = f"<br><span class='ci'>best metric: {share:.0%} of it</span>" \
        if math.isfinite(share) else ""
    return (f"<td title='{html.escape(str(ceiling['detail']))}' data-v='{ceiling['value']}'>"
            f"{_estimate(ceiling, fmt)}{said}</td>")


def _metric_rows(claims: pd.DataFrame, fmt: Any, colors: dict[str, str],
                 ceilings: dict[tuple[str, str], dict[str, Any]] | None = None) -> list[str]:
    """One row per task × agent: the best metric over the learned encoders (ρ [95 %],
    verdict), the noise ceiling and the share of it the best metric reaches, then each of
    the paper's metrics (ρ [95 %], verdict)."""
    ceilings = ceilings or {}
    rows = []
    for (task, agent), group in claims.groupby(["task", "agent"], sort=False):
        by_claim = {c: r for c, r in zip(group["claim"], group.to_dict("records"),
                                         strict=True)}
        best = by_claim.get(BEST_LEARNED)
        if best is None:
            continue
        metric = best_metric_name(str(best["statistic"]))
        cells = [f"<td class='txt'>{html.escape(str(task))}</td>",
                 f"<td class='txt'>{html.escape(str(agent))}</td>",
                 f"<td class='txt'><b>{html.escape(metric)}</b></td>",
                 f"<td data-v='{best['value']}'>{_estimate(best, fmt)}</td>",
                 f"<td class='txt'>{_verdict(best['verdict'], colors)}</td>",
                 _ceiling_cell(best, ceilings.get((str(task), str(agent))), fmt)]
        for _, claim in PAPER_METRICS:
            r = by_claim.get(claim)
            cells.append("<td>–</td>" if r is None else
                         f"<td class='txt'>{_estimate(r, fmt)}<br>"
                         f"{_verdict(r['verdict'], colors)}</td>")
        rows.append(f"<tr data-task='{html.escape(str(task))}' data-agent="
                    f"'{html.escape(str(agent))}' data-metric='{html.escape(metric)}'>"
                    + "".join(cells) + "</tr>")
    return rows


def _caveat(detail: Any) -> str:
    """Why a same-best-metric check is inconclusive, where its detail says it (the best metric,
    or one not told apart from it, whose interval includes 0:
    ``"...; <what it is>, but not shown to predict return under <setting>: <why>"``)."""
    head, sep, _ = str(detail).partition(", but not shown to predict")
    if not sep:
        return ""
    said = head.rsplit("; ", 1)[-1]
    return f"<br><span class='ci'>{html.escape(said)}, but not shown to predict</span>"


def _budgets(detail: Any) -> str:
    """The budgets a check compares, under its name, where they differ (each agent where it
    learns: "SAC at 10k steps, DDPG at 50k steps")."""
    said = budgets_of_detail(detail)
    return f"<br><span class='ci'>{html.escape(said)}</span>" if said else ""


def _trainings(detail: Any) -> str:
    """Under a check's name, where the other run's RL used other trainings of the encoders than
    the board's (:func:`repbench.analysis.robustness.same_trainings`)."""
    said = trainings_of_detail(detail)
    return (f"<br><span class='ci'>its RL used the board's trained encoders for {html.escape(said)}"
            "</span>") if said else ""


def _checks_table(checks: pd.DataFrame, fmt: Any, colors: dict[str, str]) -> list[str]:
    """The robustness checks other than coverage (transfers, agreements), one row each, and
    one line for the coverage checks."""
    is_cov = checks["check"].astype(str).str.startswith(COVERAGE_PREFIX)
    out = []
    cov = checks[is_cov]
    if not cov.empty:
        counts = cov["verdict"].astype(str).value_counts()
        said = ", ".join(f"{n} {html.escape(v)}" for v, n in counts.items())
        out.append(f"<p class='sub'>Out-of-sample coverage (each family of encoders predicted "
                   f"from the others): {len(cov)} checks — {said}. "
                   "<a href='#robustness'>All checks</a>.</p>")
    rest = checks[~is_cov]
    if rest.empty:
        return out
    body = "".join(
        f"<tr title='{html.escape(str(r['detail']))}'>"
        f"<td class='txt'>{html.escape(str(r['check']))}{_budgets(r['detail'])}"
        f"{_trainings(r['detail'])}</td>"
        f"<td class='txt' style='white-space:normal;min-width:180px'>"
        f"{html.escape(str(r['statistic']))}</td>"
        f"<td data-v='{r['value']}'>{_estimate(r, fmt)}</td>"
        f"<td class='txt' style='white-space:normal;min-width:240px'>"
        f"{_verdict(r['verdict'], colors)}{_caveat(r['detail'])}</td></tr>"
        for r in rest.to_dict("records"))
    out.insert(0, "<h3>Does it hold? Transfers and agreements</h3>"
               "<table id='answer-checks'><thead><tr><th class='txt'>check</th>"
               "<th class='txt'>statistic</th><th>value [95% CI]</th>"
               f"<th class='txt'>verdict</th></tr></thead><tbody>{body}</tbody></table>")
    return out


def _return_matrix(encoders_df: pd.DataFrame, fmt: Any) -> list[str]:
    """Encoders × (task, agent): mean evaluation return over seeds, shaded within each column
    (darkest = that column's best), rows by mean within-column rank."""
    if encoders_df is None or encoders_df.empty or "encoder" not in encoders_df:
        return []
    agents = [c[: -len("_return")] for c in encoders_df.columns
              if c.endswith("_return") and not c.endswith("predicted_return")]
    if not agents:
        return []
    df = encoders_df.assign(task=encoders_df.get("task", "task"))
    table = df.pivot_table(index="encoder", columns="task",
                           values=[f"{a}_return" for a in agents], aggfunc="first")
    table = table.dropna(axis=1, how="all")
    if table.empty:
        return []
    order = table.rank(ascending=False).mean(axis=1).sort_values().index
    table = table.loc[order]
    cols = list(table.columns)
    head = "".join(f"<th>{html.escape(task)}<br>{html.escape(col[: -len('_return')])}</th>"
                   for col, task in cols)
    body = []
    for enc, row in table.iterrows():
        cells = []
        for col in cols:
            v, top = row[col], table[col].max()
            bottom = table[col].min()
            if v is None or (isinstance(v, float) and math.isnan(v)):
                cells.append("<td>–</td>")
                continue
            share = 0.0 if top == bottom else (v - bottom) / (top - bottom)
            cells.append(f"<td data-v='{v}' style='background:rgba(46,125,50,"
                         f"{0.08 + 0.55 * share:.2f})'>{fmt(v)}</td>")
        body.append(f"<tr><td class='txt'>{html.escape(str(enc))}</td>{''.join(cells)}</tr>")
    return ["<h3>Return of every encoder, task by task</h3>"
            "<p class='sub'>Mean evaluation return over seeds (the encoder table below has "
            "intervals, IQM and success); shaded within each column, rows by mean rank.</p>",
            f"<table class='sortable' id='answer-returns'><thead><tr><th class='txt'>encoder"
            f"</th>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"]


#: The two readers the opening sentence speaks to: (group of ``metrics.csv``, who, what it reads).
READERS = (("privileged", "A simulator user",
            "the simulator's state"),
           ("observable", "A real-robot user",
            "only what a robot logs: observations, robot state, actions and rewards"))


def _best_of_group(grp: pd.DataFrame) -> dict[str, Any] | None:
    grp = grp[grp["spearman_learned"].notna()]
    if grp.empty:
        return None
    return grp.sort_values("spearman_learned", ascending=False).iloc[0].to_dict()


def _predicts(r: dict[str, Any]) -> bool:
    """Holm-adjusted p below 0.05: the metric is shown to predict return there."""
    holm = r.get("spearman_learned_p_holm")
    return holm is not None and math.isfinite(float(holm)) and float(holm) < 0.05


def _said(r: dict[str, Any], task: str, agent: str, agents: int, *, why: bool = True) -> str:
    where = f"{html.escape(task)}" + (f" ({html.escape(agent)})" if agents > 1 else "")
    share = r.get("of_ceiling")
    share_said = f", {float(share):.0%} of the noise ceiling" \
        if share is not None and math.isfinite(float(share)) else ""
    return (f"on {where} <code>{html.escape(str(r['metric']))}</code>, ρ "
            f"{_fmt2(r['spearman_learned'])} [{_fmt2(r['spearman_learned_ci_low'])}, "
            f"{_fmt2(r['spearman_learned_ci_high'])}]{share_said}"
            + ("" if _predicts(r) else " — not significant" + (
                ": no metric of this kind is shown to predict there" if why else "")))


def opening_sentence(ranking: pd.DataFrame | None) -> str:
    """The answer in words, from ``metrics.csv``'s rows: per reader (:data:`READERS`), the
    metric of their group with the largest within-learned ρ on each task × agent, its interval
    and share of the noise ceiling. A reader none of whose best metrics is significant is told
    so first ("has no metric shown to predict return yet"), not "should use"; the tasks on
    which the group has no metric are named; a group with no metric on the board is said to
    be absent. Empty without a ranking."""
    if ranking is None or ranking.empty or "group" not in ranking:
        return ""
    agents = ranking["agent"].nunique()
    tasks = sorted(ranking["task"].astype(str).unique())
    parts = []
    for group, who, reads in READERS:
        mine = ranking[ranking["group"] == group]
        best = [(b, str(task), str(agent))
                for (task, agent), grp in mine.groupby(["task", "agent"], sort=True)
                if (b := _best_of_group(grp)) is not None]
        lead = f"<b>{who}</b> (metrics that read {reads})"
        if not best:
            parts.append(f"{lead} has no metric on this board yet.")
            continue
        unscored = [t for t in tasks if t not in {task for _, task, _ in best}]
        tail = f" None is scored on {', '.join(unscored)} yet." if unscored else ""
        if any(_predicts(b) for b, _, _ in best):
            said = "; ".join(_said(b, t, a, agents) for b, t, a in best)
            parts.append(f"{lead} should use: {said}.{tail}")
        else:
            said = "; ".join(_said(b, t, a, agents, why=False) for b, t, a in best)
            parts.append(f"{lead} has no metric shown to predict return yet; the best of its "
                         f"kind: {said}.{tail}")
    return "<p class='lede' id='answer-words'>" + " ".join(parts) + "</p>"


def answer_section(claims: pd.DataFrame | None, checks: pd.DataFrame | None,
                   encoders_df: pd.DataFrame, figures: dict[str, Path],
                   ranking: pd.DataFrame | None = None) -> list[str]:
    """The page's first section, ``<section id="answer">``; empty before any correlation.
    With ``ranking`` (``metrics.csv``'s rows) it opens with :func:`opening_sentence`."""
    rows = [] if claims is None or claims.empty else _metric_rows(
        claims, _fmt2, _VERDICT_COLORS, ceiling_rows(checks))
    if not rows:
        return []
    paper_heads = "".join(f"<th class='txt'>{name}</th>" for name, _ in PAPER_METRICS)
    out = ["<section id='answer'><h2>The answer</h2>", opening_sentence(ranking),
           "<p class='note'>Which metric predicts RL return, per task and agent: the metric "
           "with the highest Spearman ρ between its value and the mean return <b>over the "
           "learned encoders</b>, with its 95% bootstrap interval and verdict (significant = "
           "Holm-adjusted p &lt; 0.05 over every metric × agent test), the noise ceiling (no "
           "metric can correlate with a 3-seed mean return above it: √ of the Spearman–Brown "
           "reliability of the seeds' ranking) and the share of it the best metric reaches, "
           "then the paper's own "
           "metrics (MI by MINE and KSG, regression error to the true state) as its claims, "
           "checked. Details: <a href='#claims-section'>claims</a>, <a href='#ranking-section'>"
           "the metric ranking</a>.</p>",
           "<table id='answer-metrics'><thead><tr><th class='txt'>task</th>"
           "<th class='txt'>agent</th><th class='txt'>best metric</th><th>ρ [95% CI]</th>"
           "<th class='txt'>verdict</th><th>noise ceiling [95% CI]</th>"
           f"{paper_heads}</tr></thead><tbody>"
           + "".join(rows) + "</tbody></table>"]
    if checks is not None and not checks.empty:
        out.extend(_checks_table(checks, _fmt2, _VERDICT_COLORS))
    if CENTRAL_FIGURE in figures:
        out.append(f"<div class='fig'><h3>{html.escape(CENTRAL_FIGURE)}</h3>"
                   f"{_figure(figures[CENTRAL_FIGURE], CENTRAL_FIGURE)}</div>")
    out.extend(_return_matrix(encoders_df, _fmt))
    out.append("</section>")
    return out
