"""Closed-form answers. Tolerances were measured over 10 seeds (max |error| given per test)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from repbench.metrics.coherence import coherence
from repbench.metrics.mutual_information import (
    gaussian_entropy,
    gaussian_mi,
    knn_entropy,
    ksg,
    ksg_mi,
    mi_noisy,
    mine,
)
from repbench.metrics.regression import regression
from repbench.metrics.smoothness import smoothness, smoothness_objective
from repbench.testing.metric import synthetic_true_state

from ._reference import knn_mse_reference, ksg_mi_reference

COV4 = np.array([[1, .6, .5, .1], [.6, 1, .2, .4], [.5, .2, 1, .3], [.1, .4, .3, 1]])


def test_ksg_matches_per_point_reference_exactly() -> None:
    rng = np.random.default_rng(0)
    x = rng.standard_normal((400, 3))
    y = x[:, :2] + 0.5 * rng.standard_normal((400, 2))
    assert ksg_mi(x, y, k=5, jitter=0) == pytest.approx(ksg_mi_reference(x, y, 5), abs=1e-12)


def test_ksg_matches_scikit_learn_in_1d() -> None:
    from sklearn.feature_selection._mutual_info import _compute_mi_cc

    rng = np.random.default_rng(1)
    a = rng.standard_normal(600)
    b = a + rng.standard_normal(600)
    assert ksg_mi(a, b, k=3, jitter=0) == pytest.approx(_compute_mi_cc(a, b, 3), abs=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ksg_zero_for_independent(seed: int) -> None:
    rng = np.random.default_rng(seed)
    # measured max |MI| 0.023 over 10 seeds at n=2000, 2+2 dims
    assert abs(ksg_mi(rng.standard_normal((2000, 2)), rng.standard_normal((2000, 2)))) < 0.05


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ksg_gaussian_closed_form(seed: int) -> None:
    rng = np.random.default_rng(seed)
    xy = rng.multivariate_normal(np.zeros(4), COV4, 2000)
    # measured max |error| 0.052 over 10 seeds (true MI 0.297 nats)
    assert ksg_mi(xy[:, :2], xy[:, 2:]) == pytest.approx(gaussian_mi(COV4, 2), abs=0.08)


def test_ksg_invariant_to_invertible_elementwise_transform() -> None:
    rng = np.random.default_rng(4)
    xy = rng.multivariate_normal(np.zeros(4), COV4, 2000)
    ep = np.repeat(np.arange(20), 100)
    plain = ksg(xy[:, :2], xy[:, 2:], ep, 0, n_bootstrap=0).value
    warped = ksg(np.exp(xy[:, :2]), np.tanh(xy[:, 2:]) ** 3, ep, 0, n_bootstrap=0).value
    # invariance is asymptotic for KSG; measured max |difference| 0.067 over 10 seeds, n=2000
    assert warped == pytest.approx(plain, abs=0.1)


@pytest.mark.parametrize("seed", [0, 1])
def test_knn_entropy_gaussian(seed: int) -> None:
    rng = np.random.default_rng(seed)
    cov = COV4[:3, :3]
    x = rng.multivariate_normal(np.zeros(3), cov, 2000)
    # measured errors -0.03 .. -0.10 over 10 seeds (slightly biased low), n=2000, d=3
    assert knn_entropy(x) == pytest.approx(gaussian_entropy(cov), abs=0.15)


def test_knn_entropy_scaling_exact() -> None:
    x = np.random.default_rng(5).standard_normal((1000, 3))
    assert knn_entropy(2.5 * x) - knn_entropy(x) == pytest.approx(3 * math.log(2.5), abs=1e-9)


@pytest.mark.parametrize("seed", [0, 1])
def test_mi_noisy_linear_gaussian_channel(seed: int) -> None:
    rng = np.random.default_rng(seed)
    zt = rng.standard_normal((2000, 2)) @ np.array([[1.0, 0.5], [0.0, 1.0]])
    z = zt @ np.array([[2.0, 1.0], [-1.0, 1.0]])
    corr = np.corrcoef(z.T)
    closed = 0.5 * np.linalg.slogdet(np.eye(2) + corr / 0.5**2)[1]  # 1.557 nats
    res = mi_noisy(z, zt, np.repeat(np.arange(20), 100), seed, noise=0.5, n_bootstrap=0)
    # measured errors -0.06 .. 0.00 over 10 seeds (KSG biased slightly low)
    assert res.value == pytest.approx(closed, abs=0.1)
    assert res.value <= res.extras["channel_capacity"]


@pytest.mark.slow
def test_mine_gaussian_closed_form() -> None:
    rng = np.random.default_rng(0)
    xy = rng.multivariate_normal(np.zeros(4), COV4, 4000)
    ep = np.repeat(np.arange(40), 100)
    res = mine(xy[:, :2], xy[:, 2:], ep, 0, steps=3000, learning_rate=1e-3, n_bootstrap=0)
    # true 0.297; measured 0.254, 0.233, 0.333 for data seeds 0, 1, 2 (this test uses seed 0)
    assert gaussian_mi(COV4, 2) - 0.1 < res.value < gaussian_mi(COV4, 2) + 0.05


def test_mine_zero_for_independent() -> None:
    rng = np.random.default_rng(0)
    ep = np.repeat(np.arange(20), 100)
    res = mine(rng.standard_normal((2000, 2)), rng.standard_normal((2000, 2)), ep, 0,
               steps=600, learning_rate=1e-3, eval_every=100, n_bootstrap=0)
    assert abs(res.value) < 0.05  # measured -0.01: held-out DV bound of an overfit T is <= 0


def test_coherence_identity_vs_shuffled() -> None:
    rng = np.random.default_rng(0)
    zt = rng.standard_normal((3000, 3)) * np.array([1.0, 2.0, 0.5])
    ep = np.repeat(np.arange(30), 100)
    shuffled = coherence(zt[rng.permutation(3000)], zt, ep, 0, standardize_true=False,
                         n_bootstrap=0).value
    identity = coherence(zt, zt, ep, 0, standardize_true=False, n_bootstrap=0).value
    two_tr_cov = 2 * np.trace(np.cov(zt.T))  # 10.5
    # measured relative error of the shuffled value 0.02 (sampling error of 3000 x 5 pairs)
    assert shuffled == pytest.approx(two_tr_cov, rel=0.06)
    assert identity < 0.02 * two_tr_cov  # measured 0.05 vs 10.5


def test_coherence_matches_brute_force() -> None:
    rng = np.random.default_rng(1)
    z, zt = rng.standard_normal((300, 4)), rng.standard_normal((300, 3))
    res = coherence(z, zt, np.zeros(300, int), 0, standardize_true=False, standardize_z=False,
                    n_bootstrap=0)
    assert res.value == pytest.approx(knn_mse_reference(z, zt, 5), rel=1e-12)


def test_coherence_standardizes_z_as_the_policy_does() -> None:
    rng = np.random.default_rng(2)
    z, zt = rng.standard_normal((300, 4)) * [1.0, 50.0, 0.1, 3.0], rng.standard_normal((300, 3))
    res = coherence(z, zt, np.zeros(300, int), 0, standardize_true=False, n_bootstrap=0)
    zs = (z - z.mean(0)) / z.std(0)
    assert res.value == pytest.approx(knn_mse_reference(zs, zt, 5), rel=1e-12)
    # per-dimension rescaling of z no longer changes the neighbourhoods
    again = coherence(z * [7.0, 0.01, 3.0, 1.0], zt, np.zeros(300, int), 0,
                      standardize_true=False, n_bootstrap=0)
    assert again.value == pytest.approx(res.value, rel=1e-9)


def test_coherence_constant_z_is_random_neighbour_value() -> None:
    zt, ep = synthetic_true_state(6, 30)
    res = coherence(np.ones((len(zt), 3)), zt, ep, 0)
    assert res.value == pytest.approx(2 * zt.shape[1] * len(zt) / (len(zt) - 1))


def test_regression_invertible_vs_noise() -> None:
    zt, ep = synthetic_true_state(20, 100, dynamic_dims=4, static_dims=0, seed=1)
    rng = np.random.default_rng(0)
    q = np.linalg.qr(rng.standard_normal((4, 4)))[0]
    inv = regression(np.tanh(zt @ q), zt, ep, 0, random_split=False, n_bootstrap=0)
    noise = regression(rng.standard_normal(zt.shape), zt, ep, 0, random_split=False,
                       n_bootstrap=0)
    # measured: invertible 0.07 (R² per dim 0.86-0.98), independent noise > 1 (held-out
    # episodes, overfit MLP)
    assert inv.value < 0.15
    assert noise.value > 0.9
    assert all(r is not None and r > 0.8 for r in inv.extras["r2_per_dim"])


def test_jacobian_bound_exact_for_scaled_rotation() -> None:
    rng = np.random.default_rng(0)
    steps = rng.standard_normal((20, 300, 4)) * 0.1  # isotropic true-state steps
    zt = np.cumsum(steps, axis=1).reshape(-1, 4)
    ep = np.repeat(np.arange(20), 300)
    q = np.linalg.qr(rng.standard_normal((4, 4)))[0]
    c = 3.0
    res = smoothness_objective(c * zt @ q.T + 1.5, zt, ep, 0, n_bootstrap=0)
    # ln|J| = 4 ln 3; measured |bound - 4 ln c| = 0.001 (AM-GM gap of the estimated alpha_d)
    assert res.extras["log_jacobian_bound"] == pytest.approx(4 * math.log(c), abs=0.01)
    base = smoothness_objective(zt, zt, ep, 0, n_bootstrap=0)
    # the objective is invariant to the scale c (entropy and bound both shift by 4 ln c);
    # measured difference 0.03 (rotation changes the max-norm kNN entropy slightly)
    assert res.value == pytest.approx(base.value, abs=0.1)


def test_smoothness_identity_is_one_and_static_dims_handled() -> None:
    zt, ep = synthetic_true_state(8, 50)  # 2 static dims
    res = smoothness(zt, zt, ep, 0, n_bootstrap=0)
    assert res.value == pytest.approx(1.0)
    obj = smoothness_objective(zt, zt, ep, 0, n_bootstrap=0)
    assert obj.extras["static_true_dims"] == [6, 7]
    assert np.isfinite(obj.value)
    fixed = smoothness_objective(zt, zt, ep, 0, alpha=0.12, n_bootstrap=0)
    assert fixed.extras["alpha"] == 0.12 and np.isfinite(fixed.value)
