"""Coherence: KNN-MSE of Raffin et al. 2018 (S-RL Toolbox)."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from repbench.errors import DataError
from repbench.metric import MetricResult, metric
from repbench.metrics._common import check_params, drop_constant, episode_bootstrap_replicates

__all__ = ["coherence", "knn_mse_terms"]


def knn_mse_terms(z: np.ndarray, z_true: np.ndarray, k: int = 5) -> np.ndarray:
    """Per-sample mean of ‖z°_i − z°_j‖² over the ``k`` nearest neighbours j of i in z.

    Neighbours by Euclidean distance in z (``scipy.spatial.cKDTree``), the sample itself
    excluded; exact ties are broken by the tree's order.
    """
    n = len(z)
    if not 1 <= k < n:
        raise DataError(f"KNN-MSE needs 1 <= k < number of samples; got k={k}, n={n}")
    _, nb = cKDTree(z).query(z, k=k + 1)
    nb = nb[:, 1:]
    # If a duplicate is returned before the point itself, the point appears in its own list;
    # its distance to itself is 0 in both spaces either way, so replace it by the (k+1)-th.
    self_hit = nb == np.arange(n)[:, None]
    if self_hit.any():
        _, nb_full = cKDTree(z).query(z, k=k + 2)
        for r in np.flatnonzero(self_hit.any(1)):
            nb[r] = [c for c in nb_full[r] if c != r][:k]
    return ((z_true[nb] - z_true[:, None, :]) ** 2).sum(-1).mean(1)


def _check_coherence(*, k: int, **_: Any) -> None:
    """Range checks of :func:`coherence`'s parameters (the planner runs them too)."""
    check_params("coherence", k=(int(k) >= 1, f"must be >= 1, got {k}"))


@metric("coherence", higher_is_better=False, check=_check_coherence,
        version=2,  # v1: standardized z by default; v2: episode resamples from
        # resampling_stream, paired across encoders
        description="KNN-MSE (Raffin 2018): mean squared z° distance to the k=5 nearest in z")
def coherence(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
              *, k: int = 5, standardize_true: bool = True, standardize_z: bool = True,
              n_bootstrap: int = 100) -> MetricResult:
    """KNN-MSE: mean over samples of ‖z°_i − z°_j‖² over i's ``k`` nearest neighbours in z.

    Lower is better. With ``standardize_z`` (default) each non-constant column of z is
    standardized first: the RL agents standardize their input per dimension with fixed
    statistics (``repbench.rl.normalization``), so that is the geometry a policy sees; it also
    stops one large-scale latent dimension from deciding every neighbourhood. ``False`` uses z
    as given (Raffin et al.'s KNN-MSE on the raw latent). With
    ``standardize_true`` (default) each true-state dimension is standardized first, so that
    positions and velocities count equally; an uninformative z then scores about 2·S (S the
    number of non-constant true-state dims: 2 tr Cov for random neighbours). Constant z
    columns do not change any distance and are dropped; a fully constant z has no neighbour
    structure and scores the exact random-neighbour value, the mean over all pairs,
    2 tr Cov · n/(n − 1). CI: bootstrap over episodes of the per-sample errors (neighbours
    held fixed).
    """
    _check_coherence(k=k)
    zv, dropped = drop_constant(z)
    zt = z_true[:, np.ptp(z_true, axis=0) > 0]
    if zt.shape[1] == 0:
        raise DataError("coherence: every column of z_true is constant; nothing to measure")
    if standardize_true:
        zt = (zt - zt.mean(0)) / zt.std(0)
    n = len(zt)
    random_value = float(2 * zt.var(axis=0).sum() * n / (n - 1))
    extras = {"k": int(k), "dropped_constant_dims": dropped, "random_neighbours_value":
              random_value, "standardize_true": bool(standardize_true),
              "standardize_z": bool(standardize_z)}
    if zv.shape[1] == 0:
        return MetricResult(random_value, False, random_value, random_value,
                            extras={**extras, "note": "z is constant: random-neighbour value"})
    if standardize_z:
        zv = (zv - zv.mean(0)) / zv.std(0)
    terms = knn_mse_terms(zv, zt, int(k))
    lo, hi, reps = episode_bootstrap_replicates(lambda r: terms[r].mean(), episode, rng,
                                                n_bootstrap)
    return MetricResult(float(terms.mean()), False, lo, hi,
                        extras={**extras, "bootstrap_replicates": reps})
