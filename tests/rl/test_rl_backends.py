"""The SBX (JAX) backend of the SAC/DDPG agents: the same contract as the SB3 one.

SBX ships in the ``sbx`` and ``test`` extras; where it is not installed these tests skip and the
error for ``backend = "sbx"`` is still checked.
"""

from __future__ import annotations

import numpy as np
import pytest

from repbench.errors import ConfigError
from repbench.rl import DDPGAgent, SACAgent, save_policy
from repbench.rl.agents import spread
from repbench.rl.full_state import StandardizedModel, load_model

SMALL = {"learning_starts": 20, "batch_size": 16, "buffer_size": 500, "hidden_sizes": (32, 32),
         "normalize_steps": 50, "progress": False, "backend": "sbx"}


def test_unknown_backend_is_refused(toy_task, state_encoder) -> None:
    with pytest.raises(ConfigError, match="backend"):
        SACAgent(backend="jax", learning_starts=10, progress=False).train(
            toy_task, state_encoder, train_steps=50, seed=0, eval_episodes=1)


def test_missing_sbx_names_the_install(monkeypatch, toy_task, state_encoder) -> None:
    import builtins

    real_import = builtins.__import__

    def no_sbx(name, *args, **kwargs):
        if name == "sbx" or name.startswith("sbx."):
            raise ImportError("No module named 'sbx'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_sbx)
    with pytest.raises(ConfigError, match=r"repbench\[sbx\]"):
        SACAgent(**SMALL).train(toy_task, state_encoder, train_steps=60, seed=0,
                                eval_episodes=1)


@pytest.fixture(scope="module")
def sbx_run(toy_task, state_encoder):
    pytest.importorskip("sbx")
    agent = SACAgent(curve_episodes=2, **SMALL)
    result = agent.train(toy_task, state_encoder, train_steps=200, seed=0, eval_episodes=4,
                         curve_points=2, progress=False)
    return agent, result


def test_sbx_sac_trains_and_reports_like_sb3(sbx_run) -> None:
    agent, result = sbx_run
    assert type(agent.model_).__module__.startswith("sbx")
    assert result.extras["backend"] == "sbx"
    assert np.isfinite(result.eval_return) and result.train_steps == 200
    assert result.curve_steps == [100, 200]
    subset = spread(list(range(4)), 2)  # the last curve point is read from the evaluation
    rets = result.eval_episode_returns
    assert result.curve_return[-1] == pytest.approx(np.mean([rets[i] for i in subset]))
    assert any(d in result.extras["device"].lower() for d in ("cpu", "gpu", "cuda"))


def test_sbx_policy_round_trips_with_its_feature_statistics(sbx_run, tmp_path, toy_task,
                                                            state_encoder) -> None:
    from repbench.rl import make_encoded_env
    from repbench.rl.normalization import standardize

    agent, _ = sbx_run
    stats = agent.model_.repbench_feature_stats
    assert stats is not None  # SBX reads standardized features: saved beside the model
    loaded = load_model(save_policy(agent.model_, tmp_path / "m.zip"))
    assert isinstance(loaded, StandardizedModel)
    env = make_encoded_env(toy_task, state_encoder, seed=3)
    raw, _ = env.reset(seed=3)
    want, _ = agent.model_.predict(standardize(raw, *stats), deterministic=True)
    got, _ = loaded.predict(raw, deterministic=True)  # raw features in, as EncodedPolicy does
    np.testing.assert_allclose(got, want, rtol=1e-6)


def test_sbx_keep_best_ends_with_the_best_curve_point(toy_task, state_encoder) -> None:
    pytest.importorskip("sbx")
    result = SACAgent(keep_best=True, curve_episodes=3, **SMALL).train(
        toy_task, state_encoder, train_steps=240, seed=1, eval_episodes=3, curve_points=4,
        progress=False)
    i = result.curve_steps.index(result.extras["kept_step"])
    assert (result.curve_success[i], result.curve_return[i]) == max(
        zip(result.curve_success, result.curve_return, strict=True))
    assert result.eval_return == pytest.approx(result.curve_return[i])


def test_sbx_ddpg_trains(toy_task, state_encoder) -> None:
    pytest.importorskip("sbx")
    result = DDPGAgent(**SMALL).train(toy_task, state_encoder, train_steps=120, seed=0,
                                      eval_episodes=2, curve_points=1, progress=False)
    assert np.isfinite(result.eval_return) and result.extras["backend"] == "sbx"


def test_sbx_privileged_policy_collects_on_policy_data(toy_task, toy_dataset) -> None:
    pytest.importorskip("sbx")
    from repbench.rl import collect_on_policy, train_full_state_agent

    policy, _ = train_full_state_agent(toy_task, train_steps=120, seed=0,
                                       dataset=toy_dataset, eval_episodes=2,
                                       curve_points=1, **SMALL)
    assert isinstance(policy.model, StandardizedModel)
    data = collect_on_policy(toy_task, policy, n_episodes=1, steps_per_episode=10, seed=0,
                             progress=False)
    assert len(data) == 10
