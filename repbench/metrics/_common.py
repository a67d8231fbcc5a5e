"""Shared helpers of the metric functions: standardization, constant columns, bootstrap CIs.

Constant columns in ``z``: a collapsed VAE latent dimension is a legitimate representation, so the
metrics drop exactly-constant columns (they carry no information and do not change any distance)
and record them in ``extras["dropped_constant_dims"]``. Only where a metric needs at least one
varying column and ``z`` has none does it fall back to a documented worst-case value or raise a
:class:`~repbench.errors.DataError`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy import stats

from repbench.devices import resolve_device
from repbench.errors import DataError

__all__ = [
    "constant_columns",
    "drop_constant",
    "episode_bootstrap",
    "episode_bootstrap_replicates",
    "episode_rows",
    "resampling_stream",
    "resolve_device",
    "seed_from",
    "standardize",
]


def constant_columns(x: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """Boolean mask of columns whose spread is zero (relative to their magnitude)."""
    x = np.asarray(x, dtype=np.float64)
    if x.shape[0] == 0:
        return np.zeros(x.shape[1], dtype=bool)
    spread = np.ptp(x, axis=0)
    scale = np.maximum(np.abs(x).max(axis=0), 1.0)
    return spread <= rtol * scale


def drop_constant(x: np.ndarray) -> tuple[np.ndarray, list[int]]:
    """``x`` without its constant columns, and the indices of the dropped columns."""
    const = constant_columns(x)
    return x[:, ~const], [int(i) for i in np.flatnonzero(const)]


def standardize(x: np.ndarray, name: str, *, mean: np.ndarray | None = None,
                std: np.ndarray | None = None) -> np.ndarray:
    """Zero mean, unit variance per column (statistics from ``x`` unless given).

    Raises:
        DataError: a column is constant (standardization divides by its zero spread).
    """
    x = np.asarray(x, dtype=np.float64)
    if mean is None or std is None:
        const = constant_columns(x)
        if const.any():
            raise DataError(
                f"{name}: columns {np.flatnonzero(const).tolist()} are constant and cannot be "
                "standardized; drop them first"
            )
        mean, std = x.mean(axis=0), x.std(axis=0)
    return (x - mean) / std


def episode_rows(episode: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Unique episode ids and, for each, the row indices that belong to it."""
    ids, inverse = np.unique(episode, return_inverse=True)
    order = np.argsort(inverse, kind="stable")
    bounds = np.cumsum(np.bincount(inverse, minlength=ids.size))[:-1]
    return ids, np.split(order, bounds)


def episode_bootstrap(statistic: Callable[[np.ndarray], float], episode: np.ndarray,
                      rng: np.random.Generator, n_bootstrap: int = 100,
                      confidence: float = 0.95) -> tuple[float | None, float | None]:
    """Percentile bootstrap CI of ``statistic(rows)``, resampling whole episodes.

    ``statistic`` receives an index array of rows (episodes drawn with replacement, their rows
    concatenated) and returns a float. Resampling episodes rather than rows keeps the temporal
    correlation inside an episode, so the interval is not too narrow. With fewer than two
    episodes the rows themselves are resampled (the interval is then optimistic). Returns
    ``(None, None)`` when ``n_bootstrap`` is 0. Uses :func:`scipy.stats.bootstrap`.
    """
    lo, hi, _ = episode_bootstrap_replicates(statistic, episode, rng, n_bootstrap, confidence)
    return lo, hi


def episode_bootstrap_replicates(statistic: Callable[[np.ndarray], float], episode: np.ndarray,
                                 rng: np.random.Generator, n_bootstrap: int = 100,
                                 confidence: float = 0.95
                                 ) -> tuple[float | None, float | None, list[float]]:
    """:func:`episode_bootstrap` plus the bootstrap replicates themselves (a list of floats).

    Metrics store the replicates in ``extras["bootstrap_replicates"]`` so that the correlation
    analysis can carry each encoder's metric estimation noise
    (:mod:`repbench.analysis.correlation`).
    """
    if n_bootstrap <= 0:
        return None, None, []
    rng = resampling_stream(rng)
    ids, rows = episode_rows(episode)
    if ids.size < 2:
        rows = [np.array([i]) for i in range(len(episode))]

    def stat(group_idx: np.ndarray) -> float:
        return float(statistic(np.concatenate([rows[g] for g in group_idx.astype(int)])))

    res = stats.bootstrap(
        (np.arange(len(rows)),), stat, n_resamples=int(n_bootstrap), vectorized=False,
        method="percentile", confidence_level=confidence, random_state=rng,
    )
    reps = [float(v) for v in np.asarray(res.bootstrap_distribution).ravel()
            if np.isfinite(v)]
    lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return None, None, reps
    return lo, hi, reps


#: spawn key of the episode-resampling stream (any fixed value; "b007" reads "boot")
RESAMPLING_KEY = 0xB007


def resampling_stream(rng: np.random.Generator) -> np.random.Generator:
    """The stream that draws a metric's episode resamples: a fixed child of ``rng``'s seed.

    It depends on the seed ``rng`` was created from, not on how much of ``rng`` the metric has
    used already (jitter and noise draws grow with the latent size). So every encoder scored
    with the same seed on the same held-out episodes gets the same resamples, and its bootstrap
    replicate b is paired with every other encoder's replicate b (the correlation analysis draws
    one replicate index for all encoders). A generator without a seed sequence is returned as
    it is.
    """
    seq = getattr(rng.bit_generator, "seed_seq", None)
    if not isinstance(seq, np.random.SeedSequence):
        return rng
    child = np.random.SeedSequence(seq.entropy, spawn_key=(*seq.spawn_key, RESAMPLING_KEY),
                                   pool_size=seq.pool_size)
    return np.random.default_rng(child)


def seed_from(rng: np.random.Generator) -> int:
    """A 31-bit integer seed drawn from ``rng`` (for torch / scikit-learn)."""
    return int(rng.integers(0, 2**31 - 1))


def check_params(name: str, **checks: tuple[bool, str]) -> None:
    """Raise a one-line ConfigError for the first failed ``(condition, message)``."""
    from repbench.errors import ConfigError

    for param, (ok, msg) in checks.items():
        if not ok:
            raise ConfigError(f"{name}: parameter {param!r} {msg}")
