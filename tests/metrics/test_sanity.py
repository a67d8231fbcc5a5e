"""Sanity orderings on realistic shapes, and bad inputs with clear messages."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import representations

from repbench.errors import ConfigError, DataError
from repbench.metrics.diagnostics import true_state_differences
from repbench.registry import metrics
from repbench.testing.metric import synthetic_extra_inputs

FAST = {"mine": {"steps": 1500, "learning_rate": 1e-3, "eval_every": 100},
        "regression": {"random_split": False}}


def _extras(name: str, z_true: np.ndarray, episode: np.ndarray) -> dict[str, np.ndarray]:
    """The synthetic extra arrays a metric asks for (robot state = the random-walk dims)."""
    extra = synthetic_extra_inputs(z_true, episode)
    return {k: extra[k] for k in metrics.get(name).extra_inputs}


#: Metrics of what z adds beyond the robot state: folding robot-state dims of z changes nothing
#: they measure (the agent has the robot state anyway), so only true/folded > random is known.
BEYOND_ROBOT = {"task_cmi", "task_r2_gain", "task_probe", "action_probe", "value_probe",
                "value_probe_gain", "reward_probe_gain", "task_vinfo_linear", "task_cmi_gc"}


@pytest.mark.parametrize("name", [n for n in metrics.names()
                                  if n != "mine" and not metrics.get(n).label_free])
def test_true_beats_folded_beats_random(name: str, realistic) -> None:
    z_true, episode = realistic
    m = metrics.get(name)
    kw = {**FAST.get(name, {}), **_extras(name, z_true, episode)}
    vals = {k: m(z, z_true, episode, 0, n_bootstrap=0, **kw).value
            for k, z in representations(z_true).items()}
    order = ["true", "folded", "random"] if m.higher_is_better else ["random", "folded", "true"]
    if name in BEYOND_ROBOT:
        assert min(vals["true"], vals["folded"]) > vals["random"], vals
    else:
        assert vals[order[0]] > vals[order[1]] > vals[order[2]], vals


@pytest.mark.slow
def test_mine_ordering(realistic) -> None:
    z_true, episode = realistic
    vals = {k: metrics.get("mine")(z, z_true, episode, 0, n_bootstrap=0, **FAST["mine"]).value
            for k, z in representations(z_true).items()}
    assert vals["true"] > vals["folded"] > vals["random"], vals


@pytest.mark.parametrize("name", metrics.names())
def test_collapsed_latent_dim_is_accepted(name: str, realistic) -> None:
    z_true, episode = realistic
    z = z_true.copy()
    z[:, 0] = 0.0  # a collapsed VAE dimension
    params = {"steps": 100, "eval_every": 50} if name == "mine" else {}
    res = metrics.get(name)(z, z_true, episode, 0, n_bootstrap=0, **params,
                            **_extras(name, z_true, episode))
    assert np.isfinite(res.value)
    if "dropped_constant_dims" in res.extras:
        assert res.extras["dropped_constant_dims"] == [0]


@pytest.mark.parametrize("name", metrics.names())
def test_fully_constant_z_defined_or_clear_error(name: str, realistic) -> None:
    z_true, episode = realistic
    m = metrics.get(name)
    extra = _extras(name, z_true, episode)
    try:
        res = m(np.zeros((len(z_true), 4)), z_true, episode, 0, n_bootstrap=0,
                **({"steps": 50} if name == "mine" else {}), **extra)
    except DataError as exc:
        assert "constant" in str(exc)
        return
    rand = m(np.random.default_rng(0).standard_normal(z_true.shape), z_true, episode, 0,
             n_bootstrap=0, **({"steps": 300} if name == "mine" else {}), **extra)
    # a defined value must be the uninformative level: no information (MI 0), the best
    # constant predictor (regression error ~1; train/test mean differ, measured 1.00), or the
    # random-neighbour KNN-MSE; a random map may score worse (an overfit MLP reaches 1.2)
    if name in ("task_probe", "action_probe", "value_probe"):  # z adds nothing: r's own R²
        assert res.value == pytest.approx(res.extras["r2_robot_only"], abs=1e-12)
    elif m.higher_is_better:
        # task_r2_gain of a random map: an MLP overfit on noise inputs, measured -0.23
        assert res.value == 0.0 and rand.value > (-0.5 if name == "task_r2_gain" else -0.05)
    elif name == "regression":
        assert res.value == pytest.approx(1.0, abs=0.1)
    elif name == "task_sdl":  # z adds nothing: the robot state's own curve (measured SDL 4.80);
        assert 0 < res.value <= rand.value  # an MLP overfit on noise inputs is worse (5.70)
    else:
        assert res.value == pytest.approx(rand.value, rel=0.1)


def test_bad_parameter_is_config_error(realistic) -> None:
    z_true, episode = realistic
    with pytest.raises(ConfigError, match="'k'"):
        metrics.get("ksg")(z_true, z_true, episode, 0, k=0)


def test_true_state_differences(realistic) -> None:
    z_true, episode = realistic
    d = true_state_differences(z_true, episode)
    assert d["static_dims"] == [8, 9]
    assert d["first"][8]["static"] and d["first"][8]["normaltest_stat"] is None
    # random-walk steps are Gaussian: first differences pass the normality test
    assert d["first"][0]["normaltest_pvalue"] > 1e-3
    assert sum(d["first"][0]["histogram"]["counts"]) == d["first"][0]["n"]
    with pytest.raises(DataError):
        true_state_differences(z_true[:, 0], episode)


@pytest.mark.parametrize("name", [n for n in metrics.names() if metrics.get(n).label_free])
def test_a_label_free_metric_does_not_change_under_a_rotation_of_z(name: str, realistic) -> None:
    """What a label-free (spectral) metric owes instead of the ordering: it scores the spread
    of z, so an orthogonal rotation of z changes nothing."""
    z_true, episode = realistic
    q, _ = np.linalg.qr(np.random.default_rng(3).standard_normal((z_true.shape[1],) * 2))
    m = metrics.get(name)
    plain = m(z_true, z_true, episode, 0, n_bootstrap=0).value
    rotated = m(z_true @ q, z_true, episode, 0, n_bootstrap=0).value
    assert rotated == pytest.approx(plain, rel=1e-6, abs=1e-9)
