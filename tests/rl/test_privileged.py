"""The privileged agent, the fixed evaluation episodes and the plan-time checks of issue 11."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import repbench
from repbench.errors import ConfigError
from repbench.pipeline.plan import build_plan
from repbench.pipeline.suite import load_suite
from repbench.rl import SACAgent
from repbench.task import Task
from repbench.testing.toy_task import ToyReachTask

TINY = {"learning_starts": 20, "batch_size": 16, "buffer_size": 500, "normalize_steps": 0,
        "progress": False}

SUITE = """
name = "toy"
tasks = ["{task}"]
encoders = {encoders}
metrics = ["ksg"]
agents = ["sac"]
seeds = [0]
[dataset]
random_episodes = 2
random_steps = 10
on_policy_episodes = 1
on_policy_steps = 10
[encoder_training]
epochs = 1
[rl]
train_steps = {train_steps}
eval_episodes = 2
full_state_train_steps = 2000
[task_params."{task}"]
{task_params}
"""


def suite_file(tmp_path: Path, *, task: str = "ToyReach-v0", encoders: str = '["oracle"]',
               train_steps: int = 2000, task_params: str = "") -> Path:
    p = tmp_path / "suite.toml"
    p.write_text(SUITE.format(task=task, encoders=encoders, train_steps=train_steps,
                              task_params=task_params))
    return p


def test_keep_best_ends_with_the_best_curve_point(toy_task, state_encoder) -> None:
    # the curve and the final evaluation use the same resets here, and evaluation is
    # deterministic, so the kept policy must reproduce its curve point exactly
    agent = SACAgent(keep_best=True, curve_episodes=3, **TINY)
    result = agent.train(toy_task, state_encoder, train_steps=300, seed=0, eval_episodes=3,
                         curve_points=4, progress=False)
    kept = result.extras["kept_step"]
    assert kept in result.curve_steps
    i = result.curve_steps.index(kept)
    best = max(zip(result.curve_success, result.curve_return, strict=True))
    assert (result.curve_success[i], result.curve_return[i]) == best
    assert result.eval_return == pytest.approx(result.curve_return[i])
    last = SACAgent(keep_best=False, curve_episodes=3, **TINY).train(
        toy_task, state_encoder, train_steps=300, seed=0, eval_episodes=3, curve_points=4,
        progress=False)
    assert last.extras["kept_step"] is None


def test_last_curve_point_is_read_from_the_final_evaluation(toy_task, state_encoder) -> None:
    # the last point is the final policy on the curve's episodes, which are a subset of the
    # evaluation episodes: no second rollout, and the numbers agree exactly
    from repbench.rl.agents import spread

    result = SACAgent(curve_episodes=2, **TINY).train(
        toy_task, state_encoder, train_steps=300, seed=0, eval_episodes=4, curve_points=3,
        progress=False)
    assert result.curve_steps[-1] == result.train_steps == 300
    assert len(result.curve_steps) == 3
    subset = spread(list(range(4)), 2)
    rets = result.eval_episode_returns
    assert result.curve_return[-1] == pytest.approx(np.mean([rets[i] for i in subset]))
    succ = result.extras["eval_episode_success"]
    assert result.curve_success[-1] == pytest.approx(np.mean([succ[i] for i in subset]))


def test_curve_episodes_spread_over_the_evaluation_resets() -> None:
    from repbench.rl.agents import spread

    assert spread(list(range(25)), 5) == [0, 6, 12, 18, 24]
    assert spread([1, 2], 5) == [1, 2]


def test_privileged_agent_observes_the_task_frame_state(toy_task, toy_dataset) -> None:
    from repbench.rl import train_full_state_agent

    policy, result = train_full_state_agent(toy_task, train_steps=60, seed=0,
                                            dataset=toy_dataset, eval_episodes=2,
                                            curve_points=1, progress=False,
                                            learning_starts=20, batch_size=16,
                                            normalize_steps=0)
    assert type(policy.encoder).__name__ == "OracleTaskEncoder"
    assert result.extras["role"] == "privileged"
    assert result.extras["params"]["keep_best"] is True
    assert result.extras["params"]["hidden_sizes"] == [256, 256]
    obs, info = toy_task.make_env(seed=1).reset(seed=1)
    z = policy.encoder.encode({k: np.asarray(v)[None] for k, v in
                               {**obs, "true_state": info["true_state"]}.items()})
    np.testing.assert_allclose(z[0], [*(info["true_state"][:2] - info["true_state"][4:]),
                                      *info["true_state"][2:4]], atol=1e-6)


def test_plan_uses_the_privileged_encoder_and_its_settings(tmp_path: Path) -> None:
    plan = build_plan(load_suite(suite_file(tmp_path)))
    cfg = plan.tasks[0].full_state.config
    assert cfg["encoder"] == "oracle_task"
    assert cfg["agent_params"]["keep_best"] is True


def test_task_without_task_state_fails_at_plan_time(tmp_path: Path) -> None:
    class NoTaskState(ToyReachTask):
        task_id = "NoTaskState-v0"
        task_state = Task.task_state

    repbench.tasks.register("NoTaskState-v0")(NoTaskState)
    try:
        with pytest.raises(ConfigError, match="NoTaskState-v0 defines no task_state"):
            build_plan(load_suite(suite_file(tmp_path, task="NoTaskState-v0")))
    finally:
        repbench.tasks.unregister("NoTaskState-v0")


def test_image_encoder_on_a_camera_less_task_fails_at_plan_time(tmp_path: Path) -> None:
    path = suite_file(tmp_path, task="PegInHole-v0", encoders='["oracle", "vae"]',
                      task_params="camera = false")
    with pytest.raises(ConfigError, match=r"encoder .vae. reads the wrist image.*camera = false"):
        build_plan(load_suite(path))


def test_rl_budget_below_learning_starts_fails_at_plan_time(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"learning_starts.*train_steps=500"):
        build_plan(load_suite(suite_file(tmp_path, train_steps=500)))


def test_default_evaluation_resets_are_fixed_seeds() -> None:
    assert ToyReachTask().evaluation_resets(3) == [{"seed": 10_000}, {"seed": 10_001},
                                                   {"seed": 10_002}]
