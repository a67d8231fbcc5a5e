"""Temporal smoothness of the encoding z = g(z°) (paper §III.B, §IV.C and the appendix).

* :func:`smoothness` — the ratio ‖z_n − z_{n+1}‖ / ‖z°_n − z°_{n+1}‖ over successive steps of
  one episode (paper Fig. 5b: its histogram; value: its mean, lower is better), and the latent
  distance curve E‖z_n − z_{n+T}‖ over offsets T (paper Fig. 5a), both in ``extras``.
* :func:`smoothness_objective` — H(z) − E ln|J_g| with the paper's bound
  E ln|J_g| ≤ (k/2)(ln E‖δz‖² − ln αk) (k the latent dimension), higher is better.

Static true-state dimensions. z° contains the hole position, which does not move within an
episode, so its first differences are exactly zero. The ratio uses the norm of the whole z°
step and only drops pairs whose *whole* true state did not move (counted in extras). For the
Jacobian bound the choice is per-dimension α: α_d = E[(δz°_d)²] for every dimension that moves,
static dimensions (α_d = 0; their Jacobian columns cannot be observed from temporal differences)
are **excluded**, and α is the geometric mean of the remaining α_d. This is the exact
generalization of the paper's bound to δz° ~ N(0, diag(α_d)) — whiten δz° and apply the
log-sum inequality — and equals the paper's formula when all α_d are equal. ``alpha="scalar"``
uses the arithmetic mean over moving dimensions (one α as in the paper) and a float uses that
value (the paper's α = 0.12).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from repbench.dataset import successor_index
from repbench.errors import DataError
from repbench.metric import MetricResult, metric
from repbench.metrics._common import check_params, drop_constant, episode_bootstrap_replicates
from repbench.metrics.mutual_information import knn_entropy_terms

__all__ = ["jacobian_bound", "latent_distance_curve", "smoothness", "smoothness_objective"]

DEFAULT_OFFSETS = (1, 2, 3, 5, 10, 20, 50, 100)


def _total_std(x: np.ndarray) -> float:
    """sqrt(tr Cov x): the isotropic scale of a point cloud."""
    return float(np.sqrt(x.var(axis=0).sum()))


def latent_distance_curve(z: np.ndarray, episode: np.ndarray,
                          offsets: tuple[int, ...] = DEFAULT_OFFSETS) -> dict[str, list[float]]:
    """E‖z_n − z_{n+T}‖ over offsets T, pairs within one episode (paper Fig. 5a).

    Offsets longer than every episode are left out. Returns ``{"offsets", "mean_distance",
    "n_pairs"}``.
    """
    out: dict[str, list[Any]] = {"offsets": [], "mean_distance": [], "n_pairs": []}
    for t in offsets:
        i, j = successor_index(episode, None, int(t))
        if i.size == 0:
            continue
        out["offsets"].append(int(t))
        out["mean_distance"].append(float(np.linalg.norm(z[j] - z[i], axis=1).mean()))
        out["n_pairs"].append(int(i.size))
    return out


def _check_smoothness(*, offsets: Any, bins: int, **_: Any) -> None:
    """Range checks of :func:`smoothness`'s parameters (the planner runs them too)."""
    check_params("smoothness", bins=(int(bins) >= 1, "must be >= 1"),
                 offsets=(all(int(t) >= 1 for t in offsets), "must list step offsets >= 1"))


@metric("smoothness", higher_is_better=False, rows="on_policy", check=_check_smoothness,
        version=1,  # v1: episode resamples from resampling_stream, paired across encoders
        description="Mean of ‖z_n − z_n+1‖ / ‖z°_n − z°_n+1‖ within episodes, scale-normalized")
def smoothness(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
               *, normalize: bool = True, offsets: tuple[int, ...] = DEFAULT_OFFSETS,
               bins: int = 50, n_bootstrap: int = 100) -> MetricResult:
    """Encoder smoothness: mean ratio ‖z_n − z_{n+1}‖ / ‖z°_n − z°_{n+1}‖ (lower is better).

    With ``normalize`` (default) z and z° are each divided by their total standard deviation
    sqrt(tr Cov) first, so the ratio does not reward merely shrinking z (the paper's raw ratio,
    which does, is ``extras["raw_mean"]``). The true state as representation scores 1.
    Pairs are successive steps of one episode; pairs whose true state did not move at all
    are dropped (``extras["n_static_pairs"]``). Extras: histogram of the ratio (``bin_edges``,
    ``counts``, ``overflow`` beyond the last edge = 99.5th percentile), the latent distance
    curve E‖z_n − z_{n+T}‖ (raw and normalized), quantiles. CI: bootstrap over episodes.
    A fully constant z is rejected (the normalized ratio is 0/0).
    """
    _check_smoothness(offsets=offsets, bins=bins)
    i, j = successor_index(episode, None, 1)
    if i.size < 2:
        raise DataError("smoothness: needs at least 2 pairs of successive steps in one episode; "
                        "check the episode ids (rows must be ordered by episode, step)")
    sz, szt = _total_std(z), _total_std(z_true)
    if sz == 0:
        raise DataError("smoothness: z is constant; the normalized ratio is undefined")
    if szt == 0:
        raise DataError("smoothness: z_true is constant; the ratio is undefined")
    dz_raw = np.linalg.norm(z[j] - z[i], axis=1)
    dzt_raw = np.linalg.norm(z_true[j] - z_true[i], axis=1)
    moving = dzt_raw > 0
    if moving.sum() < 2:
        raise DataError("smoothness: the true state never moves between successive steps")
    raw = dz_raw[moving] / dzt_raw[moving]
    ratio = raw * (szt / sz) if normalize else raw
    pair_ep = episode[i[moving]]
    value = float(ratio.mean())
    lo, hi, reps = episode_bootstrap_replicates(lambda r: ratio[r].mean(), pair_ep, rng,
                                                n_bootstrap)
    top = float(np.quantile(ratio, 0.995))
    counts, edges = np.histogram(ratio, bins=int(bins), range=(0.0, top if top > 0 else 1.0))
    curve = latent_distance_curve(z, episode, offsets)
    curve["mean_distance_normalized"] = [d / sz for d in curve["mean_distance"]]
    extras = {
        "histogram": {"bin_edges": edges.tolist(), "counts": counts.tolist(),
                      "overflow": int((ratio > edges[-1]).sum())},
        "latent_distance": curve,
        "raw_mean": float(raw.mean()), "normalized": bool(normalize),
        "scale_z": sz, "scale_z_true": szt,
        "quantiles": {str(q): float(np.quantile(ratio, q)) for q in (0.05, 0.25, 0.5, 0.75, 0.95)},
        "n_pairs": int(moving.sum()), "n_static_pairs": int((~moving).sum()),
        "bootstrap_replicates": reps,
    }
    return MetricResult(value, False, lo, hi, extras=extras)


def true_state_alpha(z_true: np.ndarray, episode: np.ndarray, static_rtol: float = 1e-10
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Per-dimension α_d = E[(z°_{n+1,d} − z°_{n,d})²] within episodes, and a static mask.

    A dimension is static when its α_d is below ``static_rtol`` times the largest α_d.
    """
    i, j = successor_index(episode, None, 1)
    if i.size == 0:
        raise DataError("no pairs of successive steps within an episode; check the episode ids")
    alpha = ((z_true[j] - z_true[i]) ** 2).mean(axis=0)
    static = alpha <= static_rtol * max(float(alpha.max()), 1e-300)
    return alpha, static


def jacobian_bound(mean_sq_step: float, dim: int, alpha: float) -> float:
    """The paper's bound (k/2)(ln E‖δz‖² − ln αk) ≥ E ln|J_g| with k = ``dim``."""
    return 0.5 * dim * (math.log(mean_sq_step) - math.log(alpha * dim))


def _check_smoothness_objective(*, k: int, alpha: str | float, **_: Any) -> None:
    """Range checks of :func:`smoothness_objective`'s parameters (the planner runs them too)."""
    check_params("smoothness_objective", k=(int(k) >= 1, f"must be >= 1, got {k}"),
                 alpha=(alpha in ("per_dim", "scalar") if isinstance(alpha, str)
                        else float(alpha) > 0,
                        f"must be 'per_dim', 'scalar' or a number > 0, got {alpha!r}"))


@metric("smoothness_objective", higher_is_better=True, rows="on_policy",
        check=_check_smoothness_objective,
        version=1,  # v1: episode resamples from resampling_stream, paired across encoders
        description="H(z) − E ln|J_g| with the paper's bound on ln|J_g| (kNN entropy, k=5)")
def smoothness_objective(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                         rng: np.random.Generator, *, k: int = 5,
                         alpha: str | float = "per_dim", n_bootstrap: int = 100
                         ) -> MetricResult:
    """The smoothness objective H(z) − E ln|J_g| (higher is better; paper Fig. 6b).

    H(z) is the Kozachenko–Leonenko kNN entropy (k = 5, nats) of z as given (no
    standardization: the objective is invariant to rescaling z, as both terms shift by
    D ln c). E ln|J_g| is replaced by the paper's upper bound (D/2)(ln E‖δz‖² − ln αD), δz the
    latent step between successive steps of one episode, D the number of non-constant latent
    dimensions. α (see the module docstring): ``"per_dim"`` (default) geometric mean of the
    per-dimension α_d of the moving true-state dimensions, static ones excluded; ``"scalar"``
    their arithmetic mean; a float is used as given (paper: 0.12). Constant z columns are
    dropped (a collapsed dimension has zero entropy and zero Jacobian; keeping it gives
    −∞ − (−∞)); a fully constant z is rejected. CI: bootstrap over episodes of the entropy
    terms and latent steps (neighbours and α held fixed).
    """
    _check_smoothness_objective(k=k, alpha=alpha)
    zv, dropped = drop_constant(z)
    if zv.shape[1] == 0:
        raise DataError("smoothness_objective: z is constant; its entropy is -inf")
    alpha_d, static = true_state_alpha(z_true, episode)
    if static.all():
        raise DataError("smoothness_objective: no true-state dimension moves within an episode")
    if isinstance(alpha, str):
        if alpha == "per_dim":
            alpha_used = float(np.exp(np.log(alpha_d[~static]).mean()))
        elif alpha == "scalar":
            alpha_used = float(alpha_d[~static].mean())
        else:
            raise DataError(f"smoothness_objective: alpha must be 'per_dim', 'scalar' or a "
                            f"positive number, got {alpha!r}")
    else:
        alpha_used = float(alpha)  # > 0: _check_smoothness_objective
    i, j = successor_index(episode, None, 1)
    step_sq = np.full(len(zv), np.nan)
    step_sq[i] = ((zv[j] - zv[i]) ** 2).sum(axis=1)
    if not np.nanmax(step_sq) > 0:
        raise DataError("smoothness_objective: z never changes between successive steps")
    dim = zv.shape[1]
    h_terms = knn_entropy_terms(zv, int(k), rng=rng)

    def objective(rows: np.ndarray) -> float:
        msq = np.nanmean(step_sq[rows])
        return float(h_terms[rows].mean() - jacobian_bound(msq, dim, alpha_used))

    entropy = float(h_terms.mean())
    mean_sq = float(np.nanmean(step_sq))
    bound = jacobian_bound(mean_sq, dim, alpha_used)
    lo, hi, reps = episode_bootstrap_replicates(objective, episode, rng, n_bootstrap)
    extras = {
        "entropy": entropy, "log_jacobian_bound": bound, "alpha": alpha_used,
        "alpha_mode": alpha if isinstance(alpha, str) else "fixed",
        "alpha_per_dim": alpha_d.tolist(), "static_true_dims": np.flatnonzero(static).tolist(),
        "mean_sq_latent_step": mean_sq, "latent_dim_used": dim,
        "dropped_constant_dims": dropped, "k": int(k), "bootstrap_replicates": reps,
    }
    return MetricResult(entropy - bound, True, lo, hi, extras=extras)
