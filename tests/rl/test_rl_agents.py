"""The ``sac`` and ``ddpg`` agents: registry, paper hyperparameters, training, bad input."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

import repbench
from repbench.errors import ConfigError, PluginError
from repbench.pipeline.suite import load_suite
from repbench.rl import DDPGAgent, SACAgent
from repbench.testing import check_agent

TINY = {"learning_starts": 30, "batch_size": 32, "progress": False}


@pytest.mark.parametrize("name, cls", [("sac", SACAgent), ("ddpg", DDPGAgent)])
def test_registered(name, cls):
    assert repbench.agents.get(name) is cls


def test_unknown_agent_name():
    with pytest.raises(PluginError, match="unknown agent 'sca'; did you mean 'sac'"):
        check_agent("sca")


@pytest.mark.parametrize("suite", ["smoke", "quick", "paper"])
@pytest.mark.parametrize("name", ["sac", "ddpg"])
def test_suite_agent_params_are_constructor_kwargs(suite, name):
    params = load_suite(suite).agent_params.get(name, {})
    agent = repbench.agents.get(name)(**params)
    for k, v in params.items():
        assert getattr(agent, k) == v
    if suite == "paper":
        assert set(params) <= set(inspect.signature(type(agent).__init__).parameters)
        assert agent.get_params()["buffer_size"] == 3_000_000


def test_paper_defaults():
    sac, ddpg = SACAgent(), DDPGAgent()
    for a in (sac, ddpg):
        assert list(a.hidden_sizes) == [128, 128]
        assert (a.learning_rate, a.buffer_size, a.batch_size, a.tau) == (1e-3, 3e6, 256, 0.005)
        assert a.device == "auto" and a.n_envs == 1
    assert sac.ent_coef == "auto" and ddpg.action_noise == 0.25


def test_sb3_model_matches_the_hyperparameters(toy_task, state_encoder):
    from repbench.rl import make_encoded_env

    env = make_encoded_env(toy_task, state_encoder)
    sac = SACAgent(hidden_sizes=[96, 96], learning_rate=3e-3).build_model(env, seed=0,
                                                                          buffer_size=1000)
    linears = [m for m in sac.actor.latent_pi if hasattr(m, "out_features")]
    assert [m.out_features for m in linears] == [96, 96]
    assert sac.learning_rate == 3e-3 and sac.tau == 0.005 and sac.batch_size == 256
    assert sac.ent_coef == "auto" and sac.log_ent_coef is not None  # automatic tuning
    qf = [m.out_features for m in sac.critic.q_networks[0] if hasattr(m, "out_features")]
    assert qf == [96, 96, 1]
    ddpg = DDPGAgent().build_model(env, seed=0, buffer_size=1000)
    np.testing.assert_allclose(ddpg.action_noise._sigma, 0.25 * env.action_space.high)
    assert str(sac.device) == ("cuda" if __import__("torch").cuda.is_available() else "cpu")


@pytest.mark.parametrize("name", ["sac", "ddpg"])
def test_check_agent_smoke(name, toy_task, state_encoder):
    result = check_agent(name, toy_task, state_encoder, train_steps=80, **TINY)
    assert result.extras["agent"] == name
    assert result.extras["eval_resets"] == toy_task.evaluation_resets(2)
    assert result.extras["observation_dim"] == 10
    assert result.extras["effective_buffer_size"] <= 81  # capped at the run's length


def test_seed_changes_training(toy_task, state_encoder):
    a = SACAgent(**TINY).train(toy_task, state_encoder, train_steps=60, seed=0,
                               eval_episodes=2, curve_points=1, progress=False)
    b = SACAgent(**TINY).train(toy_task, state_encoder, train_steps=60, seed=1,
                               eval_episodes=2, curve_points=1, progress=False)
    assert a.eval_episode_returns != b.eval_episode_returns


def test_training_leaves_no_sb3_log_folder(toy_task, state_encoder, tmp_path, monkeypatch):
    # SB3's default logger makes an empty <tmp>/SB3-<date> folder for every model that learns
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    SACAgent(**TINY).train(toy_task, state_encoder, train_steps=40, seed=0, eval_episodes=1,
                           curve_points=1, progress=False)
    assert not list(tmp_path.glob("SB3-*"))


@pytest.mark.parametrize("field, value, match", [
    ("hidden_sizes", [], "hidden_sizes"),
    ("learning_rate", -1.0, "learning_rate"),
    ("tau", 0.0, "tau"),
    ("ent_coef", "manual", "ent_coef"),
    ("learning_starts", 500, "learning_starts=500 must be below train_steps=100"),
    ("device", "tpu", "device"),
])
def test_bad_params(field, value, match, toy_task, state_encoder):
    agent = SACAgent(**{**TINY, field: value})
    with pytest.raises(ConfigError, match=f"agent 'sac': parameter .*{match}"):
        agent.train(toy_task, state_encoder, train_steps=100, seed=0, eval_episodes=1)


def test_unfitted_encoder_fails_before_training(toy_task):
    from .rl_test_encoders import TrueStateEncoder

    with pytest.raises(ConfigError, match="encoder TrueStateEncoder is not fitted"):
        DDPGAgent(**TINY).train(toy_task, TrueStateEncoder(), train_steps=100, seed=0,
                                eval_episodes=1)


@pytest.mark.slow  # worker processes start in ~10-40 s on a loaded 2-core machine
def test_vectorised_training_in_worker_processes(toy_task, state_encoder):
    result = SACAgent(**TINY, n_envs=2).train(toy_task, state_encoder, train_steps=80, seed=0,
                                              eval_episodes=1, curve_points=2, progress=False)
    assert result.train_steps >= 80 and result.extras["params"]["n_envs"] == 2
    assert np.isfinite(result.eval_return) and len(result.curve_steps) == 2
