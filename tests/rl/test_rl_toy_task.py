"""The toy task keeps the task contract (observation dict, info, determinism, dataset)."""

from __future__ import annotations

import numpy as np
import pytest

from repbench.dataset import Dataset
from repbench.errors import ConfigError


def test_observation_contract(toy_task):
    env = toy_task.make_env(seed=3)
    obs, info = env.reset()
    assert set(obs) == {"image", "ft", "proprio", "last_action"}
    assert obs["image"].shape == (64, 64, 3) and obs["image"].dtype == np.uint8
    assert obs["ft"].shape == (6,) and obs["ft"].dtype == np.float32
    assert obs["proprio"].shape == (4,) and obs["last_action"].shape == (2,)
    assert info["true_state"].shape == (6,) and isinstance(info["is_success"], bool)
    for key, space in env.observation_space.spaces.items():
        assert space.contains(obs[key]), key
    np.testing.assert_array_equal(info["true_state"], toy_task.true_state(env))
    # the hole is drawn: its colour is in the image at the hole position
    hole = info["true_state"][4:]
    col = int((hole[0] + 1) / 2 * 64)
    row = int((1 - hole[1]) / 2 * 64)
    np.testing.assert_array_equal(obs["image"][row, col], [40, 90, 230])


def test_reset_is_deterministic_and_horizon_truncates(toy_task):
    a, b = toy_task.make_env(), toy_task.make_env()
    oa, ia = a.reset(seed=11)
    ob, ib = b.reset(seed=11)
    np.testing.assert_array_equal(ia["true_state"], ib["true_state"])
    np.testing.assert_array_equal(oa["image"], ob["image"])
    _, other = a.reset(seed=12)
    assert not np.array_equal(other["true_state"][4:], ia["true_state"][4:])
    truncated, t = False, 0
    while not truncated:
        _, _, terminated, truncated, _ = a.step(a.action_space.sample())
        assert not terminated
        t += 1
    assert t == toy_task.horizon


def test_moving_to_the_hole_succeeds(toy_task):
    env = toy_task.make_env()
    _, info = env.reset(seed=5)
    for _ in range(toy_task.horizon):
        z = info["true_state"]
        action = np.clip((z[4:] - z[:2]) / 0.1, -1, 1)
        _, reward, _, _, info = env.step(action)
    assert info["is_success"] and reward > 0.5


def test_collect_random_dataset(toy_dataset):
    assert isinstance(toy_dataset, Dataset)
    assert len(toy_dataset) == 60 and toy_dataset.n_episodes == 3
    assert toy_dataset.observations["image"].shape == (60, 64, 64, 3)
    # random data starts in the hole (backwards exploration)
    start = toy_dataset.true_state[toy_dataset.step == 0]
    np.testing.assert_allclose(start[:, :2], start[:, 4:])


def test_collect_bad_kind(toy_task):
    with pytest.raises(ConfigError, match="unknown dataset kind"):
        toy_task.collect("expert", n_episodes=1, steps_per_episode=2, seed=0)
    with pytest.raises(ConfigError, match="needs policy"):
        toy_task.collect("on_policy", n_episodes=1, steps_per_episode=2, seed=0)
