"""Straightforward per-point reference implementations, for agreement tests and benchmarks."""

from __future__ import annotations

import numpy as np
from scipy.special import digamma


def ksg_mi_reference(x: np.ndarray, y: np.ndarray, k: int = 5) -> float:
    """KSG estimator 1, one point at a time with brute-force max-norm distances."""
    x = np.asarray(x, float).reshape(len(x), -1)
    y = np.asarray(y, float).reshape(len(y), -1)
    n = len(x)
    total = 0.0
    for i in range(n):
        dx = np.abs(x - x[i]).max(axis=1)
        dy = np.abs(y - y[i]).max(axis=1)
        d = np.maximum(dx, dy)
        d[i] = np.inf
        eps = np.partition(d, k - 1)[k - 1]
        nx = int((dx < eps).sum()) - 1  # minus the point itself
        ny = int((dy < eps).sum()) - 1
        total += digamma(nx + 1) + digamma(ny + 1)
    return float(digamma(k) + digamma(n) - total / n)


def knn_mse_reference(z: np.ndarray, z_true: np.ndarray, k: int = 5) -> float:
    """KNN-MSE by brute force: mean squared true-state distance to the k latent neighbours."""
    n = len(z)
    total = 0.0
    for i in range(n):
        d = ((z - z[i]) ** 2).sum(axis=1)
        d[i] = np.inf
        nb = np.argsort(d, kind="stable")[:k]
        total += ((z_true[nb] - z_true[i]) ** 2).sum(axis=1).mean()
    return total / n
