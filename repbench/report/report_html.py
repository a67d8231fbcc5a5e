"""One leaderboard page: no network access, the suite's figures inlined, tables sortable, the
answer (:mod:`repbench.report.answer`) first and the detailed tables after it, collapsed. The
per-encoder figures (training curves, reconstructions: most of a big board's bytes) are the PNG
files in ``figures/`` beside the page, which the page links rather than inlines.

Every piece of text that comes from a user (encoder names, suite descriptions, error strings) is
escaped with :func:`html.escape`.
"""

from __future__ import annotations

import html
import json
import math
import urllib.parse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from repbench.report.answer import CENTRAL_FIGURE, answer_section
from repbench.report.html_parts import VERDICT_COLORS as _VERDICT_COLORS
from repbench.report.html_parts import figure as _figure
from repbench.report.html_parts import fmt as _fmt
from repbench.report.html_parts import img as _img

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px auto;
max-width:1200px;color:#1d2433;padding:0 16px}
h1{font-size:1.6em;margin-bottom:0}h2{margin-top:1.6em;border-bottom:1px solid #dde;
padding-bottom:4px}.sub{color:#667;margin-top:4px}
table{border-collapse:collapse;font-size:12.5px;margin:8px 0;display:block;overflow-x:auto}
th,td{padding:4px 8px;border-bottom:1px solid #eef;text-align:right;white-space:nowrap}
th{background:#f4f6fb;cursor:pointer;position:sticky;top:0;user-select:none}
th.sorted-asc::after{content:" ▲"}th.sorted-desc::after{content:" ▼"}
td.txt,th.txt{text-align:left}tr:hover td{background:#fafbff}
.ci{color:#889;font-size:11px}.fig{margin:12px 0}.fig img{max-width:100%;border:1px solid #eee}
.note{background:#f7f7fa;border-left:3px solid #99a;padding:8px 12px;font-size:13px}
.lede{font-size:16px;line-height:1.5;margin:8px 0 12px}
code{background:#f2f2f6;padding:1px 4px;border-radius:3px}
tr.stale td{color:#8a8f99;font-style:italic}
tr.highlight td{background:#fff3c4;font-weight:600}
.svgfig svg{display:block;max-width:100%;height:auto}
.svgfig svg g[id^="mvr-"]{cursor:pointer}.svgfig svg g[id^="mvr-"]:hover{opacity:.6}
details{margin:2px 0}summary{cursor:pointer;font-size:13px;padding:2px 0}
.per-encoder details{display:inline-block;vertical-align:top;margin-right:14px}
.per-encoder details[open]{display:block}
details.section>summary{font-size:inherit}details.section>summary h2{display:inline-block;
margin:1.2em 0 .3em}#answer{border:1px solid #cfd6e6;border-radius:6px;padding:4px 16px 12px;
margin-top:16px}#answer h2{margin-top:.6em}
"""

_JS = """
document.querySelectorAll('table.sortable').forEach(function(table){
  table.querySelectorAll('th').forEach(function(th, col){
    th.addEventListener('click', function(){
      var body = table.tBodies[0];
      var rows = Array.from(body.rows);
      var asc = !th.classList.contains('sorted-asc');
      table.querySelectorAll('th').forEach(function(h){h.classList.remove('sorted-asc','sorted-desc');});
      th.classList.add(asc ? 'sorted-asc' : 'sorted-desc');
      rows.sort(function(a, b){
        var x = a.cells[col].dataset.v, y = b.cells[col].dataset.v;
        var nx = parseFloat(x), ny = parseFloat(y);
        var cmp;
        if (!isNaN(nx) && !isNaN(ny)) cmp = nx - ny;
        else if (isNaN(nx) && !isNaN(ny)) return 1;
        else if (!isNaN(nx) && isNaN(ny)) return -1;
        else cmp = String(x).localeCompare(String(y));
        return asc ? cmp : -cmp;
      });
      rows.forEach(function(r){ body.appendChild(r); });
    });
  });
});
function openTarget(){  // a link into a collapsed section opens it
  var t = location.hash && document.getElementById(location.hash.slice(1));
  for (var e = t; e; e = e.parentElement) if (e.tagName === 'DETAILS') e.open = true;
  if (t) t.scrollIntoView();
}
window.addEventListener('hashchange', openTarget); openTarget();
"""


def _table(df: pd.DataFrame, table_id: str, ci_cols: bool = True,
           row_class: Any = None) -> str:
    """HTML table; ``x_ci_low``/``x_ci_high`` columns fold into the cell of ``x``;
    ``row_class(row)`` gives an optional CSS class per row."""
    if df.empty:
        return "<p>No results yet.</p>"
    cols = [c for c in df.columns if not (ci_cols and (c.endswith("_ci_low")
                                                       or c.endswith("_ci_high")))]
    head = "".join(
        f'<th class="{"txt" if df[c].dtype == object else ""}">{html.escape(str(c))}</th>'
        for c in cols)
    body = []
    for _, row in df.iterrows():
        cells = []
        for c in cols:
            v = row[c]
            val = v.item() if hasattr(v, "item") else v
            sort_v = "" if val is None or (isinstance(val, float) and math.isnan(val)) else val
            text = html.escape(_fmt(val))
            lo, hi = row.get(f"{c}_ci_low"), row.get(f"{c}_ci_high")
            if ci_cols and lo is not None and hi is not None and pd.notna(lo) and pd.notna(hi):
                text += f' <span class="ci">[{_fmt(float(lo))}, {_fmt(float(hi))}]</span>'
            cls = "txt" if isinstance(val, str) else ""
            cells.append(f'<td class="{cls}" data-v="{html.escape(str(sort_v))}">{text}</td>')
        cls_attr = f' class="{row_class(row)}"' if row_class and row_class(row) else ""
        body.append(f"<tr{cls_attr}>" + "".join(cells) + "</tr>")
    return (f'<table class="sortable" id="{table_id}"><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(body)}</tbody></table>")


def _linked_img(path: Path, alt: str) -> str:
    """An image of a file in the ``figures/`` folder beside the page, by its relative path
    (inlined when it lies anywhere else)."""
    parts = path.parts
    if "figures" not in parts[:-1]:
        return _img(path, alt)
    below = parts[len(parts) - parts[::-1].index("figures"):]  # an encoder name may hold a "/"
    src = "/".join(urllib.parse.quote(p) for p in ("figures", *below))
    return f'<img alt="{html.escape(alt)}" src="{html.escape(src)}">'


def _figures_section(figures: dict[str, Path]) -> list[str]:
    """The suite's figures open (but the answer's central one, shown above), then each kind of
    per-encoder figure (training curves, reconstructions) as one closed ``<details>`` per
    encoder, linked from ``figures/``, so the page stays short and small."""
    from repbench.report.figures import per_encoder_figures

    shared, groups = per_encoder_figures(figures)
    out = [f"<div class='fig'><h3>{html.escape(name)}</h3>{_figure(path, name)}</div>"
           for name, path in shared.items() if name != CENTRAL_FIGURE]
    for heading, items in groups.items():
        out.append(f"<div class='fig per-encoder'><h3>{html.escape(heading)}</h3>"
                   f"<p class='sub'>One per encoder; click a name to open it (the PNG files "
                   f"in <code>figures/</code> beside this page).</p>")
        out.extend(f"<details><summary>{html.escape(enc)}</summary>"
                   f"{_linked_img(path, f'{heading}: {enc}')}</details>" for enc, path in items)
        out.append("</div>")
    return out


def _collapsed(parts: list[str], section_id: str) -> list[str]:
    """A section (its first part opening with its ``<h2>``) as a closed ``<details>`` whose
    summary is that heading."""
    if not parts:
        return []
    head, _, rest = parts[0].partition("</h2>")
    return [f"<details class='section' id='{section_id}'><summary>{head}</h2></summary>{rest}",
            *parts[1:], "</details>"]


def _privileged_section(prov: dict[str, Any]) -> list[str]:
    """The privileged agent (it collects the on-policy data and sets the ceiling)."""
    rows = []
    for label, info in sorted(prov.get("datasets", {}).items()):
        if "eval_success_rate" in info:
            rows.append(
                f"<li>{html.escape(label)}: success {info['eval_success_rate']:.0%}, return "
                f"{info.get('eval_return', float('nan')):.1f} on the fixed evaluation episodes "
                f"(policy kept at step {info.get('extras', {}).get('kept_step')})</li>")
        elif "contact_share" in info:
            rows.append(
                f"<li>{html.escape(label)}: {info.get('n_steps')} steps, success share "
                f"{info.get('success_share', float('nan')):.1%}, contact share "
                f"{info['contact_share']:.1%}</li>")
    if not rows:
        return []
    return ["<h2>Privileged agent and its data</h2><p class='note'>SAC on the task-frame "
            "state ⊕ robot state; it collects the on-policy dataset and sets the ceiling of "
            "the returns above.</p><ul>", *rows, "</ul>"]


def _encoder_row_class(res: Any) -> Any:
    highlight = set(getattr(res, "highlight", []) or [])
    stale = getattr(res, "stale", {}) or {}

    def row_class(row: Any) -> str:
        key = (row.get("task"), row.get("encoder"))
        classes = (["highlight"] if row.get("encoder") in highlight else []) + (
            ["stale"] if key in stale else [])
        return " ".join(classes)

    return row_class


def _encoder_notes(res: Any) -> list[str]:
    notes = [f"<p class='note'>⚠ {html.escape(w)}</p>" for w in getattr(res, "warnings", [])]
    highlight = getattr(res, "highlight", []) or []
    predictions = getattr(res, "predictions", []) or []
    if highlight:
        text = (f"Highlighted: {html.escape(', '.join(highlight))} — evaluated with "
                "<code>repbench evaluate</code> against the reference records.")
        for p in predictions:
            text += html.escape(
                f" Predicted {p['agent']} return of {p['encoder']}: "
                f"{_fmt(p['predicted_return'])} [{_fmt(p['ci_low'])}, {_fmt(p['ci_high'])}]"
                f" from {p['predictor']} ({p['method']}, {p['n_reference']} reference "
                "encoders); no RL was run for it.")
            if p.get("measured_coverage") is not None:
                lo, hi = p["coverage_ci"]
                text += html.escape(
                    f" Measured out of sample on the reference encoders (one family held out "
                    f"at a time), intervals of this method covered {p['measured_coverage']:.0%}"
                    f" [{lo:.0%}, {hi:.0%}] of actual returns, median half-width "
                    f"±{_fmt(p['median_half_width'])}.")
            if p.get("method_warning"):
                text += html.escape(f" ⚠ {p['method_warning']}.")
        notes.append(f"<p class='note' id='evaluated'>{text}</p>")
    if getattr(res, "stale", None):
        notes.append("<p class='note'>Rows in grey italics are <b>stale</b>: computed by an "
                     "older version of a plugin than the one installed (column "
                     "<code>stale</code>). Run the suite again to replace them.</p>")
    return notes


_WIDE = "class='txt' style='white-space:normal;min-width:{}px'"
_TXT = "class='txt'"


def _verdict_table(df: pd.DataFrame, table_id: str, text_cols: Sequence[tuple[str, int]]
                   ) -> str:
    """A table of checks: the text columns (name, min width in px; 0 = no wrapping), then
    value [95% CI], verdict (coloured) and detail."""
    head = [c for c, _ in text_cols] + ["value [95% CI]", "verdict", "detail"]
    rows = [f"<table id='{table_id}'><thead><tr>"
            + "".join(f"<th class='txt'>{h}</th>" for h in head) + "</tr></thead><tbody>"]
    for r in df.to_dict("records"):
        cells = "".join(
            f"<td {_WIDE.format(w) if w else _TXT}>"
            f"{html.escape(str(r[c]))}</td>" for c, w in text_cols)
        rows.append(
            f"<tr>{cells}<td>{_fmt(r['value'])} <span class='ci'>[{_fmt(r['ci_low'])}, "
            f"{_fmt(r['ci_high'])}]</span></td><td class='txt' style='background:"
            f"{_VERDICT_COLORS.get(str(r['verdict']), '')}'><b>{html.escape(str(r['verdict']))}"
            f"</b></td><td {_WIDE.format(260)}>{html.escape(str(r['detail']))}</td></tr>")
    rows.append("</tbody></table>")
    return "".join(rows)


def _claims_section(claims: pd.DataFrame | None) -> list[str]:
    """The paper's claims with their numbers and verdicts (:mod:`repbench.analysis.claims`)."""
    if claims is None or claims.empty:
        return []
    return ["<h2>Paper claims, checked</h2><p class='note'>Each claim of the paper as a signed "
            "statistic, with its 95% interval and a verdict fixed before the data: "
            "<b>reproduced</b> = interval excludes 0 on the claimed side (correlations: also "
            "Holm-adjusted p &lt; 0.05); <b>not reproduced</b> = estimate on the other side; "
            "<b>inconclusive</b> = right side, interval includes 0. Correlations are over the "
            "learned encoders, as in the paper. The last rows answer the question the paper "
            "left open: which metric predicts return best.</p>",
            _verdict_table(claims, "claims", [*_task_column(claims), ("agent", 0),
                                              ("claim", 220), ("source", 0),
                                              ("statistic", 200)])]


def _task_column(df: pd.DataFrame) -> list[tuple[str, int]]:
    """The ``task`` column of a verdict table, where its rows come from several tasks (each
    claim is checked per task; without it a two-task page shows each claim twice, unlabelled)."""
    return [("task", 0)] if "task" in df and df["task"].nunique() > 1 else []


def _robustness_section(checks: pd.DataFrame | None) -> list[str]:
    """Does the answer hold? (:mod:`repbench.analysis.robustness`)."""
    if checks is None or checks.empty:
        return []
    return ["<h2 id='robustness'>Does the answer hold?</h2><p class='note'>Checks with "
            "verdict rules fixed in code before the data. <b>Out-of-sample coverage</b>: each "
            "family of encoders (paper VAEs, low-KL twins, ablations, contrastive, supervised, "
            "baselines) is predicted from its metrics by a line fitted on the other families "
            "(metric chosen inside the fold), with the interval those families alone give; "
            "coverage = share of actual mean returns inside (Clopper–Pearson 95% interval). "
            "<b>does not hold</b> = coverage significantly below nominal (exact binomial, "
            "p &lt; 0.05); <b>holds, too wide</b> = covers, but the median interval is wider "
            "than ±150. Agreement rows (SAC vs DDPG, 10k vs a longer budget), where run: "
            "<b>holds</b> if the bootstrap interval (encoders and seeds resampled) lies above "
            "the threshold, <b>does not hold</b> if below. Across tasks, where a suite has "
            "several: the encoder rankings of every pair of tasks (Kendall τ, holds if its "
            "interval lies above 0), the first task's best metric on each other task, and "
            "each "
            "pre-registered cross-task prediction (Spearman ρ of predicted vs actual over the "
            "learned encoders: holds if its interval lies above 0).</p>",
            _verdict_table(checks, "robustness-checks", [("check", 240), ("statistic", 180)])]


#: The modality ablations shown side by side across tasks: all inputs, image only, F/T and
#: proprioception only, then the blind and untrained baselines and the information ceiling.
ABLATIONS = ("vae_lowkl", "vae_lowkl_image", "vae_lowkl_ft_proprio", "proprio_only", "random",
             "oracle_task")


def _cross_task_section(encoders_df: pd.DataFrame) -> list[str]:
    """Across tasks (suites with several tasks): the modality ablations' returns side by
    side; the checks themselves are rows of the robustness table."""
    if "task" not in encoders_df.columns or encoders_df["task"].nunique() < 2:
        return []
    tasks = list(dict.fromkeys(encoders_df["task"]))
    agents = [c[: -len("_return")] for c in encoders_df.columns
              if c.endswith("_return") and not c.endswith("predicted_return")]
    rows = []
    for enc in ABLATIONS:
        cells = []
        for task in tasks:
            r = encoders_df[(encoders_df["task"] == task) & (encoders_df["encoder"] == enc)]
            for a in agents:
                if r.empty or pd.isna(r[f"{a}_return"].iloc[0]):
                    cells.append("<td>–</td>")
                    continue
                x = r.iloc[0]
                cells.append(f"<td>{_fmt(x[f'{a}_return'])} <span class='ci'>["
                             f"{_fmt(x[f'{a}_return_ci_low'])}, {_fmt(x[f'{a}_return_ci_high'])}"
                             f"]</span> · {x.get(f'{a}_success', float('nan')):.0%}</td>")
        rows.append(f"<tr><td class='txt'>{html.escape(enc)}</td>{''.join(cells)}</tr>")
    head = "".join(f"<th>{html.escape(t)} {html.escape(a)}</th>" for t in tasks for a in agents)
    return ["<h2 id='across-tasks'>Across tasks</h2><p class='note'>Whether each pair of "
            "tasks ranks the encoders alike (Kendall τ), whether the first task's best metric "
            "is best on each other task, and, where a task has a "
            "prediction committed before its RL ran, how the first task's calibration "
            "predicted it — rows of the table above, figures below. The modality ablations "
            "side by side (mean return over seeds [95% interval] · success rate): on a task "
            "where what varies is felt, not seen, F/T + proprioception should do well against "
            "the image alone.</p>",
            f"<table id='ablations'><thead><tr><th class='txt'>encoder</th>{head}</tr></thead>"
            f"<tbody>{''.join(rows)}</tbody></table>"]


def _partial_banner(res: Any) -> list[str]:
    """A warning at the top when stages of the suite have not finished."""
    if not res.missing:
        return []
    return [f"<p class='note' style='border-left-color:#c33'><b>Partial results:</b> "
            f"{len(res.missing)} stages of this suite have not finished (listed under "
            "<a href='#missing'>Missing results</a>); every table, correlation and claim below "
            "is over the results that exist. Run the suite again with the same store to "
            "finish it.</p>"]


def render_html(res: Any, encoders_df: pd.DataFrame, metrics_df: pd.DataFrame,
                figures: dict[str, Path], claims: pd.DataFrame | None = None) -> str:
    """The whole page as a string."""
    prov = res.provenance
    title = f"repbench leaderboard — suite {prov.get('suite', '?')}"
    corr_cols = ["task", "agent", "metric", "higher_is_better", "n_encoders", "spearman",
                 "spearman_ci_low", "spearman_ci_high", "spearman_p", "pearson",
                 "pearson_ci_low", "pearson_ci_high", "pearson_p", "kendall", "kendall_ci_low",
                 "kendall_ci_high", "kendall_p"]
    met = metrics_df[[c for c in corr_cols if c in metrics_df.columns]]
    rank_cols = ["agent", "metric", "spearman_learned", "spearman_learned_ci_low",
                 "spearman_learned_ci_high", "spearman_learned_p_holm", "spearman_learned_p_bh",
                 "n_learned", "spearman_all", "spearman_all_ci_low", "spearman_all_ci_high",
                 "spearman_all_p_holm", "spearman_all_p_bh", "n_all", "loo_rmse",
                 "loo_rmse_ratio", "cost_s", "cost_cpu_s"]
    if len({*metrics_df.get("task", pd.Series(dtype=object))}) > 1:
        rank_cols.insert(0, "task")
    ranking = metrics_df[[c for c in rank_cols if c in metrics_df.columns]]
    checks = (getattr(res, "robustness", None) or {}).get("checks")
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f"<p class='sub'>{html.escape(prov.get('description') or '')}</p>",
        *_partial_banner(res),
        *answer_section(claims, checks, encoders_df, figures, metrics_df),
        "<p class='sub'>The detailed tables: click a heading to open it.</p>",
        *_collapsed([
        "<h2>Metric leaderboard</h2>",
        "<p class='note'>Metrics ranked by their Spearman ρ with RL return <b>within the learned "
        "encoders</b> (baselines such as the oracle and the untrained encoder excluded: they "
        "anchor any pooled correlation), then over all encoders. Brackets: 95% bootstrap "
        "interval resampling encoders, RL seeds and each encoder's metric estimate (its own "
        "bootstrap replicates, paired across encoders). p_holm / p_bh: Holm and "
        "Benjamini–Hochberg adjusted p-values over all metric × agent tests. loo_rmse: error "
        "of predicting an encoder's mean return from the metric by a line fit on the other "
        "encoders; ratio &lt; 1 beats predicting the others' mean. cost_s: wall seconds to compute "
        "the metric for one encoder; cost_cpu_s: CPU seconds of its whole stage (loading the "
        "latents, the estimate and its bootstrap), which a paused or crowded run does not "
        "inflate.</p>",
        _table(ranking, "ranking") if "spearman_learned" in metrics_df.columns
        else "<p>No correlations yet.</p>"], "ranking-section"),
        *_collapsed(_claims_section(claims), "claims-section"),
        *_collapsed(_robustness_section(checks), "robustness-section"),
        *_collapsed(_cross_task_section(encoders_df), "across-tasks-section"),
        *_collapsed([
        "<h2>Which metric predicts RL performance?</h2>",
        "<p class='note'>Correlation across encoders between each metric and the final "
        "evaluation return (mean over seeds). Metrics where lower is better are sign-flipped, so "
        "a positive coefficient always means the metric ranks encoders as RL does. Brackets: "
        "bootstrap 95% interval over encoders and seeds. Click a header to sort.</p>",
        _table(met, "metrics")], "metrics-section"),
        *_collapsed([
        "<h2>Which encoder is best?</h2>",
        "<p class='note'>One row per task × encoder: every metric with its confidence interval, "
        "and per agent the evaluation return over seeds — mean and interquartile mean (IQM), "
        "each with a stratified-bootstrap 95% interval (rliable; seeds are the unit of "
        "inference) — and success rate on the fixed evaluation episodes. fit_time_s is the "
        "encoder's training in wall seconds, fit_cpu_s the CPU seconds of its stage: compare "
        "costs on the second, which a paused or crowded run does not inflate.</p>",
        *_encoder_notes(res),
        _table(encoders_df, "encoders", row_class=_encoder_row_class(res))],
        "encoders-section"),
        *_collapsed(_privileged_section(prov), "privileged-section"),
        "<h2>Figures</h2>",
    ]
    parts.extend(_figures_section(figures))
    if not figures:
        parts.append("<p>No figures: no finished results.</p>")
    if res.missing:
        parts.append("<h2 id='missing'>Missing results</h2><p class='note'>These stages have "
                     "not finished (or failed); run the suite again to complete them.</p><ul>")
        parts.extend(f"<li>{html.escape(m)}</li>" for m in res.missing[:200])
        parts.append("</ul>")
    parts.append("<h2>Provenance</h2><details id='provenance'><summary>Suite settings, "
                 "plugin versions, data sets and records (JSON)</summary><pre>" + html.escape(
                     json.dumps({k: v for k, v in prov.items() if k != "directions"},
                                indent=1, default=str)) + "</pre></details>")
    parts.append(f"<script>{_JS}</script></body></html>")
    return "\n".join(parts)
