"""Full-state SAC, its saved policy, and the on-policy dataset it collects."""

from __future__ import annotations

import numpy as np
import pytest

from repbench.dataset import Dataset
from repbench.errors import ConfigError, DataError
from repbench.rl import collect_on_policy, load_policy, save_policy, train_full_state_agent

TINY = {"learning_starts": 30, "batch_size": 32, "progress": False}


@pytest.fixture(scope="module")
def trained(toy_task, state_encoder):
    return train_full_state_agent(toy_task, train_steps=80, seed=0, encoder=state_encoder,
                                  eval_episodes=2, curve_points=1, **TINY)


def test_full_state_agent_result(trained):
    _, result = trained
    assert result.extras["role"] == "privileged" and result.extras["agent"] == "sac"
    assert len(result.eval_episode_returns) == 2


def test_policy_save_load_round_trip(trained, toy_task, state_encoder, tmp_path):
    policy, _ = trained
    path = save_policy(policy.model, tmp_path / "full_state.zip")
    loaded = load_policy(path, toy_task, state_encoder)
    env = toy_task.make_env()
    obs, info = env.reset(seed=3)
    step_obs = {**obs, "true_state": info["true_state"]}
    a, b = policy(step_obs), loaded(step_obs)
    assert a.shape == (2,) and a.dtype == np.float32
    np.testing.assert_allclose(a, b, atol=1e-6)
    batched = loaded({k: v[None] for k, v in step_obs.items()})
    np.testing.assert_allclose(batched, a[None], atol=1e-6)


def test_on_policy_dataset_has_the_random_schema(trained, toy_task, toy_dataset, tmp_path):
    policy, _ = trained
    ds = collect_on_policy(toy_task, policy, n_episodes=2, steps_per_episode=10, seed=1,
                           progress=False)
    assert len(ds) == 20 and ds.n_episodes == 2
    assert ds.modalities == toy_dataset.modalities
    for k in ds.modalities:
        assert ds.observations[k].dtype == toy_dataset.observations[k].dtype
        assert ds.observations[k].shape[1:] == toy_dataset.observations[k].shape[1:]
    for f in ("action", "true_state", "reward", "success", "episode", "step"):
        assert getattr(ds, f).dtype == getattr(toy_dataset, f).dtype, f
        assert getattr(ds, f).shape[1:] == getattr(toy_dataset, f).shape[1:], f
    # the policy acted: actions equal its deterministic output
    first = ds.obs(np.array([0]))
    np.testing.assert_allclose(ds.action[0], np.clip(policy(first)[0], -1, 1), atol=1e-6)
    loaded = Dataset.load(ds.save(tmp_path / "on_policy.npz"))
    assert loaded.checksum() == ds.checksum() and loaded.metadata["kind"] == "on_policy"


def test_policy_with_other_encoder_fails_clearly(trained, toy_task, noise_encoder, tmp_path):
    from .rl_test_encoders import NoiseEncoder

    path = save_policy(trained[0].model, tmp_path / "p.zip")
    smaller = NoiseEncoder(latent_dim=3).fit(None)
    policy = load_policy(path, toy_task, smaller)
    obs, info = toy_task.make_env().reset(seed=0)
    with pytest.raises(ConfigError, match="encoder NoiseEncoder gives latent_dim 3"):
        policy({**obs, "true_state": info["true_state"]})
    with pytest.raises(DataError, match="needs the observation dict with 'true_state'"):
        policy(obs)


def test_damaged_policy_file(tmp_path, toy_task, state_encoder):
    bad = tmp_path / "bad.zip"
    bad.write_bytes(b"not a zip")
    with pytest.raises(DataError, match="damaged or not a repbench policy"):
        load_policy(bad, toy_task, state_encoder)
    with pytest.raises(DataError, match="does not exist"):
        load_policy(tmp_path / "none.zip", toy_task, state_encoder)
