"""The paper's claims, checked against a leaderboard's records.

Each :class:`Claim` restates one finding of the paper (§IV) as a signed statistic whose claimed
sign is fixed here, before any data is seen, with a 95 % interval and a verdict:

* **reproduced** — the interval excludes 0 on the claimed side (for correlations, also the
  Holm-adjusted permutation p-value < 0.05 over all metric × agent tests);
* **not reproduced** — the point estimate is 0 or on the other side;
* **inconclusive** — the point estimate is on the claimed side but the interval includes 0 (or
  the Holm-adjusted p ≥ 0.05).

Correlations are the metric leaderboard's Spearman ρ (:func:`repbench.analysis.correlation.
metric_leaderboard`) over the *learned* encoders — the paper correlated its VAE family, not
baselines — with the all-encoder value in the detail. Paired comparisons (low vs standard KL,
with vs without the smoothing loss) average the difference over the paper's encoder pairs;
their intervals resample each encoder's metric from its own bootstrap replicates (the same
replicate index for every encoder: replicates are paired across encoders), or each
encoder's RL seeds, with the pairs held fixed (the claim is about these objectives).
Finally the question the paper left open — which metric predicts return best — is answered from
the metric leaderboard, with its corrected p-value, interval and cost.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pandas as pd

from repbench.analysis.correlation import (
    BASELINE_FAMILY,
    batch_coefficients,
    bootstrap_resamples,
    replicate_matrix,
)

__all__ = ["KL_PAIRS", "SMOOTHING_PAIRS", "Claim", "check_claims", "claims_table", "verdict"]

#: (standard KL, low KL) encoder pairs of the paper's family (§IV-A).
KL_PAIRS: tuple[tuple[str, str], ...] = (
    ("vae", "vae_lowkl"), ("success", "success_lowkl"), ("pred_z", "pred_z_lowkl"),
    ("pred_im", "pred_im_lowkl"), ("smooth", "smooth_lowkl"))
#: (without, with) the smoothing loss (§IV-C).
SMOOTHING_PAIRS: tuple[tuple[str, str], ...] = (("vae", "smooth"), ("vae_lowkl", "smooth_lowkl"))
MI_METRICS = ("mine", "ksg")
ALPHA = 0.05


@dataclass(frozen=True)
class Claim:
    """One checked claim. ``value``/``ci_*`` are in the claim's own sign convention
    (``claimed_sign`` says which side of 0 the paper claims)."""

    claim: str
    source: str
    statistic: str
    value: float
    ci_low: float
    ci_high: float
    claimed_sign: int
    verdict: str
    detail: str


def verdict(value: float, ci_low: float, ci_high: float, claimed_sign: int,
            p_adjusted: float | None = None) -> str:
    """The verdict rule of the module docstring, for a claim that ``sign(value) ==
    claimed_sign``."""
    if not np.isfinite(value):
        return "inconclusive"
    v = claimed_sign * value
    lo = min(claimed_sign * ci_low, claimed_sign * ci_high)
    if v <= 0:
        return "not reproduced"
    significant = p_adjusted is None or (np.isfinite(p_adjusted) and p_adjusted < ALPHA)
    if np.isfinite(lo) and lo > 0 and significant:
        return "reproduced"
    return "inconclusive"


def _fmt(v: float) -> str:
    return "n/a" if not np.isfinite(v) else f"{v:.3g}"


def _ci(lo: float, hi: float) -> str:
    return f"[{_fmt(lo)}, {_fmt(hi)}]"


def _correlation_claim(ranking: pd.DataFrame, metric: str, claim: str, source: str,
                       claimed_sign: int, raw_sign: int) -> Claim | None:
    """A "metric correlates with return" claim from one metric-leaderboard row. The ranking's ρ
    is direction-normalized (positive = ranks encoders as RL does); ``raw_sign`` turns it back
    into ρ(metric value, return), the paper's convention."""
    if ranking.empty or "metric" not in ranking:
        return None
    rows = ranking[ranking["metric"] == metric]
    if rows.empty:
        return None
    r = rows.iloc[0]
    val = raw_sign * float(r["spearman_learned"])
    lo, hi = sorted((raw_sign * float(r["spearman_learned_ci_low"]),
                     raw_sign * float(r["spearman_learned_ci_high"])))
    p_holm = float(r.get("spearman_learned_p_holm", np.nan))
    all_v = raw_sign * float(r["spearman_all"])
    all_lo, all_hi = sorted((raw_sign * float(r["spearman_all_ci_low"]),
                             raw_sign * float(r["spearman_all_ci_high"])))
    detail = (f"{int(r['n_learned'])} learned encoders, Holm p = {_fmt(p_holm)}; over all "
              f"{int(r['n_all'])} encoders ρ = {_fmt(all_v)} {_ci(all_lo, all_hi)}, Holm p = "
              f"{_fmt(float(r.get('spearman_all_p_holm', np.nan)))}")
    return Claim(claim, source, f"Spearman ρ({metric}, {r['agent']} return), learned encoders",
                 val, lo, hi, claimed_sign, verdict(val, lo, hi, claimed_sign, p_holm), detail)


def _paired_difference(pairs: Sequence[tuple[str, str]], samples: Mapping[str, np.ndarray],
                       point: Mapping[str, float]) -> tuple[float, float, float, int, int]:
    """Mean over pairs of ``point[b] − point[a]`` and its percentile interval from
    independent draws of each encoder's ``samples``; also how many pairs have b > a."""
    use = [(a, b) for a, b in pairs if a in point and b in point
           and np.isfinite(point[a]) and np.isfinite(point[b])]
    if not use:
        return np.nan, np.nan, np.nan, 0, 0
    value = float(np.mean([point[b] - point[a] for a, b in use]))
    boot = np.mean([samples[b] - samples[a] for a, b in use], axis=0)
    lo, hi = np.quantile(boot, [ALPHA / 2, 1 - ALPHA / 2]) if boot.size else (np.nan, np.nan)
    return value, float(lo), float(hi), sum(point[b] > point[a] for a, b in use), len(use)


def _metric_samples(metric_rows: Sequence[Mapping[str, Any]], metric: str, task: str,
                    rng: np.random.Generator, n: int) -> tuple[dict[str, float],
                                                              dict[str, np.ndarray]]:
    """Each encoder's metric value, and n draws from its bootstrap replicates — the same
    replicate indices for every encoder, which keeps the pairing of replicates computed on the
    same resample of held-out episodes (as
    :func:`repbench.analysis.correlation.bootstrap_resamples`)."""
    rows = [r for r in metric_rows if r["metric"] == metric and r["task"] == task]
    point = {r["encoder"]: float(r["value"]) for r in rows}
    if not rows:
        return point, {}
    paired = replicate_matrix(
        [(r.get("extras") or {}).get("bootstrap_replicates") or [r["value"]] for r in rows],
        [float(r["value"]) for r in rows])
    pick = rng.integers(0, paired.shape[1], n)
    return point, {r["encoder"]: paired[i, pick] for i, r in enumerate(rows)}


def _returns_by_encoder(rl_rows: Sequence[Mapping[str, Any]], task: str, agent: str
                        ) -> dict[str, list[float]]:
    """encoder → final evaluation returns, one per seed."""
    by: dict[str, list[float]] = {}
    for r in rl_rows:
        if r["task"] == task and r["agent"] == agent:
            by.setdefault(r["encoder"], []).append(float(r["eval_return"]))
    return by


def _return_samples(rl_rows: Sequence[Mapping[str, Any]], task: str, agent: str,
                    rng: np.random.Generator, n: int) -> tuple[dict[str, float],
                                                              dict[str, np.ndarray]]:
    """Each encoder's mean return over seeds, and its seed-bootstrap distribution."""
    by = _returns_by_encoder(rl_rows, task, agent)
    point = {e: float(np.mean(v)) for e, v in by.items()}
    samples = {e: rng.choice(np.asarray(v), (n, len(v))).mean(1) for e, v in by.items()}
    return point, samples


def _paired_claim(claim: str, source: str, statistic: str, pairs: Sequence[tuple[str, str]],
                  point: Mapping[str, float], samples: Mapping[str, np.ndarray],
                  claimed_sign: int, unit: str) -> Claim | None:
    v, lo, hi, k, n = _paired_difference(pairs, samples, point)
    if n == 0:
        return None
    better = k if claimed_sign > 0 else n - k
    names = ", ".join(f"{b} − {a}" for a, b in pairs if a in point and b in point)
    return Claim(claim, source, statistic, v, lo, hi, claimed_sign,
                 verdict(v, lo, hi, claimed_sign),
                 f"{better} of {n} pairs in the claimed direction ({names}); {unit}")


def _difference_of_correlations(metric_rows: Sequence[Mapping[str, Any]],
                                rl_rows: Sequence[Mapping[str, Any]], task: str, agent: str,
                                a: str, b: str, families: Mapping[str, str],
                                directions: Mapping[str, bool], n_bootstrap: int, seed: int
                                ) -> tuple[float, float, float, int]:
    """|ρ_a| − |ρ_b| (Spearman with return over the learned encoders), its paired bootstrap
    interval (the same encoder, seed and replicate draws for both metrics)."""
    vals: dict[str, dict[str, float]] = {a: {}, b: {}}
    reps: dict[str, dict[str, list[float]]] = {a: {}, b: {}}
    for r in metric_rows:
        if r["task"] == task and r["metric"] in vals:
            vals[r["metric"]][r["encoder"]] = float(r["value"])
            reps[r["metric"]][r["encoder"]] = list(
                (r.get("extras") or {}).get("bootstrap_replicates") or [r["value"]])
    ret = _returns_by_encoder(rl_rows, task, agent)
    names = sorted(e for e in ret if e in vals[a] and e in vals[b]
                   and families.get(e, "learned") != BASELINE_FAMILY
                   and np.isfinite(vals[a][e]) and np.isfinite(vals[b][e]))
    if len(names) < 4:
        return np.nan, np.nan, np.nan, len(names)
    signs = {m: 1.0 if directions.get(m, True) else -1.0 for m in (a, b)}
    xs = [signs[m] * np.array([vals[m][e] for e in names]) for m in (a, b)]
    per_seed = [np.asarray(ret[e]) for e in names]
    y = np.array([r.mean() for r in per_seed])
    point = [abs(batch_coefficients(x[None], y[None])["spearman"][0]) for x in xs]
    rng = np.random.default_rng(seed)
    xbs, yb = bootstrap_resamples(xs, per_seed, rng, n_bootstrap,
                                  [[signs[m] * np.asarray(reps[m][e], dtype=float)
                                    for e in names] for m in (a, b)])
    diff = (np.abs(batch_coefficients(xbs[0], yb)["spearman"])
            - np.abs(batch_coefficients(xbs[1], yb)["spearman"]))
    diff = diff[np.isfinite(diff)]
    lo, hi = np.quantile(diff, [ALPHA / 2, 1 - ALPHA / 2])
    return float(point[0] - point[1]), float(lo), float(hi), len(names)


def check_claims(metric_rows: Sequence[Mapping[str, Any]], rl_rows: Sequence[Mapping[str, Any]],
                 ranking: pd.DataFrame, families: Mapping[str, str],
                 directions: Mapping[str, bool], *, task: str, agent: str = "sac",
                 n_bootstrap: int = 2000, seed: int = 0) -> list[Claim]:
    """Check the paper's claims for one task × agent (see the module docstring). Claims whose
    encoders or metrics are absent from the records are left out."""
    rank = ranking[(ranking["task"] == task) & (ranking["agent"] == agent)] \
        if not ranking.empty else ranking
    rng = np.random.default_rng(seed)
    out: list[Claim | None] = []
    for m in MI_METRICS:
        out.append(_correlation_claim(
            rank, m, f"MI between latent and true state ({m}) correlates positively with return",
            "§IV-A, Fig. 4", +1, +1))
    out.append(_correlation_claim(
        rank, "regression", "Regression error latent → true state correlates negatively with "
        "return", "§IV-B", -1, -1))
    for m in MI_METRICS:
        point, samples = _metric_samples(metric_rows, m, task, rng, n_bootstrap)
        out.append(_paired_claim(
            f"Low-KL encoders have higher MI ({m}) than their standard-KL twins", "§IV-A",
            f"mean over pairs of {m}(low KL) − {m}(standard KL), nats", KL_PAIRS, point,
            samples, +1, "interval: each encoder's metric bootstrap replicates"))
    point, samples = _return_samples(rl_rows, task, agent, rng, n_bootstrap)
    out.append(_paired_claim(
        "Low-KL encoders reach a higher RL return than their standard-KL twins", "§IV-A",
        f"mean over pairs of {agent} return(low KL) − return(standard KL)", KL_PAIRS, point,
        samples, +1, "interval: each encoder's seeds resampled"))
    point, samples = _metric_samples(metric_rows, "smoothness", task, rng, n_bootstrap)
    raw = {r["encoder"]: float((r.get("extras") or {}).get("raw_mean", np.nan))
           for r in metric_rows if r["metric"] == "smoothness" and r["task"] == task}
    raw_diff = [raw[b] - raw[a] for a, b in SMOOTHING_PAIRS if a in raw and b in raw]
    out.append(_paired_claim(
        "The smoothing loss lowers ‖Δz‖/‖Δz°‖", "§IV-C, Fig. 5",
        "mean over pairs of smoothness(with loss) − smoothness(without), scale-normalized "
        "ratio", SMOOTHING_PAIRS, point, samples, -1,
        "interval: each encoder's episode-bootstrap replicates; the paper's raw ratio (which "
        "also falls when z merely shrinks) changes by "
        f"{_fmt(float(np.mean(raw_diff))) if raw_diff else 'n/a'} on average"))
    for m in MI_METRICS:
        v, lo, hi, n = _difference_of_correlations(
            metric_rows, rl_rows, task, agent, m, "smoothness_objective", families, directions,
            n_bootstrap, seed)
        if n >= 4:
            out.append(Claim(
                f"H(z) − E ln|J_g| relates to return more weakly than MI ({m})", "§IV-C, Fig. 6",
                f"|ρ({m}, return)| − |ρ(smoothness_objective, return)|, learned encoders",
                v, lo, hi, +1, verdict(v, lo, hi, +1),
                f"{n} learned encoders; paired bootstrap over encoders, seeds and each "
                "metric's replicates"))
    for scope in ("learned", "all"):
        col = f"spearman_{scope}"
        if rank.empty or col not in rank or not np.isfinite(rank[col]).any():
            continue
        ordered = rank.sort_values(col, ascending=False)
        best = ordered.iloc[0]
        lo, hi = float(best[f"{col}_ci_low"]), float(best[f"{col}_ci_high"])
        overlap = [str(m) for m, h in zip(ordered["metric"].iloc[1:], ordered[f"{col}_ci_high"]
                                          .iloc[1:], strict=True) if np.isfinite(h) and h >= lo]
        p = float(best.get(f"{col}_p_holm", np.nan))
        answer = ("significant" if np.isfinite(p) and p < ALPHA and lo > 0
                  else "not significant")
        out.append(Claim(
            f"Which metric predicts return best ({scope} encoders)?", "open question (§V)",
            f"highest direction-normalized Spearman ρ: {best['metric']}",
            float(best[col]), lo, hi, +1, answer,
            f"{int(best[f'n_{scope}'])} encoders, Holm p = {_fmt(p)}, cost "
            f"{_cost_text(best)} per encoder; intervals overlapping "
            f"its own: {', '.join(overlap) if overlap else 'none'}"))
    return [c for c in out if c is not None]


def _cost_text(row: pd.Series) -> str:
    """A metric's cost per encoder: CPU seconds of its stage where recorded, else wall seconds.

    Wall time is inflated by a paused or crowded run; CPU time is not, so it is preferred.
    """
    cpu = float(row.get("cost_cpu_s", np.nan))
    if np.isfinite(cpu):
        return f"{_fmt(cpu)} CPU-s"
    return f"{_fmt(float(row.get('cost_s', np.nan)))} s (wall)"


def claims_table(claims: Sequence[Claim], task: str, agent: str) -> pd.DataFrame:
    """Claims as a table (``claims.csv``)."""
    return pd.DataFrame([{"task": task, "agent": agent, **asdict(c)} for c in claims])
