"""The agents on the real encoder plugins (``oracle``, ``vae_lowkl``) and, when installed,
the real peg-in-hole task."""

from __future__ import annotations

import numpy as np
import pytest

import repbench
from repbench.rl import collect_on_policy, train_full_state_agent
from repbench.testing import check_agent


def _plugin(name: str, **params):
    try:
        return repbench.encoders.get(name)(**params)
    except repbench.RepbenchError as exc:
        pytest.skip(f"encoder {name} unavailable: {exc}")


@pytest.fixture(scope="module")
def short_task():
    from repbench.testing.toy_task import ToyReachTask

    return ToyReachTask(horizon=10)


@pytest.fixture(scope="module")
def real_encoders(short_task):
    data = short_task.collect("random", n_episodes=2, steps_per_episode=8, seed=0,
                              progress=False)
    oracle = _plugin("oracle").fit(data)
    vae = _plugin("vae_lowkl", latent_dim=8, epochs=1, batch_size=16, progress=False,
                  device="auto").fit(data)
    return {"oracle": oracle, "vae_lowkl": vae}


@pytest.mark.parametrize("agent", ["sac", "ddpg"])
@pytest.mark.parametrize("encoder", ["oracle", "vae_lowkl"])
def test_agents_on_real_encoders(agent, encoder, real_encoders, short_task):
    enc = real_encoders[encoder]
    result = check_agent(agent, short_task, enc, train_steps=30, eval_episodes=1,
                         curve_points=1, learning_starts=10, batch_size=8)
    expected_dim = enc.latent_dim + 4
    assert result.extras["observation_dim"] == expected_dim


def test_full_state_agent_uses_registered_oracle_task(toy_task, toy_dataset):
    _plugin("oracle_task")
    policy, result = train_full_state_agent(toy_task, train_steps=60, seed=0,
                                            dataset=toy_dataset, eval_episodes=1,
                                            curve_points=1, learning_starts=20, batch_size=16,
                                            progress=False)
    assert result.extras["encoder"] == "OracleTaskEncoder"  # the privileged agent's view
    ds = collect_on_policy(toy_task, policy, n_episodes=1, steps_per_episode=5, seed=0,
                           progress=False)
    assert np.isfinite(ds.action).all()


def _peg_task(**params):
    try:
        return repbench.tasks.get("PegInHole-v0")(**params)
    except repbench.RepbenchError as exc:
        pytest.skip(f"PegInHole-v0 unavailable: {exc}")


@pytest.mark.slow
@pytest.mark.parametrize("agent", ["sac", "ddpg"])
def test_smoke_budget_on_peg_in_hole(agent):
    """The smoke suite's RL settings on the real task, oracle and VAE encoders."""
    suite = repbench.load_suite("smoke")
    task = _peg_task(**suite.task_params.get("PegInHole-v0", {}))
    data = task.collect("random", n_episodes=suite.dataset.random_episodes,
                        steps_per_episode=suite.dataset.random_steps, seed=0, progress=False)
    for name in ("oracle", "vae_lowkl"):
        params = {} if name == "oracle" else {
            "latent_dim": suite.encoder_training.latent_dim,
            "epochs": suite.encoder_training.epochs, "progress": False}
        enc = _plugin(name, **params).fit(data)
        params = {**suite.agent_params.get(agent, {}), "progress": False}
        result = repbench.agents.get(agent)(**params).train(
            task, enc, train_steps=suite.rl.train_steps, seed=0,
            eval_episodes=suite.rl.eval_episodes, curve_points=suite.rl.curve_points,
            progress=False)
        print(f"\n{agent} on {name}: return {result.eval_return:.2f}, "
              f"{result.steps_per_s:.1f} steps/s")
        assert len(result.eval_episode_returns) == suite.rl.eval_episodes
        assert np.isfinite(result.eval_return)
