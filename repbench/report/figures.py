"""This run's versions of the paper's figures, as PNG files (matplotlib, no display needed).

* ``metric_vs_return.png`` — every metric against final RL return, one panel per agent × metric
  (paper Fig. 3a, 4 and, for ``smoothness_objective``, 6b);
* ``learning_curves.png`` — return against training steps (Fig. 3b);
* ``latent_distance.png`` — E‖z_n − z_{n+T}‖ against the offset T (Fig. 5a);
* ``smoothness_hist.png`` — ‖z_n − z_{n+1}‖ / ‖z°_n − z°_{n+1}‖ histograms (Fig. 5b);
* ``true_state_diffs.png`` — first and second differences of z° (Fig. 6a);
* ``predicted_vs_actual.png`` — each encoder's return predicted with its whole family held out
  (the calibration ``evaluate`` uses), with the stated interval, against its actual mean return
  (one panel per task × agent; a black edge marks an encoder outside its interval);
* ``agent_agreement.png`` — where DDPG ran beside SAC, each encoder's mean SAC return against
  its mean DDPG return (one panel per task, encoders named).
* ``budget_agreement.png`` — where a longer-budget run was joined, each encoder's mean return at
  the suite's budget against the longer one (one panel per task × agent, encoders named).
"""

from __future__ import annotations

import itertools
import os
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from repbench.analysis.correlation import mean_ci
from repbench.analysis.robustness import rl_tasks
from repbench.report.families import (
    encoder_families,
    family_legend,
    family_order,
    family_style,
)
from repbench.report.svg import figure_svg, inline_svg, write_svg


def _colors(names: list[str]) -> dict[str, Any]:
    cmap = plt.get_cmap("tab20")
    return {n: cmap(i % 20) for i, n in enumerate(sorted(names))}


def save_figure(fig: Any, path: str | os.PathLike[str], dpi: int = 110, tight: bool = True
                ) -> Path:
    """Write ``fig`` to ``path`` (parent folders created), close it, return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, bbox_inches="tight" if tight else None)
    plt.close(fig)
    return path


_GRID_COLS = 4


def _returns_by_encoder(res: Any, agent: str, task: str | None = None
                        ) -> dict[str, tuple[float, float, float]]:
    """encoder → (mean, CI low, CI high) of the final return of ``agent`` over seeds (on
    ``task`` only, when given: two tasks' returns are never pooled)."""
    rets: dict[str, list[float]] = {}
    for r in res.rl_rows:
        if r["agent"] == agent and (task is None or r["task"] == task):
            rets.setdefault(r["encoder"], []).append(r["eval_return"])
    return {e: mean_ci(v) for e, v in rets.items()}


def _label_candidates(returns: Mapping[str, tuple[float, float, float]],
                      families: Mapping[str, str], n_extreme: int = 2) -> list[str]:
    """Encoders worth a text label, most important first: the baselines, then the learned
    encoders with the highest and the lowest return."""
    base = sorted(e for e in returns if families.get(e) == "baselines")
    learned = sorted((e for e in returns if e not in base), key=lambda e: -returns[e][0])
    extreme = learned[:n_extreme] + learned[::-1][:n_extreme]
    return base + [e for i, e in enumerate(extreme) if e not in extreme[:i]]


def _prune_labels(fig: Any, labels: list[tuple[Any, Any]]) -> None:
    """Remove each text label (in priority order) that would overlap a kept one or leave its
    panel; ``labels`` holds (axes, annotation) pairs."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    kept: dict[Any, list[Any]] = {}
    for ax, text in labels:
        box = text.get_window_extent(renderer).expanded(1.05, 1.1)
        inside = ax.bbox.x0 <= box.x0 and box.x1 <= ax.bbox.x1 + 2 and box.y1 <= ax.bbox.y1
        if not inside or any(box.overlaps(k) for k in kept.get(ax, [])):
            text.remove()
        else:
            kept.setdefault(ax, []).append(box)


#: Where :func:`_place_labels` tries a point's label, in order: (dx, dy) points, alignment.
_LABEL_SPOTS = ((5, -3, "left"), (-5, -3, "right"), (5, 6, "left"), (5, -11, "left"),
                (-5, 6, "right"), (-5, -11, "right"))


def _place_labels(fig: Any, labels: list[tuple[Any, Any]]) -> None:
    """Move each text label (in priority order) to the first spot beside its point where it
    overlaps no placed label and stays in its panel; remove it where there is none."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    kept: dict[Any, list[Any]] = {}
    for ax, text in labels:
        for dx, dy, align in _LABEL_SPOTS:
            text.set_position((dx, dy))
            text.set_horizontalalignment(align)
            box = text.get_window_extent(renderer).expanded(1.05, 1.1)
            inside = (ax.bbox.x0 <= box.x0 and box.x1 <= ax.bbox.x1 + 2
                      and ax.bbox.y0 <= box.y0 and box.y1 <= ax.bbox.y1)
            if inside and not any(box.overlaps(k) for k in kept.get(ax, [])):
                kept.setdefault(ax, []).append(box)
                break
        else:
            text.remove()


def _scatter_panel(ax: Any, res: Any, metric: str, agent: str,
                   returns: Mapping[str, tuple[float, float, float]],
                   families: Mapping[str, str], titles: dict[str, str], task: str
                   ) -> dict[str, Any]:
    """One task × metric × agent panel: a point per encoder (family colour and marker, CI
    bars); each point gets a gid and its hover text in ``titles``; returns encoder → (x, y)."""
    points: dict[str, Any] = {}
    for r in res.metric_rows:
        enc = r["encoder"]
        if r["metric"] != metric or r["task"] != task or enc not in returns:
            continue
        m, lo, hi = returns[enc]
        x = r["value"]
        color, marker = family_style(families.get(enc, ""))
        xerr = None
        if r.get("ci_low") is not None and r.get("ci_high") is not None:
            xerr = [[max(0.0, x - r["ci_low"])], [max(0.0, r["ci_high"] - x)]]
        yerr = [[m - lo], [hi - m]] if np.isfinite(lo) else None
        ax.errorbar(x, m, xerr=xerr, yerr=yerr, fmt="none", ecolor=color, alpha=0.35,
                    elinewidth=0.8, capsize=0)
        gid = f"mvr-{len(titles)}"
        ax.plot([x], [m], ls="none", marker=marker, color=color, ms=5.5, mec="white",
                mew=0.5, gid=gid, zorder=3)
        titles[gid] = (f"{enc} ({families.get(enc, '?')}): {task} {metric}={x:.4g}, "
                       f"{agent} return={m:.4g}" + (f" [{lo:.4g}, {hi:.4g}]"
                                                    if np.isfinite(lo) else ""))
        points[enc] = (x, m)
    return points


def _fit_limits(ax: Any, points: Mapping[str, tuple[float, float]], pad: float = 0.08
                ) -> None:
    """Axis limits around the points, not their CI bars (a few wide intervals would squash
    every point into a corner; the bars run off the edge instead)."""
    xy = np.array([p for p in points.values() if np.all(np.isfinite(p))], dtype=float)
    if len(xy) < 2:
        return
    for set_lim, col in ((ax.set_xlim, xy[:, 0]), (ax.set_ylim, xy[:, 1])):
        lo, hi = float(col.min()), float(col.max())
        span = (hi - lo) or max(abs(hi), 1.0)
        set_lim(lo - pad * span, hi + pad * span)


def _panel_title(res: Any, metric: str, agent: str, correlations: pd.DataFrame | None,
                 n_agents: int, task: str, n_tasks: int = 1) -> str:
    """``metric ↑/↓ ρ=…`` (the direction-adjusted Spearman ρ on ``task``), with the task and
    the agent when there are several."""
    arrow = "↑" if res.provenance.get("directions", {}).get(metric, True) else "↓"
    rho = ""
    if correlations is not None and not correlations.empty:
        hit = correlations[(correlations["agent"] == agent)
                           & (correlations["metric"] == metric)
                           & (correlations["task"] == task if "task" in correlations else True)]
        if len(hit) and np.isfinite(hit["spearman"].iloc[0]):
            rho = f"   ρ = {hit['spearman'].iloc[0]:+.2f}"
    prefix = (f"{task} · " if n_tasks > 1 else "") + (f"{agent} · " if n_agents > 1 else "")
    return f"{prefix}{metric} {arrow}{rho}"


def metric_vs_return(res: Any, path: Path, correlations: pd.DataFrame | None = None
                     ) -> Path | None:
    """Scatter of each metric (x, with CI) against mean RL return over seeds (y, with CI), as
    a grid of panels (4 columns, a block of rows per task × agent, a panel per metric the task
    has: a metric scored on one task only, ``repbench leaderboard --scores``, adds no empty
    panels to the others); points coloured by encoder family, text labels on the baselines and
    the best and worst encoders where they fit; panel titles carry the direction-adjusted
    Spearman ρ from ``correlations``.

    Writes ``path`` (PNG) and, next to it, the same figure as SVG in which every point has
    a hover title naming its encoder (the page inlines that one); returns ``path``."""
    if not res.metric_rows or not res.rl_rows:
        return None
    of_task: dict[str, set[str]] = {}
    for r in res.metric_rows:
        of_task.setdefault(r["task"], set()).add(r["metric"])
    blocks = _task_agent_blocks(res)
    n_tasks = len({task for task, _ in blocks})
    n_agents = len({agent for _, agent in blocks})
    families = encoder_families(res)
    block_metrics = [sorted(of_task.get(task, ())) for task, _ in blocks]
    cols = min(_GRID_COLS, max([len(m) for m in block_metrics], default=0))
    if not cols:
        return None
    block_rows = [-(-len(m) // cols) for m in block_metrics]  # no rows: a task without metrics
    fig, axes = plt.subplots(sum(block_rows), cols, squeeze=False,
                             figsize=(3.4 * cols, 2.9 * sum(block_rows)))
    titles: dict[str, str] = {}
    labels: list[tuple[Any, Any]] = []
    drawn: set[str] = set()
    for i, (task, agent) in enumerate(blocks):
        metrics = block_metrics[i]
        first_row = sum(block_rows[:i])
        returns = _returns_by_encoder(res, agent, task)
        candidates = _label_candidates(returns, families)
        for j in range(block_rows[i] * cols):
            ax = axes[first_row + j // cols][j % cols]
            if j >= len(metrics):
                ax.set_axis_off()
                continue
            points = _scatter_panel(ax, res, metrics[j], agent, returns, families, titles, task)
            drawn |= set(points)
            _fit_limits(ax, points)
            ax.set_title(_panel_title(res, metrics[j], agent, correlations, n_agents, task,
                                      n_tasks), fontsize=9.5 if n_tasks == 1 else 8.5)
            ax.tick_params(labelsize=7.5)
            ax.grid(alpha=0.25, lw=0.5)
            if j % cols == 0:
                ax.set_ylabel(f"{agent} return", fontsize=8.5)
            labels += [(ax, ax.annotate(e, points[e], fontsize=7, xytext=(4, 3),
                                        textcoords="offset points", color="#333"))
                       for e in candidates if e in points]
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.subplots_adjust(wspace=0.25)  # tight_layout leaves room for the clipped CI bars
    family_legend(fig, {families.get(e, "") for e in drawn}, y=0.97)
    _prune_labels(fig, labels)
    write_svg(inline_svg(figure_svg(fig, titles)), Path(path).with_suffix(".svg"))
    return save_figure(fig, path)


_MULTI_COLS = 8
_CONTEXT_GREY = "#d5d5d5"


def small_multiples(blocks: list[tuple[str, Mapping[str, Any]]], families: Mapping[str, str],
                    draw: Any, xlabel: str = "", cols: int = _MULTI_COLS, ymax: Any = None
                    ) -> Any:
    """One small panel per encoder (family order): that encoder drawn in its family colour
    over every other encoder in light grey, the panel title naming it. ``blocks`` holds
    (y label, encoder → curve) pairs, e.g. one per agent: each starts a new row of panels and
    shares one y axis. ``draw(ax, curve, color, lw, zorder)`` draws one curve. With ``ymax``
    (curve → top of the y axis) each panel is scaled to its own encoder instead, the grey
    context clipped (for shapes whose heights differ 100-fold)."""
    layout = [(ylabel, family_order(families, curves), curves) for ylabel, curves in blocks]
    n_rows = [-(-len(encs) // cols) for _, encs, _ in layout]
    fig, axes = plt.subplots(sum(n_rows), cols, squeeze=False, sharex=True,
                             figsize=(1.55 * cols, 1.4 * sum(n_rows) + 0.45))
    row = 0
    for (ylabel, encs, curves), rows in zip(layout, n_rows, strict=True):
        block = axes[row:row + rows].flat
        for k, ax in enumerate(block):
            if k >= len(encs):
                ax.set_axis_off()
                continue
            if k and ymax is None:
                ax.sharey(axes[row][0])
            _multiple_panel(ax, encs[k], curves, families, draw)
            if ymax is not None:
                ax.set_ylim(0, ymax(curves[encs[k]]))
            if k % cols == 0:
                ax.set_ylabel(ylabel, fontsize=8)
            if k + cols >= len(encs):
                ax.set_xlabel(xlabel, fontsize=7.5)
                ax.xaxis.set_tick_params(labelbottom=True)
            if k % cols and ymax is None:
                ax.yaxis.set_tick_params(labelleft=False)
        row += rows
    fig.tight_layout(rect=(0, 0, 1, 0.97), h_pad=0.6, w_pad=0.4)
    family_legend(fig, {families.get(e, "") for _, encs, _ in layout for e in encs}, y=0.97)
    return fig


def _multiple_panel(ax: Any, enc: str, curves: Mapping[str, Any], families: Mapping[str, str],
                    draw: Any) -> None:
    """One panel of :func:`small_multiples`: the others grey, ``enc`` in colour, named."""
    for other, curve in curves.items():
        if other != enc:
            draw(ax, curve, _CONTEXT_GREY, 0.7, 1)
    color = family_style(families.get(enc, ""))[0]
    draw(ax, curves[enc], color, 1.6, 3)
    ax.set_title(enc, fontsize=8, color=color, pad=2)
    ax.tick_params(labelsize=6.5, pad=1)
    ax.grid(alpha=0.25, lw=0.5)


def _mean_curve(runs: list[Mapping[str, Any]]) -> tuple[np.ndarray, np.ndarray]:
    """(steps, mean return over seeds), cut to the shortest curve."""
    n = min(len(r["curve_steps"]) for r in runs)
    ys = np.array([r["curve_return"][:n] for r in runs], dtype=float)
    return np.asarray(runs[0]["curve_steps"][:n], dtype=float), ys.mean(0)


def _draw_line(ax: Any, curve: tuple[Any, Any], color: Any, lw: float, zorder: int) -> None:
    ax.plot(curve[0], curve[1], color=color, lw=lw, zorder=zorder)


def learning_curves(res: Any, path: Path) -> Path | None:
    """Mean learning curve over seeds, one small panel per encoder (the others in grey), a
    block of panels per task × agent stacked into one figure."""
    if not res.rl_rows:
        return None
    families = encoder_families(res)
    pairs = _task_agent_blocks(res)
    several = len({task for task, _ in pairs}) > 1
    blocks = []
    for task, agent in pairs:
        rows = [r for r in res.rl_rows if r["agent"] == agent and r["task"] == task]
        curves: dict[str, Any] = {}
        for enc in sorted({r["encoder"] for r in rows}):
            runs = [r for r in rows if r["encoder"] == enc and r.get("curve_steps")]
            if runs:
                curves[enc] = _mean_curve(runs)
        if curves:
            blocks.append((_task_label(task, f"{agent} return", several), curves))
    if not blocks:
        return None
    fig = small_multiples(blocks, families, _draw_line, xlabel="env. steps")
    return save_figure(fig, path)


def privileged_curve(res: Any, path: Path) -> Path | None:
    """Success rate and return of the privileged agent during training (its kept step
    marked)."""
    runs = {label: info for label, info in res.provenance.get("datasets", {}).items()
            if info.get("curve_steps")}
    if not runs:
        return None
    fig, (ax_s, ax_r) = plt.subplots(1, 2, figsize=(8, 3))
    for label, info in sorted(runs.items()):
        steps = info["curve_steps"]
        ax_s.plot(steps, info["curve_success"], marker=".", label=label)
        ax_r.plot(steps, info["curve_return"], marker=".", label=label)
        kept = info.get("extras", {}).get("kept_step")
        if kept is not None:
            for ax in (ax_s, ax_r):
                ax.axvline(kept, color="grey", lw=0.8, ls=":")
    ax_s.set_ylim(-0.03, 1.03)
    ax_s.set_ylabel("success rate", fontsize=8)
    ax_r.set_ylabel("return", fontsize=8)
    for ax in (ax_s, ax_r):
        ax.set_xlabel("environment steps", fontsize=8)
        ax.tick_params(labelsize=7)
    ax_r.legend(fontsize=6)
    fig.suptitle("Privileged agent during training (dotted: the kept policy)", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)


def _smoothness_extras(res: Any) -> dict[str, dict[str, Mapping[str, Any]]]:
    """task → encoder → the smoothness metric's extras (tasks in the suite's order)."""
    out: dict[str, dict[str, Mapping[str, Any]]] = {}
    for r in res.metric_rows:
        if r["metric"] == "smoothness":
            out.setdefault(r["task"], {})[r["encoder"]] = r.get("extras") or {}
    return out


def _task_label(task: str, label: str, several: bool) -> str:
    """A small-multiples block's y label, naming the task when there are several."""
    return f"{task}\n{label}" if several else label


def latent_distance(res: Any, path: Path) -> Path | None:
    """E‖z_n − z_{n+T}‖ against T (from the smoothness metric's extras), one small panel per
    encoder with the others in grey, a block of panels per task."""
    by_task = _smoothness_extras(res)
    blocks = []
    for task, extras in by_task.items():
        curves = {e: (x["latent_distance"]["offsets"],
                      x["latent_distance"].get("mean_distance_normalized")
                      or x["latent_distance"]["mean_distance"])
                  for e, x in extras.items() if x.get("latent_distance")}
        if curves:
            blocks.append((_task_label(task, "‖z_n − z_{n+T}‖ / scale", len(by_task) > 1),
                           curves))
    if not blocks:
        return None
    fig = small_multiples(blocks, encoder_families(res), _draw_line, xlabel="offset T (steps)")
    return save_figure(fig, path)


def _density(h: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """(fraction of pairs per decade of the ratio, bin edges) of a stored histogram (overflow
    counted). Per decade, because every encoder has its own bins, some 100× wider than
    others: a fraction per bin would draw wide bins tall. A first edge at 0 becomes half the
    next edge so the ratio can be drawn on a log axis."""
    counts = np.asarray(h["counts"], dtype=float)
    edges = np.asarray(h["bin_edges"], dtype=float).copy()
    if len(edges) > 1 and edges[0] <= 0:
        edges[0] = edges[1] / 2
    frac = counts / max(1.0, counts.sum() + h.get("overflow", 0))
    with np.errstate(divide="ignore", invalid="ignore"):
        per_decade = np.where(np.diff(np.log10(edges)) > 0, frac / np.diff(np.log10(edges)), 0)
    return np.nan_to_num(per_decade), edges


def _draw_stairs(ax: Any, curve: tuple[Any, Any], color: Any, lw: float, zorder: int) -> None:
    ax.stairs(curve[0], curve[1], color=color, lw=lw, zorder=zorder)


def smoothness_hist(res: Any, path: Path) -> Path | None:
    """Histogram of ‖z_n − z_{n+1}‖ / ‖z°_n − z°_{n+1}‖, one small panel per encoder with the
    others in grey, a block of panels per task (one shared log axis)."""
    by_task = _smoothness_extras(res)
    blocks = []
    for task, extras in by_task.items():
        hists = {e: _density(x["histogram"]) for e, x in extras.items() if x.get("histogram")}
        if hists:
            blocks.append((_task_label(task, "pairs per decade", len(by_task) > 1), hists))
    if not blocks:
        return None
    fig = small_multiples(blocks, encoder_families(res), _draw_stairs,
                          xlabel="‖Δz‖ / ‖Δz°‖ (log)",
                          ymax=lambda c: 1.15 * float(np.max(c[0], initial=0)) or 1.0)
    _log_ratio_axis(fig.axes[0], [x for extras in by_task.values() for x in extras.values()],
                    [h for _, hists in blocks for h in hists.values()])
    return save_figure(fig, path)


def _log_ratio_axis(ax: Any, extras: Sequence[Mapping[str, Any]],
                    hists: Sequence[tuple[np.ndarray, np.ndarray]]) -> None:
    """Log x axis (shared by every panel) from the lowest bin edge to 1.5 × the largest 95th
    percentile (the far tail of one encoder would squash every histogram), ticks at the
    powers of ten inside."""
    ax.set_xscale("log")
    q95 = [float(x["quantiles"]["0.95"]) for x in extras
           if isinstance(x.get("quantiles"), dict) and "0.95" in x["quantiles"]]
    lows = [float(c[1][0]) for c in hists if len(c[1])]
    if not (q95 and lows):
        return
    lo, hi = min(lows), 1.5 * max(q95)
    ax.set_xlim(lo, hi)
    ticks = [10.0 ** k for k in range(int(np.floor(np.log10(lo))), int(np.ceil(np.log10(hi))))
             if lo * 1.5 < 10.0 ** k < hi / 1.5]
    if ticks:
        ax.set_xticks(ticks)


def true_state_diffs(res: Any, path: Path) -> Path | None:
    """First and second differences of one z° element per dataset: the moving dimension with
    the largest spread, with its skew, excess kurtosis and normality-test p-value."""
    panels = []
    for task, by_source in res.diagnostics.items():
        for source, d in sorted(by_source.items()):
            first = d.get("first") or []
            moving = [j for j, x in enumerate(first) if not x.get("static") and x.get("histogram")]
            if not moving:
                continue
            dim = max(moving, key=lambda j: first[j]["std"])
            for order in ("first", "second"):
                x = d[order][dim]
                if x.get("histogram"):
                    panels.append((f"{task} {source}\n{order} difference of z°[{dim}]", x))
    if not panels:
        return None
    fig, axes = plt.subplots(1, len(panels), squeeze=False, figsize=(3.2 * len(panels), 3.0))
    for ax, (title, x) in zip(axes[0], panels, strict=True):
        h = x["histogram"]
        ax.stairs(np.asarray(h["counts"], float), np.asarray(h["bin_edges"], float), fill=True,
                  alpha=0.7)
        ax.set_title(title, fontsize=8)
        ax.text(0.02, 0.97, f"skew {x['skew']:.2f}\nex. kurt {x['excess_kurtosis']:.2f}\n"
                f"normality p {x['normaltest_pvalue']:.2g}", transform=ax.transAxes,
                fontsize=6.5, va="top")
        ax.tick_params(labelsize=7)
    fig.suptitle("True-state differences (paper Fig. 6a)", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)


def loss_curves(history: list[Mapping[str, Any]], path: str | os.PathLike[str],
                title: str = "", best_epoch: int | None = None) -> Path:
    """One panel per loss term (and the weighted total): train and held-out value per epoch,
    the kept (best held-out) epoch marked. ``history`` is an encoder's ``history_``: dicts with
    ``epoch`` and the term dicts ``train`` and ``heldout``."""
    terms = [k for k in history[0]["train"]
             if any(h["train"].get(k) or h.get("heldout", {}).get(k) for h in history)]
    fig, axes = plt.subplots(1, len(terms), figsize=(2.8 * len(terms), 2.6), squeeze=False)
    epochs = [h["epoch"] for h in history]
    for ax, term in zip(axes[0], terms, strict=True):
        ax.plot(epochs, [h["train"].get(term, np.nan) for h in history], "o-", ms=3,
                label="train")
        held = [h.get("heldout", {}).get(term, np.nan) for h in history]
        if np.isfinite(held).any():
            ax.plot(epochs, held, "s-", ms=3, label="held-out episodes")
        if best_epoch:
            ax.axvline(best_epoch, color="grey", ls=":", lw=1, label=f"kept: epoch {best_epoch}")
        vals = np.asarray([h["train"].get(term, np.nan) for h in history] + held, float)
        if term == "loss" or (np.nanmin(vals) > 0 and np.nanmax(vals) / np.nanmin(vals) > 30):
            ax.set_yscale("log")
        ax.set_title(term, fontsize=9)
        ax.set_xlabel("epoch", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)


#: kind of a per-encoder figure from the stage store → its heading on the page; the page lists
#: them as ``"<heading>: <encoder>"`` (see :func:`per_encoder_figures`).
STORE_FIGURE_HEADINGS = {"loss_curves": "Training curves",
                         "reconstructions": "Reconstructions (appendix figure)"}


def predicted_vs_actual(res: Any, path: Path, ranking: pd.DataFrame) -> Path | None:
    """Each encoder's return predicted with its whole family held out (the calibration method
    ``evaluate`` uses, :func:`repbench.analysis.robustness.choose_method`) vs its actual mean
    return: horizontal bars the stated interval, vertical bars the seeds' 95 % t-interval, one
    panel per task × agent, the diagonal dashed; the title gives the measured coverage."""
    from repbench.analysis.robustness import choose_method

    rob = getattr(res, "robustness", None) or {}
    heldout, checks = rob.get("heldout"), rob.get("checks")
    if heldout is None or heldout.empty or checks is None or checks.empty:
        return None
    panels = sorted({(t, a) for t, a in zip(heldout["task"], heldout["agent"], strict=True)})
    families = encoder_families(res)
    fig, axes = plt.subplots(1, len(panels), squeeze=False, figsize=(4.6 * len(panels), 4.2))
    for ax, (task, agent) in zip(axes[0], panels, strict=True):
        mine = [c for c in checks.itertuples(index=False) if c.check.endswith(f"{task} {agent}")]
        method, _ = choose_method(mine)  # type: ignore[arg-type]
        rows = heldout[(heldout["task"] == task) & (heldout["agent"] == agent)
                       & (heldout["method"] == method.name) & heldout["predicted"].notna()]
        rets: dict[str, list[float]] = {}
        for r in res.rl_rows:
            if r["task"] == task and r["agent"] == agent:
                rets.setdefault(r["encoder"], []).append(r["eval_return"])
        lims: list[float] = []
        for r in rows.itertuples(index=False):
            m, lo, hi = mean_ci(rets.get(r.encoder, [r.actual]))
            color, marker = family_style(families.get(r.encoder, ""))
            yerr = [[m - lo], [hi - m]] if np.isfinite(lo) else None
            xerr = [[r.half_width], [r.half_width]] if np.isfinite(r.half_width) else None
            ax.errorbar(r.predicted, m, xerr=xerr, yerr=yerr, fmt="none", ecolor=color,
                        alpha=0.35, elinewidth=0.8)
            ax.plot([r.predicted], [m], ls="none", marker=marker, color=color, ms=5.5,
                    mec="white" if r.covered else "black", mew=0.5 if r.covered else 1.2,
                    zorder=3)
            lims += [r.predicted, m]
        if lims:
            lo_, hi_ = min(lims), max(lims)
            ax.plot([lo_, hi_], [lo_, hi_], color="#999", lw=0.8, ls="--")
        check = next((c for c in mine if f"({method.name})" in c.check), None)
        cov = (f"coverage {check.value:.0%} [{check.ci_low:.0%}, {check.ci_high:.0%}] "
               f"(nominal {method.coverage:.0%}), median ±{rows['half_width'].median():.0f}"
               if check is not None and method.coverage is not None else "")
        ax.set_xlabel(f"predicted with its family held out ({method.name})", fontsize=8)
        ax.set_ylabel(f"{agent} return (mean over seeds)")
        ax.set_title(f"{task} {agent}: {cov}", fontsize=8)
    family_legend(fig, set(families.values()), y=1.0)
    fig.tight_layout()
    return save_figure(fig, path)


def _mean_returns(rows: Any, task: str, agent: str, steps: int
                  ) -> dict[str, tuple[float, float, float]]:
    """encoder → (mean, 95 % t-interval) of its returns over seeds."""
    from repbench.analysis.robustness import returns_by_encoder

    return {e: mean_ci(v) for e, v in returns_by_encoder(rows, task, agent, steps).items()}


def _paired_returns_panel(ax: Any, xs: Mapping[str, tuple[float, float, float]],
                          ys: Mapping[str, tuple[float, float, float]],
                          families: Mapping[str, str], labels: list[tuple[Any, Any]],
                          diagonal: bool = True) -> None:
    """One encoder per point at (mean return under x, under y), the seeds' intervals as bars,
    each named (its label appended to ``labels`` for :func:`_place_labels`), the diagonal
    dashed (``diagonal``: the two axes are on one scale)."""
    both = sorted(set(xs) & set(ys), key=lambda e: -ys[e][0])
    for enc in both:
        (x, xlo, xhi), (y, ylo, yhi) = xs[enc], ys[enc]
        color, marker = family_style(families.get(enc, ""))
        ax.errorbar(x, y, xerr=[[x - xlo], [xhi - x]] if np.isfinite(xlo) else None,
                    yerr=[[y - ylo], [yhi - y]] if np.isfinite(ylo) else None,
                    fmt="none", ecolor=color, alpha=0.35, elinewidth=0.8)
        ax.plot([x], [y], ls="none", marker=marker, color=color, ms=6, mec="white",
                mew=0.5, zorder=3)
        labels.append((ax, ax.annotate(enc, (x, y), xytext=(5, -3),
                                       textcoords="offset points", fontsize=7, color=color)))
    _fit_limits(ax, {e: (xs[e][0], ys[e][0]) for e in both})
    vals = [v for e in both for v in (xs[e][0], ys[e][0])]
    if vals and diagonal:
        ax.plot([min(vals), max(vals)], [min(vals), max(vals)], color="#999", lw=0.8, ls="--")


def _check_note(checks: Any, name: str, statistic: str) -> str:
    """": <statistic> value [low, high], verdict" of the ``robustness.csv`` row ``name``."""
    check = None if checks is None else next(
        (c for c in checks.itertuples(index=False) if c.check == name), None)
    if check is None or not np.isfinite(check.value):
        return ""
    return (f": {statistic} {check.value:.2f} [{check.ci_low:.2f}, {check.ci_high:.2f}], "
            f"{check.verdict}")


def _agreement_figure(res: Any, path: Path, panels: Sequence[tuple[Any, ...]],
                      encoders: set[str], diagonal: bool = True) -> Path | None:
    """One :func:`_paired_returns_panel` per ``(xs, ys, title, xlabel, ylabel)``, labels
    placed, the legend of ``encoders``' families on top."""
    if not panels:
        return None
    families = encoder_families(res)
    fig, axes = plt.subplots(1, len(panels), squeeze=False, figsize=(5.2 * len(panels), 4.6))
    labels: list[tuple[Any, Any]] = []
    for ax, (xs, ys, title, xlabel, ylabel) in zip(axes[0], panels, strict=True):
        _paired_returns_panel(ax, xs, ys, families, labels, diagonal)
        ax.set_title(title, fontsize=8)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel(ylabel, fontsize=8)
    fig.tight_layout()
    _place_labels(fig, labels)
    family_legend(fig, {families.get(e, "") for e in encoders} - {""}, y=1.0)
    fig.tight_layout()
    return save_figure(fig, path)


def agent_agreement_panels(res: Any) -> list[tuple[Any, ...]]:
    """The panels of :func:`agent_agreement`, one per task with SAC and DDPG rows: each
    encoder's mean return and 95 % t-interval under SAC (x) and DDPG (y), each agent at its own
    budget (the smallest it has on the task: DDPG may run at 50k beside SAC at 10k), the title
    and the axis labels naming them."""
    rob = getattr(res, "robustness", None) or {}
    rows = [*res.rl_rows, *(rob.get("other_agent_rl") or [])]
    tasks = sorted({r["task"] for r in rows if r["agent"] == "ddpg"}
                   & {r["task"] for r in rows if r["agent"] == "sac"})
    panels = []
    for task in tasks:
        steps = {agent: min(int(r["train_steps"]) for r in rows
                            if r["task"] == task and r["agent"] == agent)
                 for agent in ("sac", "ddpg")}
        note = _check_note(rob.get("checks"), f"SAC vs DDPG ranking {task}", "Spearman ρ")
        panels.append((_mean_returns(rows, task, "sac", steps["sac"]),
                       _mean_returns(rows, task, "ddpg", steps["ddpg"]), f"{task}{note}",
                       f"SAC return at {steps['sac']} steps (mean over seeds)",
                       f"DDPG return at {steps['ddpg']} steps"))
    return panels


def agent_agreement(res: Any, path: Path) -> Path | None:
    """Each encoder's mean SAC return (x) against its mean DDPG return (y), seeds' 95 %
    t-intervals as bars, one panel per task of the joined other-agent run
    (``res.robustness["other_agent_rl"]``) or of DDPG rows in the suite itself
    (:func:`agent_agreement_panels`); the title gives the Spearman check of
    ``robustness.csv``."""
    panels = agent_agreement_panels(res)
    return _agreement_figure(res, path, panels, {e for panel in panels for e in panel[1]})


def budget_agreement(res: Any, path: Path) -> Path | None:
    """Each encoder's mean return (seeds' 95 % t-interval as bars) at the suite's budget (x)
    against a longer budget (y), one panel per task × agent of the joined longer-budget run
    (``res.robustness["longer_rl"]``), every encoder named, the diagonal dashed; the title
    gives the Kendall τ check of ``robustness.csv``."""
    from repbench.analysis.robustness import budget_check_name

    rob = getattr(res, "robustness", None) or {}
    longer = rob.get("longer_rl") or []
    panels = []
    for task, agent in sorted({(r["task"], r["agent"]) for r in longer}):
        base = min((int(r["train_steps"]) for r in res.rl_rows
                    if r["task"] == task and r["agent"] == agent), default=None)
        if base is None:
            continue
        steps = max(int(r["train_steps"]) for r in longer
                    if r["task"] == task and r["agent"] == agent)
        note = _check_note(rob.get("checks"), budget_check_name(agent, base, steps, task),
                           "Kendall τ")
        panels.append((_mean_returns(res.rl_rows, task, agent, base),
                       _mean_returns(longer, task, agent, steps), f"{task} {agent}{note}",
                       f"{agent} return at {base} steps (mean over seeds)",
                       f"{agent} return at {steps} steps"))
    return _agreement_figure(res, path, panels, {r["encoder"] for r in longer})


def _tasks(res: Any) -> list[str]:
    """The tasks with RL rows, in the suite's order."""
    return rl_tasks(res.rl_rows)


def _task_agent_blocks(res: Any) -> list[tuple[str, str]]:
    """(task, agent) pairs with RL rows: tasks in the suite's order, agents sorted."""
    have = {(r["task"], r["agent"]) for r in res.rl_rows}
    return [(t, a) for t in _tasks(res) for a in sorted({a for _, a in have}) if (t, a) in have]


def task_agreement(res: Any, path: Path) -> Path | None:
    """Each encoder's mean return on one task (x) against another (y), seeds' 95 % t-intervals
    as bars, one panel per pair of tasks × agent (no diagonal: two tasks' returns are not on
    one scale); the title gives the Kendall τ check of ``robustness.csv``."""
    rob = getattr(res, "robustness", None) or {}
    tasks = _tasks(res)
    panels = []
    for agent in dict.fromkeys(r["agent"] for r in res.rl_rows):
        for first, other in itertools.combinations(tasks, 2):
            steps = {t: min(int(r["train_steps"]) for r in res.rl_rows if r["task"] == t)
                     for t in (first, other)}
            note = _check_note(rob.get("checks"),
                               f"{agent.upper()} ranking {first} vs {other}", "Kendall τ")
            panels.append((_mean_returns(res.rl_rows, first, agent, steps[first]),
                           _mean_returns(res.rl_rows, other, agent, steps[other]),
                           f"{agent} {first} vs {other}{note}",
                           f"{first} return (mean over seeds)", f"{other} return"))
    return _agreement_figure(res, path, panels, {r["encoder"] for r in res.rl_rows},
                             diagonal=False)


def cross_task_predictions(res: Any, path: Path) -> Path | None:
    """The pre-registered cross-task predictions (:mod:`repbench.analysis.transfer`) against
    the actual mean returns: x the stated prediction with its interval, y the mean over seeds
    with its 95 % t-interval, one panel per predicted task, the diagonal dashed; the title gives
    the ranking test of ``robustness.csv``."""
    rob = getattr(res, "robustness", None) or {}
    tables = rob.get("predictions") or {}
    panels = []
    for name, table in tables.items():
        task, agent = str(table["task"].iloc[0]), str(table["agent"].iloc[0])
        steps = min(int(r["train_steps"]) for r in res.rl_rows if r["task"] == task)
        actual = _mean_returns(res.rl_rows, task, agent, steps)
        xs = {r.encoder: (r.predicted_return, r.ci_low, r.ci_high)
              for r in table.itertuples(index=False) if r.encoder in actual}
        if not xs:
            continue
        source = table["source_task"].iloc[0]
        note = _check_note(rob.get("checks"), name, "ρ")
        whence = f"{len(xs)} new encoders" if source == task else f"predicted from {source}"
        panels.append((xs, actual, f"{task} {agent}, {whence}{note}",
                       f"predicted before any RL record ({table['metric'].iloc[0]}, "
                       f"{source}'s line)", f"{agent} return (mean over seeds)"))
    return _agreement_figure(res, path, panels, {e for t in tables.values()
                                                 for e in t["encoder"]})


def cross_task_metrics(res: Any, path: Path, ranking: pd.DataFrame) -> Path | None:
    """Each metric's within-learned Spearman ρ with return (95 % interval as a bar), one
    marker per task, metrics in the first task's order: which metric predicts, task by task
    (on a one-task board, that task's: the answer's central figure)."""
    if ranking is None or ranking.empty or "spearman_learned" not in ranking.columns:
        return None
    tasks = [t for t in _tasks(res) if t in set(ranking["task"])]
    if not tasks:
        return None
    agents = list(dict.fromkeys(ranking["agent"]))
    fig, axes = plt.subplots(1, len(agents), squeeze=False,
                             figsize=(6.0 * len(agents), 0.32 * ranking["metric"].nunique() + 1.4))
    colors = _colors(tasks)
    for ax, agent in zip(axes[0], agents, strict=True):
        board = ranking[ranking["agent"] == agent]
        order = list(board[board["task"] == tasks[0]].sort_values(
            "spearman_learned")["metric"])
        order += [m for m in dict.fromkeys(board["metric"]) if m not in order]
        y = {m: i for i, m in enumerate(order)}
        for k, task in enumerate(tasks):
            rows = board[board["task"] == task]
            off = (k - (len(tasks) - 1) / 2) * 0.22
            for r in rows.itertuples(index=False):
                yy = y[r.metric] + off
                ax.plot([r.spearman_learned_ci_low, r.spearman_learned_ci_high], [yy, yy],
                        color=colors[task], lw=1.2, alpha=0.5)
                ax.plot([r.spearman_learned], [yy], "o", color=colors[task], ms=5,
                        label=task if r.metric == rows["metric"].iloc[0] else None)
        ax.axvline(0, color="#999", lw=0.8, ls="--")
        ax.set_yticks(range(len(order)), order, fontsize=8)
        ax.set_xlim(-1.05, 1.05)
        ax.set_xlabel(f"within-learned Spearman ρ with {agent} return (95 % interval)",
                      fontsize=8)
        ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return save_figure(fig, path)


def make_figures(res: Any, metrics_df: pd.DataFrame, out_dir: Path) -> dict[str, Path]:
    """Render every figure that the results support; name → PNG path."""

    def scatter(r: Any, p: Path) -> Path | None:
        return metric_vs_return(r, p, metrics_df)

    def predicted(r: Any, p: Path) -> Path | None:
        return predicted_vs_actual(r, p, metrics_df)

    def metrics_by_task(r: Any, p: Path) -> Path | None:
        return cross_task_metrics(r, p, metrics_df)

    makers = {
        "Predicted vs actual return (leave one family out)": (
            predicted, "predicted_vs_actual"),
        "Return at the suite's budget vs a longer one": (budget_agreement, "budget_agreement"),
        "SAC vs DDPG return": (agent_agreement, "agent_agreement"),
        "Which metric predicts return, task by task": (metrics_by_task, "cross_task_metrics"),
        "Encoder returns, task against task": (task_agreement, "task_agreement"),
        "Pre-registered cross-task predictions vs actual return": (
            cross_task_predictions, "cross_task_predictions"),
        "Metric vs RL return (paper Fig. 3a, 4, 6b)": (scatter, "metric_vs_return"),
        "Learning curves (Fig. 3b)": (learning_curves, "learning_curves"),
        "Privileged agent learning curve": (privileged_curve, "privileged_curve"),
        "Latent distance vs time offset (Fig. 5a)": (latent_distance, "latent_distance"),
        "Encoder smoothness histogram (Fig. 5b)": (smoothness_hist, "smoothness_hist"),
        "True-state differences (Fig. 6a)": (true_state_diffs, "true_state_diffs"),
    }
    out: dict[str, Path] = {}
    for title, (fn, stem) in makers.items():
        p = fn(res, out_dir / f"{stem}.png")
        if p is not None:
            out[title] = p.with_suffix(".svg") if p.with_suffix(".svg").is_file() else p
            shrink_png(p)
    for name, src in sorted(res.figures_from_store.items()):
        dest = out_dir / f"{name.replace(' ', '_')}.png"
        dest.parent.mkdir(parents=True, exist_ok=True)
        if src.resolve() != dest.resolve():
            dest.write_bytes(src.read_bytes())
            shrink_png(dest)
        kind, enc = name.split(" ", 1)
        out[f"{STORE_FIGURE_HEADINGS.get(kind, kind)}: {enc}"] = dest
    return out


def per_encoder_figures(figures: Mapping[str, Path]
                        ) -> tuple[dict[str, Path], dict[str, list[tuple[str, Path]]]]:
    """Split :func:`make_figures`'s output into the suite's figures (title → path) and the
    per-encoder figures from the store (heading → [(encoder, path)])."""
    shared: dict[str, Path] = {}
    groups: dict[str, list[tuple[str, Path]]] = {}
    headings = set(STORE_FIGURE_HEADINGS.values())
    for title, path in figures.items():
        heading, sep, enc = title.partition(": ")
        if sep and heading in headings:
            groups.setdefault(heading, []).append((enc, path))
        else:
            shared[title] = path
    return shared, groups


def shrink_png(path: Path, colors: int = 256) -> Path:
    """Rewrite a PNG with a palette of at most ``colors`` colours (plots and the small
    rendered frames look the same; the file, which the page inlines, is 2–3× smaller);
    kept as it is when that would not make it smaller."""
    from PIL import Image

    with Image.open(path) as im:
        small = im.convert("RGB").quantize(colors, method=Image.Quantize.MEDIANCUT)
    tmp = path.with_name(f".{path.name}.{os.getpid()}-{uuid.uuid4().hex[:8]}.tmp")
    small.save(tmp, format="PNG", optimize=True)
    if tmp.stat().st_size < path.stat().st_size:
        tmp.replace(path)
    else:
        tmp.unlink()
    return path
