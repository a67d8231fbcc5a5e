"""Feature standardization inside the policy: statistics, the extractor, save/load, bad input."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch

from repbench.errors import ConfigError
from repbench.rl import SACAgent, make_encoded_env, save_policy
from repbench.rl.full_state import load_model
from repbench.rl.normalization import StandardizedFeatures, feature_statistics

TINY = {"learning_starts": 30, "batch_size": 32, "progress": False}


def _rollout(env, steps, seed):
    """The reference: the same random-action rollout, recorded step by step."""
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    rows, episode = [obs], 0
    while len(rows) < steps:
        obs, _, term, trunc, _ = env.step(
            rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32))
        rows.append(obs)
        if term or trunc:
            episode += 1
            rows.append(env.reset(seed=seed + episode)[0])
    return np.array(rows[:steps], np.float64)


def test_statistics_match_numpy_over_the_same_rollout(toy_task, state_encoder):
    env = make_encoded_env(toy_task, state_encoder)
    mean, std = feature_statistics(env, 75, seed=3)  # horizon 30: crosses two resets
    ref = _rollout(make_encoded_env(toy_task, state_encoder), 75, seed=3)
    ref_std = ref.std(axis=0)
    ref_std[ref_std < 1e-6] = 1.0
    np.testing.assert_allclose(mean, ref.mean(axis=0), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(std, ref_std, rtol=1e-5, atol=1e-6)
    assert mean.dtype == std.dtype == np.float32 and (std > 0).all()


def test_constant_feature_gets_unit_std():
    class Const(gym.Env):
        observation_space = gym.spaces.Box(-np.inf, np.inf, (2,), np.float32)
        action_space = gym.spaces.Box(-1, 1, (1,), np.float32)

        def reset(self, *, seed=None, options=None):
            super().reset(seed=seed)
            return np.array([5.0, 0.0], np.float32), {}

        def step(self, action):
            return np.array([5.0, float(action[0])], np.float32), 0.0, False, False, {}

    mean, std = feature_statistics(Const(), 200, seed=0)
    assert mean[0] == 5.0 and std[0] == 1.0
    assert 0.5 < std[1] < 0.65  # uniform on [-1, 1]: 1/sqrt(3) = 0.577


def test_extractor_standardizes_and_clips():
    space = gym.spaces.Box(-np.inf, np.inf, (3,), np.float32)
    ext = StandardizedFeatures(space, mean=[1.0, 0.0, -2.0], std=[2.0, 0.001, 1.0])
    x = torch.tensor([[3.0, 1.0, -2.0], [1.0, -0.0005, 0.0]])
    out = ext(x)
    torch.testing.assert_close(out, torch.tensor([[1.0, 10.0, 0.0], [0.0, -0.5, 2.0]]))
    assert ext.features_dim == 3


@pytest.mark.parametrize("mean, std, match", [
    ([0.0, 0.0], [1.0, 1.0, 1.0], "statistics of size 2/3"),
    ([0.0] * 3, [1.0, 0.0, 1.0], "must be > 0"),
])
def test_extractor_rejects_bad_statistics(mean, std, match):
    space = gym.spaces.Box(-np.inf, np.inf, (3,), np.float32)
    with pytest.raises(ValueError, match=match):
        StandardizedFeatures(space, mean=mean, std=std)


def test_trained_policy_carries_its_statistics_through_save_and_load(toy_task, state_encoder,
                                                                     tmp_path):
    agent = SACAgent(**TINY, normalize_steps=40)
    agent.train(toy_task, state_encoder, train_steps=60, seed=0, eval_episodes=1,
                curve_points=1, progress=False)
    model = agent.model_
    ext = model.policy.actor.features_extractor
    assert isinstance(ext, StandardizedFeatures)
    env = make_encoded_env(toy_task, state_encoder)
    mean, std = feature_statistics(env, 40, seed=20_000)  # NORMALIZE_SEED_BASE, seed 0
    np.testing.assert_allclose(ext.mean.cpu().numpy(), mean)  # the policy's device
    np.testing.assert_allclose(ext.std.cpu().numpy(), std)
    loaded = load_model(save_policy(model, tmp_path / "p.zip"))
    np.testing.assert_array_equal(loaded.policy.actor.features_extractor.std.numpy(), std)
    obs, _ = env.reset(seed=5)
    np.testing.assert_allclose(loaded.predict(obs, deterministic=True)[0],
                               model.predict(obs, deterministic=True)[0], atol=1e-6)


def test_normalize_steps_zero_feeds_raw_features(toy_task, state_encoder):
    env = make_encoded_env(toy_task, state_encoder)
    model = SACAgent(normalize_steps=0).build_model(env, seed=0, buffer_size=100)
    assert not isinstance(model.policy.actor.features_extractor, StandardizedFeatures)


@pytest.mark.parametrize("value", [1, -5, 2.5])
def test_bad_normalize_steps(value, toy_task, state_encoder):
    with pytest.raises(ConfigError, match="agent 'sac': parameter normalize_steps"):
        SACAgent(**TINY, normalize_steps=value).train(toy_task, state_encoder, train_steps=100,
                                                      seed=0, eval_episodes=1)
