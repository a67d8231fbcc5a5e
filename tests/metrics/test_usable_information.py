"""Known answers for the usable-information metrics (repbench/metrics/usable_information.py).

Jointly Gaussian (z, c, r) with a closed-form I(z; c | r) for ``task_cmi_gc`` and
``task_vinfo_linear``; an exact linear task state and pure noise for the loss–data curve of
``task_sdl`` and ``task_eps_samples``. Tolerances were measured over data seeds 0-5 (35 episodes
× 100 rows): relative error of ``task_cmi_gc`` within ±4.6 % at 0.69 nats and ±1.8 % at 1.61
nats, of ``task_vinfo_linear`` within ±2.7 % and ±1.7 %; with z independent of c, ``task_cmi_gc``
0.0013-0.0028 nats and ``task_vinfo_linear`` −0.0051 to −0.0016 nats.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from repbench.errors import ConfigError, DataError
from repbench.metrics.task_information import gaussian_cmi
from repbench.metrics.usable_information import (
    copula_normalize,
    curve_losses,
    gaussian_copula_cmi,
    task_cmi_gc,
    task_eps_samples,
    task_sdl,
    task_vinfo_linear,
)
from repbench.registry import metrics

EPISODE = np.repeat(np.arange(35), 100)
NAMES = ("task_sdl", "task_eps_samples", "task_vinfo_linear", "task_cmi_gc")


def gaussian_zcr(n: int, a: float, *, dz: int = 6, dc: int = 2, dr: int = 3, seed: int = 0
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Jointly Gaussian z [n, dz], c [n, dc], r [n, dr] and the true I(z; c | r) in nats.

    r ~ N(0, I); the hidden u ~ N(0, I_dc); c = u + rB; z = uM + rG + ε, ε ~ N(0, I), with
    the rows of M orthogonal of norm ``a``, so c's columns are independent given r and given
    (r, z) and I(z; c | r) = dc · ½ ln(1 + a²) (checked against the covariance's closed form).
    """
    rng = np.random.default_rng(seed)
    q = np.linalg.qr(rng.standard_normal((dz, dz)))[0][:, :dc]
    lin = np.zeros((dz + dc + dr, dc + dr + dz))  # (z, c, r) = lin @ (u, r, ε)
    lin[:dz, :dc] = a * q
    lin[:dz, dc:dc + dr] = rng.standard_normal((dz, dr))
    lin[:dz, dc + dr:] = np.eye(dz)
    lin[dz:dz + dc, :dc] = np.eye(dc)
    lin[dz:dz + dc, dc:dc + dr] = rng.standard_normal((dc, dr))
    lin[dz + dc:, dc:dc + dr] = np.eye(dr)
    truth = gaussian_cmi(lin @ lin.T, dz, dc)
    assert truth == pytest.approx(dc * 0.5 * math.log1p(a * a), rel=1e-9)
    v = rng.standard_normal((n, dc + dr + dz)) @ lin.T
    return v[:, :dz], v[:, dz:dz + dc], v[:, dz + dc:], truth


# -- task_cmi_gc -------------------------------------------------------------------------------

@pytest.mark.parametrize(("a", "rel"), [(1.0, 0.08), (2.0, 0.04)])
def test_cmi_gc_matches_the_gaussian_closed_form(a: float, rel: float) -> None:
    z, c, r, truth = gaussian_zcr(3500, a)
    res = task_cmi_gc(z, z, EPISODE, 0, robot_state=r, task_state=c, n_bootstrap=50)
    assert res.value == pytest.approx(truth, rel=rel)
    assert res.ci_low is not None and res.ci_high is not None
    assert res.ci_low <= res.value <= res.ci_high
    assert len(res.extras["bootstrap_replicates"]) == 50


def test_cmi_gc_is_invariant_to_monotone_maps_of_each_column() -> None:
    z, c, r, _ = gaussian_zcr(3500, 1.0)
    base = task_cmi_gc(z, z, EPISODE, 0, robot_state=r, task_state=c, n_bootstrap=0).value
    z_mapped = np.hstack([np.exp(z[:, :2]), z[:, 2:4] ** 3 + z[:, 2:4], -2.0 * z[:, 4:] + 7.0])
    mapped = task_cmi_gc(z_mapped, z, EPISODE, 0, robot_state=np.tanh(r),
                         task_state=np.arctan(c) * 3.0, n_bootstrap=0).value
    # c keeps its ranks, so _prepare's linear test still finds both columns complementary
    assert mapped == pytest.approx(base, abs=1e-10)


def test_cmi_gc_of_independent_z_is_near_zero_and_of_constant_z_is_zero() -> None:
    _, c, r, _ = gaussian_zcr(3500, 1.0)
    z = np.random.default_rng(7).standard_normal((3500, 6))
    assert abs(task_cmi_gc(z, z, EPISODE, 0, robot_state=r, task_state=c,
                           n_bootstrap=0).value) < 0.01
    flat = np.ones((3500, 4))
    res = task_cmi_gc(flat, flat, EPISODE, 0, robot_state=r, task_state=c, n_bootstrap=0)
    assert res.value == 0.0 and res.extras["note"] == "z is constant"


def test_gaussian_copula_terms_average_to_the_value_without_ridge() -> None:
    z, c, r, _ = gaussian_zcr(2000, 1.5)
    value, terms = gaussian_copula_cmi(z, c, r, ridge=0.0)
    assert terms.shape == (2000,)
    assert float(terms.mean()) == pytest.approx(value, abs=1e-10)


def test_copula_normalize_gives_standard_normal_margins_and_keeps_ranks() -> None:
    x = np.random.default_rng(0).exponential(size=(5000, 2))
    g = copula_normalize(x)
    assert np.array_equal(np.argsort(g[:, 0]), np.argsort(x[:, 0]))
    assert abs(g.mean()) < 1e-12 and g.std(0) == pytest.approx(1.0, abs=0.01)


# -- task_vinfo_linear -------------------------------------------------------------------------

@pytest.mark.parametrize(("a", "rel"), [(1.0, 0.05), (2.0, 0.04)])
def test_vinfo_linear_equals_the_gaussian_cmi_for_linear_gaussian_data(a: float,
                                                                      rel: float) -> None:
    z, c, r, truth = gaussian_zcr(3500, a)
    res = task_vinfo_linear(z, z, EPISODE, 0, robot_state=r, task_state=c, n_bootstrap=50)
    assert res.value == pytest.approx(truth, rel=rel)
    assert sum(res.extras["per_column"]) == pytest.approx(res.value)
    assert res.ci_low is not None and res.ci_high is not None
    assert res.ci_low <= res.value <= res.ci_high


def test_vinfo_linear_of_independent_z_is_near_zero_and_of_constant_z_is_zero() -> None:
    _, c, r, _ = gaussian_zcr(3500, 1.0)
    z = np.random.default_rng(7).standard_normal((3500, 6))
    assert abs(task_vinfo_linear(z, z, EPISODE, 0, robot_state=r, task_state=c,
                                 n_bootstrap=0).value) < 0.02
    flat = np.ones((3500, 4))
    assert task_vinfo_linear(flat, flat, EPISODE, 0, robot_state=r, task_state=c,
                             n_bootstrap=0).value == 0.0


# -- task_sdl and task_eps_samples -------------------------------------------------------------

@pytest.fixture(scope="module")
def curves() -> dict[str, tuple[float, float, dict]]:
    """(SDL, ε-sample complexity, SDL's extras) at the registered defaults on 2100 rows
    (35 episodes × 60): c an exact linear function of z ⊕ r, and z pure noise."""
    rng = np.random.default_rng(0)
    episode = np.repeat(np.arange(35), 60)
    r = rng.standard_normal((2100, 4))
    u = rng.standard_normal((2100, 2))
    task = np.hstack([u + 0.5 * r[:, :2], r[:, 2:]])  # the last two columns: r's own
    out = {}
    for label, z in [("exact", np.hstack([u, r]) @ rng.standard_normal((6, 8))),
                     ("noise", rng.standard_normal((2100, 8)))]:
        # task_sdl then task_eps_samples on the same arrays: one set of probes (cached)
        sdl = task_sdl(z, z, episode, 0, robot_state=r, task_state=task, n_bootstrap=20)
        eps = task_eps_samples(z, z, episode, 0, robot_state=r, task_state=task,
                               n_bootstrap=0)
        assert eps.extras["loss_data_curve"] == sdl.extras["loss_data_curve"]
        out[label] = (sdl.value, eps.value, dict(sdl.extras))
    return out


def test_sdl_is_small_and_eps_samples_log2_64_when_c_is_linear_in_z(curves) -> None:
    sdl, eps, extras = curves["exact"]
    # measured: L(n) 0.031, 0.009, 0.005, 0.003, 0.002 for n = 64 … 1024
    assert sdl < 0.05
    assert eps == math.log2(64)
    assert extras["task_state_columns_used"] == [0, 1]


def test_sdl_is_large_and_eps_samples_the_ceiling_when_z_is_noise(curves) -> None:
    sdl, eps, extras = curves["noise"]
    # measured: L(n) 1.25-1.56 (an unregularized probe overfits noise): SDL 5.8
    assert sdl > 2.0
    assert eps == math.log2(2 * 4096)
    assert min(extras["loss_data_curve"]["loss"]) > 0.2


def test_sdl_extras_carry_the_curve_and_the_skipped_sizes(curves) -> None:
    for sdl, _, extras in curves.values():
        curve = extras["loss_data_curve"]
        assert curve["n"] == [64, 128, 256, 512, 1024]  # 1470 training rows
        assert extras["sizes_skipped"] == [2048, 4096]
        assert sdl == pytest.approx(sum(max(0.0, v - 0.2) for v in curve["loss"]))
        assert extras["epsilon"] == 0.2 and extras["hidden"] == [64, 64]


def test_curve_losses_is_mean_over_columns_of_one_minus_r2() -> None:
    err = np.array([[[1.0, 0.0], [1.0, 2.0]]])  # one size, two rows, two columns
    dev = np.array([[2.0, 4.0], [2.0, 4.0]])
    assert curve_losses(err, dev)[0] == pytest.approx(0.5 * (2 / 4 + 2 / 8))


def test_sdl_refuses_too_few_training_rows() -> None:
    z, c, r, _ = gaussian_zcr(80, 1.0)  # 8 episodes: 6 for training, 60 rows
    with pytest.raises(DataError, match="have 60 rows, fewer than the smallest training size"):
        task_sdl(z, z, np.repeat(np.arange(8), 10), 0, robot_state=r, task_state=c)


# -- inputs and parameters ---------------------------------------------------------------------

@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("missing", ["task_state", "robot_state"])
def test_a_missing_state_array_is_a_one_line_error(name: str, missing: str) -> None:
    z, c, r, _ = gaussian_zcr(3500, 1.0)
    arrays = {"task_state": c, "robot_state": r}
    del arrays[missing]
    with pytest.raises(DataError, match=f"{name}: needs task_state= and robot_state=") as exc:
        metrics.get(name)(z, z, EPISODE, 0, **arrays)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize(("name", "params", "field"), [
    ("task_sdl", {"sizes": [128, 64]}, "sizes"),
    ("task_sdl", {"epsilon": 0.0}, "epsilon"),
    ("task_eps_samples", {"hidden": []}, "hidden"),
    ("task_eps_samples", {"train_steps": 0}, "train_steps"),
    ("task_vinfo_linear", {"test_fraction": 1.0}, "test_fraction"),
    ("task_cmi_gc", {"ridge": -1.0}, "ridge"),
])
def test_bad_parameters_are_refused_before_running(name: str, params: dict, field: str) -> None:
    with pytest.raises(ConfigError, match=f"{name}: parameter '{field}'"):
        metrics.get(name).check_params(params)


def test_registered_directions_groups_and_preregistered_defaults() -> None:
    for name in NAMES:
        m = metrics.get(name)
        assert m.group == "privileged" and "task_state" in m.extra_inputs
    assert not metrics.get("task_sdl").higher_is_better
    assert not metrics.get("task_eps_samples").higher_is_better
    assert metrics.get("task_vinfo_linear").higher_is_better
    assert metrics.get("task_cmi_gc").higher_is_better
    p = metrics.get("task_sdl").parameters
    assert p["hidden"].default == (64, 64) and p["epsilon"].default == 0.2
    assert p["sizes"].default == (64, 128, 256, 512, 1024, 2048, 4096)
    assert metrics.get("task_vinfo_linear").parameters["test_fraction"].default == 0.3
