"""Known answers for the complementary-task-information and probe metrics.

Closed forms for the Frenzel–Pompe CMI estimator; known orderings on a peg-like synthetic
dataset (tests/metrics/_peg_like.py). Tolerances were measured over seeds 0-9 (CMI) or 0-4
(orderings) with the commands in NOTES-issue13.md; the measured ranges are in the comments.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import digamma

from repbench.errors import DataError
from repbench.metric import Metric, MetricResult
from repbench.metrics.mutual_information import gaussian_mi, ksg_mi
from repbench.metrics.probes import action_probe, task_probe
from repbench.metrics.task_information import (
    complementary_columns,
    gaussian_cmi,
    knn_cmi,
    task_cmi,
    task_r2_gain,
)

from ._peg_like import peg_like


def _cmi_reference(x: np.ndarray, y: np.ndarray, w: np.ndarray, k: int) -> float:
    """Frenzel–Pompe by brute force, one sample at a time (max norm, strict counts)."""
    xyw, xw, yw = np.hstack([x, y, w]), np.hstack([x, w]), np.hstack([y, w])
    total = 0.0
    for i in range(len(x)):
        d = np.abs(xyw - xyw[i]).max(1)
        d[i] = np.inf
        eps = np.sort(d)[k - 1]

        def count(a: np.ndarray, i: int = i, eps: float = eps) -> int:
            return int((np.abs(a - a[i]).max(1) < eps).sum()) - 1

        total += digamma(k) - digamma(count(xw) + 1) - digamma(count(yw) + 1) + digamma(
            count(w) + 1)
    return total / len(x)


def test_knn_cmi_matches_brute_force_reference_exactly() -> None:
    rng = np.random.default_rng(0)
    v = rng.standard_normal((400, 5))
    v[:, 2] += v[:, 0] + v[:, 3]
    x, y, w = v[:, :2], v[:, 2:3], v[:, 3:]
    assert knn_cmi(x, y, w, k=5, jitter=0) == pytest.approx(_cmi_reference(x, y, w, 5),
                                                            abs=1e-12)


def test_knn_cmi_without_condition_is_ksg() -> None:
    rng = np.random.default_rng(0)
    x = rng.standard_normal((500, 2))
    y = x[:, :1] + rng.standard_normal((500, 1))
    assert knn_cmi(x, y, np.zeros((500, 0)), jitter=0) == pytest.approx(
        ksg_mi(x, y, jitter=0), abs=1e-12)


def test_gaussian_cmi_is_the_chain_rule() -> None:
    rng = np.random.default_rng(3)
    a = rng.standard_normal((5, 5))
    cov = a @ a.T + 0.5 * np.eye(5)
    # I(x; y | w) = I(x; (y, w)) − I(x; w), x = dims 0-1, y = 2, w = 3-4
    chain = gaussian_mi(cov, 2) - gaussian_mi(cov[np.ix_([0, 1, 3, 4], [0, 1, 3, 4])], 2)
    assert gaussian_cmi(cov, 2, 1) == pytest.approx(chain, abs=1e-12)


def test_knn_cmi_gaussian_one_dimension_each() -> None:
    # x = w + e1, y = w + 1.5 e1 + e2, w: closed form 0.589 nats
    lmat = np.array([[1.0, 1.0, 0.0], [1.0, 1.5, 1.0], [1.0, 0.0, 0.0]])
    true = gaussian_cmi(lmat @ lmat.T, 1, 1)
    rng = np.random.default_rng(0)
    v = rng.standard_normal((2000, 3)) @ lmat.T
    est = knn_cmi(v[:, :1], v[:, 1:2], v[:, 2:], rng=rng)
    # measured over seeds 0-9 at n = 2000: error -0.045 .. +0.008 (mean -0.010)
    assert est == pytest.approx(true, abs=0.08)


def test_knn_cmi_gaussian_five_dimensions_is_biased_low_as_ksg() -> None:
    lmat = np.array([[0.8, 0.3, 1.0, 0.0, 0.0], [0.2, 0.9, 0.0, 1.0, 0.0],
                     [0.5, 0.0, 1.0, 0.4, 0.5], [1.0, 0.0, 0.0, 0.0, 0.0],
                     [0.0, 1.0, 0.0, 0.0, 0.0]])
    true = gaussian_cmi(lmat @ lmat.T, 2, 1)  # 0.865 nats
    rng = np.random.default_rng(0)
    v = rng.standard_normal((2000, 5)) @ lmat.T
    err = knn_cmi(v[:, :2], v[:, 2:3], v[:, 3:], rng=rng) - true
    # measured over seeds 0-9 at n = 2000: -0.196 .. -0.116 (mean -0.154); n = 3000: mean -0.122
    assert -0.25 < err < 0.0


def test_knn_cmi_conditional_independence_is_zero() -> None:
    rng = np.random.default_rng(0)
    w = rng.standard_normal((3000, 2))
    x = w @ np.array([[1.0, 0.5], [0.2, 1.0]]) + rng.standard_normal((3000, 2))
    y = w[:, :1] + rng.standard_normal((3000, 1))
    # x and y both depend on w but not on each other given w: measured |estimate| <= 0.013
    # over seeds 0-9 (while the unconditional I(x; y) is about 0.2 nats)
    assert abs(knn_cmi(x, y, w, rng=rng)) < 0.03
    assert ksg_mi(x, y) > 0.1


def test_complementary_columns_drop_what_the_robot_state_determines() -> None:
    d = peg_like(seed=0)
    keep, share = complementary_columns(d["task_state"], d["robot_state"])
    assert keep.tolist() == [True, True, False, False]  # offset kept, velocity determined
    assert max(share[2:]) < 1e-20 < min(share[:2])


@pytest.fixture(scope="module")
def peg() -> dict[str, np.ndarray]:
    return peg_like(seed=0)


def _run(fn: Metric, d: dict[str, np.ndarray], z: str) -> MetricResult:
    zt = np.hstack([d["robot_state"], d["hole"]])
    kw = {k: d[k] for k in fn.extra_inputs}
    return fn(d[z], zt, d["episode"], 0, n_bootstrap=0, **kw)


def test_task_cmi_orders_hole_over_robot_copy_and_noise(peg: dict[str, np.ndarray]) -> None:
    v = {z: _run(task_cmi, peg, z).value for z in ("z_hole", "z_cubic", "z_tip", "z_random")}
    # measured over seeds 0-4 (60 episodes x 40 steps): hole 0.063..0.114, cubic 0.019..0.076,
    # tip (a copy of the robot state) -0.012..0.000, random -0.013..0.003
    assert v["z_hole"] > 0.04 and v["z_cubic"] > 0.01
    assert abs(v["z_tip"]) < 0.03 and abs(v["z_random"]) < 0.03


def test_task_r2_gain_orders_hole_over_robot_copy_and_noise(peg: dict[str, np.ndarray]
                                                           ) -> None:
    v = {z: _run(task_r2_gain, peg, z).value for z in ("z_hole", "z_cubic", "z_tip", "z_random")}
    # measured over seeds 0-4: hole 1.16..1.67, cubic 1.08..1.57, tip -0.06..0.12,
    # random -0.14..0.13 (above 1: the robot-only MLP extrapolates worse than a constant to
    # held-out episodes, R² about -0.3 here)
    assert v["z_hole"] > 1.0 and v["z_cubic"] > 0.9
    assert abs(v["z_tip"]) < 0.25 and abs(v["z_random"]) < 0.25
    const = task_r2_gain(np.zeros((len(peg["episode"]), 3)), peg["robot_state"], peg["episode"],
                         0, n_bootstrap=0, robot_state=peg["robot_state"],
                         task_state=peg["task_state"])
    assert const.value == 0.0  # no varying z column: the same model on the same inputs


def test_task_probe_is_form_sensitive(peg: dict[str, np.ndarray]) -> None:
    res = {z: _run(task_probe, peg, z) for z in ("z_hole", "z_cubic", "z_tip", "z_random")}
    v = {z: r.value for z, r in res.items()}
    # measured over seeds 0-4: hole 1.000, cubic 0.635..0.792, tip and random 0.42..0.53 (the
    # robot state alone decodes the velocity columns)
    assert v["z_hole"] > 0.99
    assert v["z_random"] + 0.05 < v["z_cubic"] < v["z_hole"] - 0.1  # same information, tangled
    assert v["z_random"] == pytest.approx(res["z_random"].extras["r2_robot_only"], abs=0.02)
    assert v["z_tip"] == pytest.approx(res["z_tip"].extras["r2_robot_only"], abs=0.02)


def test_action_probe_orders_hole_over_noise(peg: dict[str, np.ndarray]) -> None:
    v = {z: _run(action_probe, peg, z).value for z in ("z_hole", "z_cubic", "z_random")}
    # measured over seeds 0-4: hole 0.979..0.983, cubic 0.35..0.63, random 0.067..0.186
    assert v["z_hole"] > 0.95 and v["z_random"] < 0.3
    assert v["z_random"] < v["z_cubic"] < v["z_hole"]


def test_missing_extra_arrays_are_one_line_errors(peg: dict[str, np.ndarray]) -> None:
    z, zt, ep = peg["z_hole"], peg["robot_state"], peg["episode"]
    for fn in (task_cmi, task_r2_gain, task_probe, action_probe):
        with pytest.raises(DataError, match="needs") as exc:
            fn(z, zt, ep, 0, n_bootstrap=0)
        assert "\n" not in str(exc.value)
    with pytest.raises(DataError, match="robot_state must be"):
        task_probe(z, zt, ep, 0, robot_state=zt[:-1], task_state=peg["task_state"])
