"""This run's versions of the paper's figures, as PNG files (matplotlib, no display needed).

* ``metric_vs_return.png`` — every metric against final RL return, one panel per agent × metric
  (paper Fig. 3a, 4 and, for ``smoothness_objective``, 6b);
* ``learning_curves.png`` — return against training steps (Fig. 3b);
* ``latent_distance.png`` — E‖z_n − z_{n+T}‖ against the offset T (Fig. 5a);
* ``smoothness_hist.png`` — ‖z_n − z_{n+1}‖ / ‖z°_n − z°_{n+1}‖ histograms (Fig. 5b);
* ``true_state_diffs.png`` — first and second differences of z° (Fig. 6a);
* ``predicted_vs_actual.png`` — each encoder's return predicted leave-one-encoder-out by the
  metric with the lowest LOO error, against its actual mean return (one panel per agent).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from repbench.analysis.correlation import mean_ci


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


def metric_vs_return(res: Any, path: Path, correlations: pd.DataFrame | None = None
                     ) -> Path | None:
    """Scatter of each metric (x, with CI) against mean RL return over seeds (y, with CI);
    panel titles carry the direction-adjusted Spearman ρ from ``correlations``."""
    if not res.metric_rows or not res.rl_rows:
        return None
    metrics = sorted({r["metric"] for r in res.metric_rows})
    agents = sorted({r["agent"] for r in res.rl_rows})
    encs = sorted({r["encoder"] for r in res.metric_rows})
    colors = _colors(encs)
    fig, axes = plt.subplots(len(agents), len(metrics), squeeze=False,
                             figsize=(3.0 * len(metrics), 2.8 * len(agents)))
    for i, agent in enumerate(agents):
        rets: dict[str, list[float]] = {}
        for r in res.rl_rows:
            if r["agent"] == agent:
                rets.setdefault(r["encoder"], []).append(r["eval_return"])
        for j, metric in enumerate(metrics):
            ax = axes[i][j]
            for r in res.metric_rows:
                if r["metric"] != metric or r["encoder"] not in rets:
                    continue
                m, lo, hi = mean_ci(rets[r["encoder"]])
                x = r["value"]
                xerr = None
                if r.get("ci_low") is not None and r.get("ci_high") is not None:
                    xerr = [[max(0.0, x - r["ci_low"])], [max(0.0, r["ci_high"] - x)]]
                yerr = [[m - lo], [hi - m]] if np.isfinite(lo) else None
                ax.errorbar(x, m, xerr=xerr, yerr=yerr, fmt="o", color=colors[r["encoder"]],
                            ms=5, capsize=2, label=r["encoder"])
                ax.annotate(r["encoder"], (x, m), fontsize=6, xytext=(3, 3),
                            textcoords="offset points")
            arrow = "↑" if res.provenance.get("directions", {}).get(metric, True) else "↓"
            rho = ""
            if correlations is not None and not correlations.empty:
                hit = correlations[(correlations["agent"] == agent)
                                   & (correlations["metric"] == metric)]
                if len(hit) and np.isfinite(hit["spearman"].iloc[0]):
                    rho = f"  ρ={hit['spearman'].iloc[0]:+.2f}"
            ax.set_title(f"{metric} {arrow}{rho}", fontsize=9)
            ax.tick_params(labelsize=7)
            if j == 0:
                ax.set_ylabel(f"{agent} eval return", fontsize=8)
    fig.suptitle("Metric vs RL return (one point per encoder; bars: CI)", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)


def learning_curves(res: Any, path: Path) -> Path | None:
    """Mean learning curve over seeds for every encoder, one panel per agent."""
    if not res.rl_rows:
        return None
    agents = sorted({r["agent"] for r in res.rl_rows})
    encs = sorted({r["encoder"] for r in res.rl_rows})
    colors = _colors(encs)
    fig, axes = plt.subplots(1, len(agents), squeeze=False, figsize=(5 * len(agents), 3.4))
    for ax, agent in zip(axes[0], agents, strict=True):
        for enc in encs:
            runs = [r for r in res.rl_rows if r["agent"] == agent and r["encoder"] == enc
                    and r.get("curve_steps")]
            if not runs:
                continue
            n = min(len(r["curve_steps"]) for r in runs)
            steps = np.asarray(runs[0]["curve_steps"][:n])
            ys = np.array([r["curve_return"][:n] for r in runs], dtype=float)
            ax.plot(steps, ys.mean(0), marker=".", color=colors[enc], label=enc)
        ax.set_title(f"{agent}: return during training", fontsize=9)
        ax.set_xlabel("environment steps", fontsize=8)
        ax.set_ylabel("return", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0][-1].legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
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


def _smoothness_extras(res: Any) -> dict[str, Mapping[str, Any]]:
    return {r["encoder"]: r.get("extras") or {} for r in res.metric_rows
            if r["metric"] == "smoothness"}


def latent_distance(res: Any, path: Path) -> Path | None:
    """E‖z_n − z_{n+T}‖ against T for every encoder (from the smoothness metric's extras)."""
    extras = _smoothness_extras(res)
    curves = {e: x["latent_distance"] for e, x in extras.items() if x.get("latent_distance")}
    if not curves:
        return None
    colors = _colors(list(curves))
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for enc, c in sorted(curves.items()):
        y = c.get("mean_distance_normalized") or c["mean_distance"]
        ax.plot(c["offsets"], y, marker=".", color=colors[enc], label=enc)
    ax.set_xlabel("time offset T (steps)")
    ax.set_ylabel("E‖z_n − z_{n+T}‖ / scale of z")
    ax.set_title("Latent distance against time offset", fontsize=10)
    ax.legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    return save_figure(fig, path)


def smoothness_hist(res: Any, path: Path) -> Path | None:
    """Histogram of ‖z_n − z_{n+1}‖ / ‖z°_n − z°_{n+1}‖ for every encoder."""
    extras = _smoothness_extras(res)
    hists = {e: x["histogram"] for e, x in extras.items() if x.get("histogram")}
    if not hists:
        return None
    colors = _colors(list(hists))
    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for enc, h in sorted(hists.items()):
        edges = np.asarray(h["bin_edges"], dtype=float)
        counts = np.asarray(h["counts"], dtype=float)
        dens = counts / max(1.0, counts.sum() + h.get("overflow", 0))
        ax.stairs(dens, edges, color=colors[enc], label=enc)
    q95 = [float(x["quantiles"]["0.95"]) for x in extras.values()
           if isinstance(x.get("quantiles"), dict) and "0.95" in x["quantiles"]]
    if q95:  # the far tail of one encoder would squash every histogram
        ax.set_xlim(0, 1.5 * max(q95))
    ax.set_xlabel("‖z_n − z_{n+1}‖ / ‖z°_n − z°_{n+1}‖ (each standardized)")
    ax.set_ylabel("fraction of pairs")
    ax.set_title("Encoder smoothness", fontsize=10)
    ax.legend(fontsize=6, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    return save_figure(fig, path)


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


_STORE_FIGURE_TITLES = {"reconstructions": "Reconstructions: {} (appendix figure)",
                        "loss_curves": "Training curves: {} (train and held-out loss per epoch)"}


def predicted_vs_actual(res: Any, path: Path, ranking: pd.DataFrame) -> Path | None:
    """Leave-one-encoder-out predicted return (best metric by LOO error) vs actual mean return,
    one panel per task × agent, with the seeds' 95 % t-interval and the diagonal."""
    preds = getattr(res, "loo_predictions", None) or {}
    if ranking is None or ranking.empty or "loo_rmse" not in ranking or not preds:
        return None
    best = (ranking[np.isfinite(ranking["loo_rmse"])].sort_values("loo_rmse")
            .groupby(["task", "agent"], sort=True).head(1))
    if best.empty:
        return None
    fig, axes = plt.subplots(1, len(best), squeeze=False, figsize=(4.2 * len(best), 3.8))
    for ax, (_, b) in zip(axes[0], best.iterrows(), strict=True):
        pred = preds.get((b["task"], b["agent"], b["metric"]), {})
        rets: dict[str, list[float]] = {}
        for r in res.rl_rows:
            if r["task"] == b["task"] and r["agent"] == b["agent"]:
                rets.setdefault(r["encoder"], []).append(r["eval_return"])
        colors = _colors(list(pred))
        lims = []
        for enc, yhat in pred.items():
            if enc not in rets:
                continue
            m, lo, hi = mean_ci(rets[enc])
            yerr = [[m - lo], [hi - m]] if np.isfinite(lo) else None
            ax.errorbar(yhat, m, yerr=yerr, fmt="o", color=colors[enc], ms=5, capsize=2)
            ax.annotate(enc, (yhat, m), fontsize=6, xytext=(3, 3), textcoords="offset points")
            lims += [yhat, m]
        if lims:
            lo_, hi_ = min(lims), max(lims)
            ax.plot([lo_, hi_], [lo_, hi_], color="#999", lw=0.8, ls="--")
        ax.set_xlabel(f"predicted from {b['metric']} (leave one encoder out)")
        ax.set_ylabel(f"{b['agent']} return (mean over seeds)")
        ax.set_title(f"{b['task']} {b['agent']}: LOO RMSE {b['loo_rmse']:.3g} "
                     f"(ratio {b['loo_rmse_ratio']:.2f})", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)


def make_figures(res: Any, metrics_df: pd.DataFrame, out_dir: Path) -> dict[str, Path]:
    """Render every figure that the results support; name → PNG path."""

    def scatter(r: Any, p: Path) -> Path | None:
        return metric_vs_return(r, p, metrics_df)

    def predicted(r: Any, p: Path) -> Path | None:
        return predicted_vs_actual(r, p, metrics_df)

    makers = {
        "Predicted vs actual return (best metric, leave one encoder out)": (
            predicted, "predicted_vs_actual"),
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
            out[title] = p
    for name, src in sorted(res.figures_from_store.items()):
        dest = out_dir / f"{name.replace(' ', '_')}.png"
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_bytes(src.read_bytes())
        kind, enc = name.split(" ", 1)
        out[_STORE_FIGURE_TITLES.get(kind, kind + ": {}").format(enc)] = dest
    return out
