"""The observation wrapper: μ_z ⊕ robot state, frozen encoder, clear errors."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from repbench.errors import ConfigError, DataError
from repbench.rl import FrozenEncoderObservation, make_encoded_env

from .rl_test_encoders import BadEncoder, ConvEncoder, TrueStateEncoder


def test_features_are_latent_then_robot_state(toy_task, state_encoder):
    env = make_encoded_env(toy_task, state_encoder, seed=0)
    assert env.observation_space.shape == (6 + 4,)
    assert env.observation_space.dtype == np.float32
    obs, info = env.reset(seed=7)
    assert obs.dtype == np.float32
    np.testing.assert_array_equal(obs[:6], info["true_state"])
    np.testing.assert_array_equal(obs[6:], info["true_state"][:4])  # proprio = pos, vel
    obs, _, _, _, info = env.step(np.ones(2, np.float32))
    np.testing.assert_array_equal(obs[:6], info["true_state"])
    assert env.observation_space.contains(obs)


def test_episode_truncates_at_task_horizon(toy_task, state_encoder):
    env = make_encoded_env(toy_task, state_encoder)
    env.reset(seed=0)
    steps, done = 0, False
    while not done:
        _, _, term, trunc, _ = env.step(env.action_space.sample())
        done = term or trunc
        steps += 1
    assert steps == toy_task.horizon


def test_torch_encoder_is_frozen(toy_task, toy_dataset):
    enc = ConvEncoder(latent_dim=5).fit(toy_dataset)
    enc.conv_.train()
    env = make_encoded_env(toy_task, enc)
    assert not enc.conv_.training
    assert not any(p.requires_grad for p in enc.fusion_.parameters())
    obs, _ = env.reset(seed=0)
    assert obs.shape == (5 + 4,) and np.isfinite(obs).all()
    assert torch.is_grad_enabled()  # the wrapper does not leak no_grad


def test_unfitted_encoder_is_rejected(toy_task):
    with pytest.raises(ConfigError, match="TrueStateEncoder is not fitted"):
        make_encoded_env(toy_task, TrueStateEncoder())


def test_wrong_latent_shape_names_the_encoder(toy_task, toy_dataset):
    with pytest.raises(DataError, match=r"encoder BadEncoder returned shape \(1, 5\).*latent_dim "
                                        r"is 6"):
        make_encoded_env(toy_task, BadEncoder("shape").fit(toy_dataset))


def test_nan_latent_names_the_encoder(toy_task, toy_dataset):
    with pytest.raises(DataError, match="encoder BadEncoder returned NaN"):
        make_encoded_env(toy_task, BadEncoder("nan").fit(toy_dataset))


def test_nan_in_observation_is_caught(toy_task, state_encoder):
    env = toy_task.make_env()
    wrapped = FrozenEncoderObservation(env, toy_task, state_encoder)
    obs, info = env.reset(seed=0)
    obs["ft"][2] = np.nan
    with pytest.raises(DataError, match=r"modality 'ft' .* NaN .*encoder TrueStateEncoder"):
        wrapped.features(obs, info["true_state"])


def test_latent_size_other_than_the_agent_was_built_for(toy_task, state_encoder, noise_encoder):
    dim = make_encoded_env(toy_task, state_encoder).observation_space.shape[0]
    make_encoded_env(toy_task, state_encoder, expected_dim=dim)  # fine
    msg = r"encoder NoiseEncoder gives latent_dim 3 .* built for 10"
    with pytest.raises(ConfigError, match=msg):
        make_encoded_env(toy_task, type(noise_encoder)(latent_dim=3).fit(None),
                         expected_dim=dim)


def test_batch_encoded_vec_env_matches_the_single_wrapper(toy_task, state_encoder):
    from stable_baselines3.common.vec_env import DummyVecEnv

    from repbench.rl.wrappers import batch_encoded_vec_env, make_raw_env

    venv = batch_encoded_vec_env(
        DummyVecEnv([lambda s=s: make_raw_env(toy_task, seed=s) for s in (0, 1)]),
        toy_task, state_encoder)
    singles = [make_encoded_env(toy_task, state_encoder) for _ in range(2)]
    venv.seed(5)
    obs = venv.reset()
    assert obs.shape == (2, 10) and obs.dtype == np.float32
    ref = np.stack([env.reset(seed=5 + i)[0] for i, env in enumerate(singles)])
    np.testing.assert_array_equal(obs, ref)
    actions = np.full((2, 2), 0.3, np.float32)
    for t in range(toy_task.horizon):
        obs, _, dones, infos = venv.step(actions)
        ref_steps = [env.step(actions[i]) for i, env in enumerate(singles)]
        if t < toy_task.horizon - 1:
            np.testing.assert_array_equal(obs, np.stack([r[0] for r in ref_steps]))
    assert dones.all()  # truncated at the horizon, auto-reset
    for info, r in zip(infos, ref_steps, strict=True):
        np.testing.assert_array_equal(info["terminal_observation"], r[0])


def test_the_agents_force_history_is_the_one_the_dataset_derives(toy_task, toy_dataset):
    """ForceHistory (live) and Dataset.obs (stored episodes) give the same ft_history: roll
    an episode out, store its readings the way a dataset does, derive, compare."""
    from repbench.dataset import FT_HISTORY, HISTORY_STEPS, stacked_history
    from repbench.rl.wrappers import agent_env

    env = agent_env(toy_task, ("image", FT_HISTORY, "proprio"), seed=0)
    assert env.observation_space[FT_HISTORY].shape == (HISTORY_STEPS * 6,)
    live, readings = [], []
    for episode in range(2):
        obs, _ = env.reset(seed=episode)
        for _ in range(6):
            live.append(obs[FT_HISTORY])
            readings.append(obs["ft"])
            obs, *_ = env.step(np.full(2, 0.7 if episode else -0.4, np.float32))
    episodes = np.repeat([0, 1], 6)
    derived = stacked_history(np.array(readings), episodes, np.arange(12), HISTORY_STEPS)
    np.testing.assert_array_equal(np.array(live), derived)
    # a reset starts over: the first reading, repeated
    first = np.array(live)[6].reshape(HISTORY_STEPS, 6)
    assert (first == first[0]).all()
    assert not (np.array(live)[11].reshape(HISTORY_STEPS, 6) == first[0]).all()


def test_an_encoder_reading_the_force_history_runs_in_the_agents_env(toy_task, toy_dataset):
    from repbench_encoders.vae import VAELowKLFtHistory

    enc = VAELowKLFtHistory(epochs=1, batch_size=16, progress=False).fit(toy_dataset)
    env = make_encoded_env(toy_task, enc, seed=0)
    obs, _ = env.reset(seed=0)
    obs2, *_ = env.step(np.ones(2, np.float32))
    assert obs.shape == obs2.shape == (16 + 4,) and np.isfinite(obs2).all()
    without = {k: v for k, v in toy_dataset.obs(slice(0, 2)).items() if k != "ft_history"}
    with pytest.raises(DataError, match="ft_history"):
        enc.encode(without)
