"""Observable metrics: what a real robot can compute (issue 55's pre-registered candidates).

Each reads only what a robot logs — z (its observations encoded), the robot state r, the action
a, the reward and the episode ids — and ignores ``z_true`` (group ``"observable"``; none asks
for ``task_state``). Parameters and defaults are those of
``studies/metric_search/preregistration.md``.

Spectral (label-free) metrics of z alone:

* ``rankme`` — RankMe (Garrido et al. 2023): exp of the entropy of z's normalized singular
  values, p_k = σ_k / Σσ + ε (z as encoded, not centred), ε = 1e-7.
* ``alpha_req`` — α-ReQ (Agrawal et al. 2022): −|α − 1|, α the least-squares slope of
  −log λ_i against log i over the nonzero eigenvalues λ_1 ≥ … of z's covariance (α = 1 is the
  power law the paper finds best).
* ``nesum`` — NESum (He & Ozay 2022): Σ_i λ_i / λ_1 of z's covariance.

Predictive (held-out, linear) metrics: scikit-learn ``RidgeCV`` on standardized inputs and
targets of the training episodes, out-of-sample R² on whole held-out episodes (70/30), pooled
over the target's standardized columns (:func:`~repbench.metrics.task_information.held_out_r2`):

* ``forward_r2`` — z_{t+1} from (z_t, a_t) (latent forward dynamics).
* ``inverse_r2`` — a_t from (z_t, z_{t+1}) (inverse dynamics).
* ``value_probe`` — the discounted return-to-go G_t = Σ_{k=0}^{T−t−1} γ^k r_{t+k} (γ = 0.99,
  truncated at the episode's end) from z ⊕ r, on-policy rows.
* ``value_probe_gain`` — ``value_probe`` minus the same probe's R² from r alone.
* ``reward_probe_gain`` — R² of the reward r_t from z_t ⊕ r_t minus from r_t alone, all rows.

Pairs (t, t + 1) never straddle episodes (:func:`repbench.dataset.successor_index`).
Intervals: the spectral metrics resample whole episodes and recompute, the replicates centred on
the value (:func:`_spectral_result`); the probes resample the held-out episodes with the fitted
models held fixed. ``extras["bootstrap_replicates"]`` holds
the replicates (:mod:`repbench.analysis.correlation`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.signal import lfilter

from repbench.dataset import episode_split, successor_index
from repbench.errors import DataError
from repbench.metric import MetricResult, metric
from repbench.metrics._common import (
    check_params,
    drop_constant,
    episode_bootstrap_replicates,
    episode_rows,
    seed_from,
)
from repbench.metrics.task_information import held_out_r2, r2_of

__all__ = [
    "alpha_req",
    "covariance_spectrum",
    "forward_r2",
    "inverse_r2",
    "nesum",
    "rankme",
    "rankme_of",
    "return_to_go",
    "reward_probe_gain",
    "value_probe",
    "value_probe_gain",
]


# --- spectral metrics ------------------------------------------------------------------------

def rankme_of(z: np.ndarray, eps: float = 1e-7) -> float:
    """RankMe of ``z`` as given (not centred): exp(−Σ_k p_k ln p_k), p_k = σ_k / Σ_j σ_j + ε.

    σ are the singular values of ``z`` (min(N, D) of them). A zero ``z`` (Σσ = 0, σ/Σσ
    undefined) gives NaN.
    """
    sv = np.linalg.svd(z, compute_uv=False)
    total = float(sv.sum())
    if total <= 0:
        return math.nan
    p = sv / total + eps
    return float(np.exp(-np.sum(p * np.log(p))))


def covariance_spectrum(z: np.ndarray) -> np.ndarray:
    """Eigenvalues of z's sample covariance, largest first, numerically-zero ones dropped.

    Zero means at most λ_max · D · machine ε (numpy's ``matrix_rank`` tolerance).
    """
    lam = np.linalg.eigvalsh(np.atleast_2d(np.cov(z, rowvar=False)))[::-1]
    tol = max(float(lam[0]), 0.0) * lam.size * np.finfo(np.float64).eps
    return lam[lam > tol]


def _alpha_of(lam: np.ndarray) -> float:
    """α of the power law λ_i ∝ i^−α: −(least-squares slope of ln λ_i on ln i), i = 1..k."""
    ranks = np.arange(1, lam.size + 1, dtype=np.float64)
    slope = np.polyfit(np.log(ranks), np.log(lam), 1)[0]
    return float(-slope)


def _spectral_result(statistic: Any, z: np.ndarray, episode: np.ndarray,
                     rng: np.random.Generator, n_bootstrap: int, extras: dict[str, Any]
                     ) -> MetricResult:
    """Value on every row; interval and replicates from a median-centred episode bootstrap.

    Resampling whole episodes with replacement duplicates some of them, which spreads the
    resampled covariance's spectrum and biases a spectral statistic (RankMe and NESum down):
    on 10 episodes the plain percentile interval can lie wholly below the value. Each replicate
    is therefore shifted by ``value − median(replicates)``: the bootstrap's spread (what the
    correlation analysis carries as estimation noise) is kept, its resampling bias removed, and
    the 95 % percentile interval of the shifted replicates brackets the value.
    """
    value = float(statistic(np.arange(len(z))))
    _, _, raw = episode_bootstrap_replicates(statistic, episode, rng, n_bootstrap)
    lo = hi = None
    reps: list[float] = []
    shift = 0.0
    if raw:
        shift = value - float(np.median(raw))
        reps = [r + shift for r in raw]
        lo, hi = (float(q) for q in np.percentile(reps, [2.5, 97.5]))
    return MetricResult(value, True, lo, hi,
                        extras={**extras, "n_samples": len(z), "bootstrap_replicates": reps,
                                "bootstrap_bias_shift": shift})


def _check_rankme(*, eps: float, **_: Any) -> None:
    """Range checks of :func:`rankme`'s parameters (the planner runs them too)."""
    check_params("rankme", eps=(0 < float(eps) < 1, f"must be in (0, 1), got {eps}"))


@metric("rankme", higher_is_better=True, group="observable", check=_check_rankme,
        description="RankMe (Garrido et al. 2023): exp entropy of z's normalized singular values")
def rankme(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
           *, eps: float = 1e-7, n_bootstrap: int = 100) -> MetricResult:
    """RankMe (Garrido et al. 2023, eq. 1), the smooth effective rank of z (higher is better).

    exp(−Σ_k p_k ln p_k) with p_k = σ_k / ‖σ‖₁ + ε, σ the singular values of z as encoded (not
    centred, constant columns kept: a constant nonzero column is a direction z spans).
    Between ~1 and min(N, D): an isotropic D-dimensional z scores ≈ D, a rank-k one ≈ k.
    Label-free: noise maximizes it. CI: median-centred percentile bootstrap over episodes.
    ``z_true`` is not used.

    Raises:
        DataError: z is zero everywhere (the normalization σ/Σσ is 0/0).
    """
    _check_rankme(eps=eps)
    if not np.any(z):
        raise DataError("rankme: z is constant zero (every singular value 0), so σ/Σσ is 0/0; "
                        "the encoder's output has collapsed")
    return _spectral_result(lambda rows: rankme_of(z[rows], eps), z, episode, rng, n_bootstrap,
                            {"eps": float(eps), "dims": int(z.shape[1])})


@metric("alpha_req", higher_is_better=True, group="observable",
        description="α-ReQ (Agrawal et al. 2022): −|α − 1|, α the eigenspectrum decay of z")
def alpha_req(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
              *, n_bootstrap: int = 100) -> MetricResult:
    """α-ReQ (Agrawal et al. 2022): how close z's eigenspectrum decay is to λ_i ∝ i^−1.

    α is minus the least-squares slope of ln λ_i on ln i, λ_1 ≥ … ≥ λ_k the nonzero
    eigenvalues of z's sample covariance (ranks 1..D, numerically-zero eigenvalues dropped:
    :func:`covariance_spectrum`). Value −|α − 1| (higher is better, 0 best);
    ``extras["alpha"]`` is α itself (small: whitened, spread over all dimensions; large: a few
    dimensions dominate). CI: median-centred percentile bootstrap over episodes.

    Raises:
        DataError: z's covariance has fewer than two nonzero eigenvalues (no slope).
    """
    lam = covariance_spectrum(z)
    if lam.size < 2:
        raise DataError(f"alpha_req: z's covariance has {lam.size} nonzero eigenvalue(s); the "
                        "decay slope needs at least 2 (z is constant or of rank 1)")

    def stat(rows: np.ndarray) -> float:
        spec = covariance_spectrum(z[rows])
        return -abs(_alpha_of(spec) - 1.0) if spec.size >= 2 else math.nan

    alpha = _alpha_of(lam)
    return _spectral_result(stat, z, episode, rng, n_bootstrap,
                            {"alpha": alpha, "eigenvalues": lam.tolist(),
                             "n_nonzero_eigenvalues": int(lam.size), "dims": int(z.shape[1])})


@metric("nesum", higher_is_better=True, group="observable",
        description="NESum (He & Ozay 2022): Σ λ_i / λ_1 of z's covariance eigenvalues")
def nesum(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
          *, n_bootstrap: int = 100) -> MetricResult:
    """NESum (He & Ozay 2022): the sum of z's covariance eigenvalues normalized by the largest,
    Σ_i λ_i / λ_1 (higher is better; identity covariance scores D, one dominant direction ≈ 1).

    A constant z scores 0 (no direction at all, the documented worst case). Label-free: noise
    maximizes it. CI: median-centred percentile bootstrap over episodes. ``z_true`` is not used.
    """
    def stat(rows: np.ndarray) -> float:
        lam = covariance_spectrum(z[rows])
        return float(lam.sum() / lam[0]) if lam.size else 0.0

    return _spectral_result(stat, z, episode, rng, n_bootstrap, {"dims": int(z.shape[1])})


# --- predictive probes -----------------------------------------------------------------------

def _check_probe(name: str) -> Any:
    """Range checks of probe ``name``'s parameters (the planner runs them too)."""
    def check(*, test_fraction: float, gamma: float = 0.99, **_: Any) -> None:
        check_params(name, test_fraction=(0 < float(test_fraction) < 1, "must be in (0, 1)"),
                     gamma=(0 <= float(gamma) <= 1, f"must be in [0, 1], got {gamma}"))

    return check


def _ridge_r2(name: str, x: np.ndarray, x_base: np.ndarray | None, y: np.ndarray,
              episode: np.ndarray, rng: np.random.Generator, *, test_fraction: float,
              n_bootstrap: int, gain: bool, extras: dict[str, Any]) -> MetricResult:
    """Held-out ridge R² of ``y`` from ``x`` (``gain``: minus the R² from ``x_base``).

    Whole episodes of ``episode`` (one id per row of x, y) are held out; the interval resamples
    the held-out episodes with the models held fixed.
    """
    yv = y[:, np.ptp(y, axis=0) > 0]
    if yv.shape[1] == 0:
        raise DataError(f"{name}: every column of the target is constant; nothing to predict")
    train, test = episode_split(episode, test_fraction, seed_from(rng))
    err, dev = held_out_r2(x, yv, train, test, model="ridge")
    err_b = None if x_base is None else held_out_r2(x_base, yv, train, test, model="ridge")[0]
    if float(dev.sum()) <= 0:
        raise DataError(f"{name}: R² is not finite; the held-out target is constant")

    def stat(rows: np.ndarray) -> float:
        r2 = r2_of(err[rows], dev[rows])
        return r2 - r2_of(err_b[rows], dev[rows]) if gain and err_b is not None else r2

    value = stat(np.arange(test.size))
    lo, hi, reps = episode_bootstrap_replicates(stat, episode[test], rng, n_bootstrap)
    notes: dict[str, Any] = {**extras, "r2": r2_of(err, dev)}
    if err_b is not None:
        notes["r2_robot_only"] = r2_of(err_b, dev)
        notes["gain_over_robot"] = notes["r2"] - notes["r2_robot_only"]
    notes.update({"model": "ridge", "n_train": int(train.size), "n_test": int(test.size),
                  "split": "whole episodes held out", "test_fraction": float(test_fraction),
                  "bootstrap_replicates": reps})
    return MetricResult(float(value), True, lo, hi, extras=notes)


def _need(name: str, **arrays: np.ndarray | None) -> None:
    missing = [k for k, v in arrays.items() if v is None]
    if missing:
        given = " and ".join(f"{k}=" for k in missing)
        raise DataError(f"{name}: needs {given} array(s) (the latents stage stores them; "
                        "re-run it or export-latents if the store predates them)")


def _pairs(name: str, episode: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows (t, t + 1) of one episode; a clear error when there are none."""
    i, j = successor_index(episode, None, 1)
    if i.size < 2:
        raise DataError(f"{name}: needs successive steps within episodes, found {i.size} "
                        "pair(s); rows must be ordered by (episode, step)")
    return i, j


@metric("forward_r2", higher_is_better=True, group="observable",
        check=_check_probe("forward_r2"),
        description="Held-out ridge R² of z_t+1 from (z_t, a_t): latent forward dynamics")
def forward_r2(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
               *, action: np.ndarray | None = None, test_fraction: float = 0.3,
               n_bootstrap: int = 100) -> MetricResult:
    """Latent forward-dynamics predictability: held-out R² of z_{t+1} from z_t ⊕ a_t.

    Ridge (``RidgeCV``) on standardized inputs and standardized targets of the training
    episodes (70 %), out-of-sample R² pooled over z's varying columns on the held-out episodes
    (higher is better; 1 = z evolves linearly given the action, ≈ 0 = unpredictable noise).
    Pairs never straddle episodes; constant columns of z and a are dropped.
    CI: bootstrap over held-out episodes. ``z_true`` is not used.
    """
    _check_probe("forward_r2")(test_fraction=test_fraction)
    _need("forward_r2", action=action)
    i, j = _pairs("forward_r2", episode)
    zv, dropped = drop_constant(z)
    av, dropped_a = drop_constant(action)
    return _ridge_r2("forward_r2", np.hstack([zv[i], av[i]]), None, zv[j], episode[i], rng,
                     test_fraction=test_fraction, n_bootstrap=n_bootstrap, gain=False,
                     extras={"dropped_constant_dims": dropped,
                             "dropped_constant_action_dims": dropped_a,
                             "n_pairs": int(i.size)})


@metric("inverse_r2", higher_is_better=True, group="observable",
        check=_check_probe("inverse_r2"),
        description="Held-out ridge R² of a_t from (z_t, z_t+1): inverse dynamics")
def inverse_r2(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
               *, action: np.ndarray | None = None, test_fraction: float = 0.3,
               n_bootstrap: int = 100) -> MetricResult:
    """Action predictability (inverse dynamics): held-out R² of a_t from z_t ⊕ z_{t+1}.

    Ridge as :func:`forward_r2`, R² pooled over the action's varying columns (higher is
    better; 1 = the step in z determines the action linearly). Pairs never straddle episodes.
    CI: bootstrap over held-out episodes. ``z_true`` is not used.
    """
    _check_probe("inverse_r2")(test_fraction=test_fraction)
    _need("inverse_r2", action=action)
    i, j = _pairs("inverse_r2", episode)
    zv, dropped = drop_constant(z)
    return _ridge_r2("inverse_r2", np.hstack([zv[i], zv[j]]), None, action[i], episode[i], rng,
                     test_fraction=test_fraction, n_bootstrap=n_bootstrap, gain=False,
                     extras={"dropped_constant_dims": dropped, "n_pairs": int(i.size)})


def return_to_go(reward: np.ndarray, episode: np.ndarray, gamma: float = 0.99) -> np.ndarray:
    """G_t = Σ_{k=0}^{T−t−1} γ^k r_{t+k} within each episode, truncated at its last row.

    Rows are ordered by (episode, step); ``reward`` is ``[N]`` or ``[N, 1]``.
    """
    r = np.asarray(reward, dtype=np.float64).reshape(len(episode))
    out = np.empty_like(r)
    for rows in episode_rows(episode)[1]:
        out[rows] = lfilter([1.0], [1.0, -float(gamma)], r[rows][::-1])[::-1]
    return out


def _reward_column(name: str, reward: np.ndarray) -> np.ndarray:
    r = np.asarray(reward, dtype=np.float64)
    if r.ndim == 2 and r.shape[1] != 1:
        raise DataError(f"{name}: reward must be one number per row ([N] or [N, 1]), got shape "
                        f"{r.shape}")
    return r.reshape(-1)


def _value_probe(name: str, z: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
                 robot_state: np.ndarray | None, reward: np.ndarray | None, gamma: float,
                 test_fraction: float, n_bootstrap: int, gain: bool) -> MetricResult:
    _check_probe(name)(test_fraction=test_fraction, gamma=gamma)
    _need(name, robot_state=robot_state, reward=reward)
    g = return_to_go(_reward_column(name, reward), episode, gamma)
    zv, dropped = drop_constant(z)
    rv, dropped_r = drop_constant(robot_state)
    return _ridge_r2(name, np.hstack([zv, rv]), rv, g[:, None], episode, rng,
                     test_fraction=test_fraction, n_bootstrap=n_bootstrap, gain=gain,
                     extras={"gamma": float(gamma), "dropped_constant_dims": dropped,
                             "dropped_constant_robot_dims": dropped_r})


@metric("value_probe", higher_is_better=True, group="observable", rows="on_policy",
        check=_check_probe("value_probe"),
        description="Held-out ridge R² of the discounted return-to-go (γ 0.99) from z ⊕ robot "
                    "state")
def value_probe(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
                *, robot_state: np.ndarray | None = None, reward: np.ndarray | None = None,
                gamma: float = 0.99, test_fraction: float = 0.3, n_bootstrap: int = 100
                ) -> MetricResult:
    """Value probe: held-out R² of the on-policy return-to-go from z ⊕ robot state.

    G_t = Σ_{k=0}^{T−t−1} γ^k r_{t+k} within the episode, truncated at its end
    (:func:`return_to_go`); ridge on standardized z ⊕ r and G of the training episodes,
    out-of-sample R² on the held-out ones (higher is better). On-policy rows (the metric stage
    selects them), so G estimates the behaviour policy's value. ``extras["r2_robot_only"]`` is
    the probe's R² from r alone. CI: bootstrap over held-out episodes. ``z_true`` is not used.
    """
    return _value_probe("value_probe", z, episode, rng, robot_state, reward, gamma,
                        test_fraction, n_bootstrap, gain=False)


@metric("value_probe_gain", higher_is_better=True, group="observable", rows="on_policy",
        check=_check_probe("value_probe_gain"),
        description="value_probe's R² from z ⊕ robot state minus its R² from the robot state")
def value_probe_gain(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                     rng: np.random.Generator, *, robot_state: np.ndarray | None = None,
                     reward: np.ndarray | None = None, gamma: float = 0.99,
                     test_fraction: float = 0.3, n_bootstrap: int = 100) -> MetricResult:
    """R²(G | z ⊕ r) − R²(G | r) on held-out episodes, G the return-to-go of
    :func:`value_probe` (higher is better; 0 = z adds nothing to the robot state about the
    value). Same split and ridge as ``value_probe``. CI: bootstrap over held-out episodes of
    the difference (models held fixed). ``z_true`` is not used.
    """
    return _value_probe("value_probe_gain", z, episode, rng, robot_state, reward, gamma,
                        test_fraction, n_bootstrap, gain=True)


@metric("reward_probe_gain", higher_is_better=True, group="observable",
        check=_check_probe("reward_probe_gain"),
        description="Held-out ridge R² of the reward from z ⊕ robot state minus from robot state")
def reward_probe_gain(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                      rng: np.random.Generator, *, robot_state: np.ndarray | None = None,
                      reward: np.ndarray | None = None, test_fraction: float = 0.3,
                      n_bootstrap: int = 100) -> MetricResult:
    """R²(reward_t | z_t ⊕ r_t) − R²(reward_t | r_t) on held-out episodes (higher is better;
    0 = z adds nothing to the robot state about the reward).

    Ridge on standardized inputs and reward of the training episodes, all stored rows.
    CI: bootstrap over held-out episodes of the difference (models held fixed).
    ``z_true`` is not used.
    """
    name = "reward_probe_gain"
    _check_probe(name)(test_fraction=test_fraction)
    _need(name, robot_state=robot_state, reward=reward)
    zv, dropped = drop_constant(z)
    rv, dropped_r = drop_constant(robot_state)
    return _ridge_r2(name, np.hstack([zv, rv]), rv, _reward_column(name, reward)[:, None],
                     episode, rng, test_fraction=test_fraction, n_bootstrap=n_bootstrap,
                     gain=True, extras={"dropped_constant_dims": dropped,
                                        "dropped_constant_robot_dims": dropped_r})
