"""Constructor validation, rewards, and the force/torque filter (no simulator needed)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from repbench.errors import ConfigError
from repbench_tasks.peg_in_hole import PegInHoleTask
from repbench_tasks.rewards import RewardParams, reach_reward, stage_of, staged_reward
from repbench_tasks.sensing import LowPass, weight_wrench


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"grid_size": 0}, "grid_size"),
    ({"grid_size": 2.5}, "grid_size"),
    ({"grid_extent": 0.9}, "off the table"),
    ({"grid_center": (0.35, 0.0)}, "off the table"),
    ({"clearance": 0.0001}, "clearance"),
    ({"clearance": 0.05}, "clearance"),
    ({"image_size": 0}, "image_size"),
    ({"horizon": 0}, "horizon"),
    ({"start": "sideways"}, "start"),
    ({"hole_sampling": "random"}, "hole_sampling"),
    ({"physics_dt": 0.003}, "physics_dt"),
])
def test_bad_constructor_args_raise_one_line_config_error(kwargs, field) -> None:
    with pytest.raises(ConfigError, match=field) as exc:
        PegInHoleTask(**kwargs)
    assert "\n" not in str(exc.value)


def test_unknown_override_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="unknown parameter"):
        PegInHoleTask().config(colour="red")


def test_params_roundtrip_and_grid() -> None:
    task = PegInHoleTask(grid_size=5, grid_extent=0.16)
    assert PegInHoleTask(**task.get_params()).get_params() == task.get_params()
    grid = task.config().grid_positions()
    assert grid.shape == (25, 2)
    np.testing.assert_allclose(grid.min(0), [-0.08, -0.08])
    np.testing.assert_allclose(np.diff(np.unique(grid[:, 0])), 0.04)


def test_reward_stages_increase_along_an_insertion() -> None:
    p = RewardParams(hole_depth=0.04, clearance=0.002)
    far, _ = staged_reward(np.array([0.1, 0.05, 0.1]), p)
    near, _ = staged_reward(np.array([0.02, 0.0, 0.03]), p)
    align, _ = staged_reward(np.array([0.002, 0.0, 0.01]), p)
    shallow, _ = staged_reward(np.array([0.0, 0.0, -0.01]), p)
    deep, _ = staged_reward(np.array([0.0, 0.0, -0.025]), p)
    done, ok = staged_reward(np.array([0.0, 0.0, -0.035]), p)
    assert 0 < far < near <= 1 < align <= 2 < 4 <= shallow < deep < 6 < done == 10 and ok
    # below the opening but outside it (beside the hole) is not insertion
    assert staged_reward(np.array([0.05, 0.0, -0.02]), p)[0] < 1


def test_reach_reward_known_values() -> None:
    # on the opening it pays c_r; 3 cm straight above: c_r - c_r/2 tanh(0.3) (the xy term is 0)
    assert reach_reward(np.zeros(3), c_r=2.0) == 2.0
    assert reach_reward(np.array([0.0, 0.0, 0.03])) == pytest.approx(1 - np.tanh(0.3) / 2)
    # 3 cm sideways costs both terms, so hovering above pays more than resting beside
    assert reach_reward(np.array([0.03, 0.0, 0.0])) == pytest.approx(1 - np.tanh(0.3))
    assert reach_reward(np.array([5.0, 0.0, 0.0]), lam=10.0) < 1e-12


@pytest.mark.parametrize("offset_mm", [4.5, 8.0, 13.0])
def test_pressing_on_the_rim_is_not_insertion(offset_mm) -> None:
    """A peg pressed onto a wall top sinks ~0.3 mm into it (soft contact): still outside."""
    p = RewardParams(hole_depth=0.04, clearance=0.002)
    s = np.array([offset_mm / 1000, 0.0, -0.0004])
    stage, _ = stage_of(s, p)
    assert stage in ("align", "reach") and staged_reward(s, p)[0] <= 2
    # entering with play (within the clearance, tilted or pressed on a side) is insertion
    assert stage_of(np.array([0.0025, -0.001, -0.005]), p)[0] == "insert"


def test_lowpass_in_chunks_equals_scipy_on_the_whole_signal() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(100, 6)) + 3.0
    lp = LowPass(10.0, 200.0)
    lp.reset(np.zeros(6))
    chunked = np.stack([lp(c) for c in np.split(x, 10)])
    whole = signal.sosfilt(lp.sos, x, axis=0)
    np.testing.assert_allclose(chunked, whole[9::10], atol=1e-12)
    # a constant settles to itself (unit DC gain)
    lp.reset(np.zeros(6))
    lp(np.ones((400, 6)))
    np.testing.assert_allclose(lp.value, 1.0, atol=1e-6)


def test_weight_wrench_of_a_hanging_mass() -> None:
    # sensor frame = world, mass 1 kg with its centre 0.1 m along +x from the site
    w = weight_wrench(np.eye(3), np.array([0.1, 0, 0]), np.zeros(3), 1.0,
                      np.array([0, 0, -9.81]))
    np.testing.assert_allclose(w[:3], [0, 0, 9.81])
    np.testing.assert_allclose(w[3:], [0, -0.981, 0], atol=1e-12)


def test_weight_wrench_batch_equals_single_samples_and_np_cross() -> None:
    rng = np.random.default_rng(1)
    rots = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(7)])
    com, pos = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    g = np.array([0.0, 0.0, -9.81])
    batch = weight_wrench(rots, com, pos, 1.7, g)
    single = np.stack([weight_wrench(r, c, p, 1.7, g)
                       for r, c, p in zip(rots, com, pos, strict=True)])
    np.testing.assert_allclose(batch, single, rtol=0, atol=1e-12)
    support = -1.7 * g
    ref = np.concatenate([np.einsum("nji,j->ni", rots, support),
                          np.einsum("nji,nj->ni", rots, np.cross(com - pos, support))], axis=1)
    np.testing.assert_allclose(batch, ref, rtol=0, atol=1e-12)


def test_evaluation_resets_cover_the_grid_then_off_grid_holes() -> None:
    task = PegInHoleTask()
    resets = task.evaluation_resets(40)
    assert resets == task.evaluation_resets(40)  # fixed
    assert len({r["seed"] for r in resets}) == 40
    assert [r["options"]["hole_index"] for r in resets[:25]] == list(range(25))
    grid = task.config().grid_positions()
    half = task.grid_extent / 2
    for r in resets[25:]:
        xy = np.asarray(r["options"]["hole_xy"])
        assert np.all(np.abs(xy) <= half)
        assert np.min(np.linalg.norm(grid - xy, axis=1)) >= 0.01
    with pytest.raises(ConfigError, match="evaluation episodes"):
        task.evaluation_resets(0)


def test_robot_view_tip_is_tip_position_and_velocity() -> None:
    proprio = np.arange(20, dtype=np.float32)
    np.testing.assert_array_equal(PegInHoleTask(robot_view="tip").robot_state(
        {"proprio": proprio}), np.arange(14, 20))
    np.testing.assert_array_equal(
        PegInHoleTask(robot_view="proprio").robot_state({"proprio": proprio}), proprio)
    assert PegInHoleTask().robot_view == "tip"
    with pytest.raises(ConfigError, match="robot_view"):
        PegInHoleTask(robot_view="joints")


def test_agent_env_renders_only_for_image_encoders() -> None:
    env = PegInHoleTask().make_agent_env(seed=0, modalities=("proprio", "true_state"))
    try:
        assert env.config.camera is False
        obs, _ = env.reset(seed=0)
        assert not obs["image"].any()
    finally:
        env.close()
    with pytest.raises(ConfigError, match="camera=False but the encoder reads"):
        PegInHoleTask(camera=False).make_agent_env(modalities=("image", "ft"))
