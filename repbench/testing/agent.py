"""Conformance checks for agents: ``check_agent("sac")`` or ``check_agent(MyAgent(...))``.

Trains the agent twice on a tiny budget with the same seed and checks the
:class:`repbench.AgentResult`: fields, shapes, finite values, a consistent summary, JSON
round trip, and that the evaluation episodes are reproducible (same seed → same returns).
"""

from __future__ import annotations

import inspect
import json
import math
from typing import Any

import numpy as np

from repbench.agent import Agent, AgentResult
from repbench.encoder import Encoder, TrueStateEncoder
from repbench.task import Task

#: Defaults that make SB3-style agents learn within the tiny budget (applied only to the
#: constructor arguments the agent actually has, and only when not given).
_TINY_DEFAULTS = {"learning_starts": 40, "batch_size": 32, "normalize_steps": 20,
                  "progress": False}


def _build(agent_or_name: Any, params: dict[str, Any]) -> Agent:
    if isinstance(agent_or_name, Agent):
        if params:
            raise AssertionError("check_agent: pass params only with an agent name or class")
        return agent_or_name
    cls = agent_or_name
    if isinstance(agent_or_name, str):
        from repbench.registry import agents

        cls = agents.get(agent_or_name)  # unknown name → PluginError with close matches
    if not (inspect.isclass(cls) and issubclass(cls, Agent)):
        raise AssertionError(f"check_agent: {agent_or_name!r} is not a repbench.Agent")
    accepted = inspect.signature(cls.__init__).parameters
    kwargs = {k: v for k, v in _TINY_DEFAULTS.items() if k in accepted}
    kwargs.update(params)
    return cls(**kwargs)


def check_result(result: AgentResult, *, train_steps: int, eval_episodes: int,
                 curve_points: int, label: str = "agent") -> None:
    """Raise AssertionError unless ``result`` is a complete, finite, consistent AgentResult."""
    assert isinstance(result, AgentResult), f"{label}: train returned {type(result)!r}"
    n = len(result.curve_steps)
    assert 1 <= n <= curve_points, f"{label}: {n} curve points, expected 1..{curve_points}"
    assert len(result.curve_return) == n and len(result.curve_success) == n, (
        f"{label}: curve_steps/curve_return/curve_success have different lengths")
    assert all(b > a for a, b in zip(result.curve_steps, result.curve_steps[1:], strict=False)), (
        f"{label}: curve_steps must increase, got {result.curve_steps}")
    assert 0 < result.curve_steps[-1] <= result.train_steps, f"{label}: curve beyond training"
    assert all(math.isfinite(v) for v in result.curve_return), f"{label}: non-finite curve"
    assert all(0.0 <= v <= 1.0 for v in result.curve_success), f"{label}: success not in [0,1]"
    assert len(result.eval_episode_returns) == eval_episodes, (
        f"{label}: {len(result.eval_episode_returns)} evaluation returns, expected "
        f"{eval_episodes}")
    assert all(math.isfinite(v) for v in result.eval_episode_returns), f"{label}: non-finite"
    assert math.isclose(result.eval_return, float(np.mean(result.eval_episode_returns)),
                        rel_tol=1e-6, abs_tol=1e-9), f"{label}: eval_return is not the mean"
    assert 0.0 <= result.eval_success_rate <= 1.0, f"{label}: eval_success_rate not in [0, 1]"
    assert result.train_steps >= train_steps, (
        f"{label}: trained {result.train_steps} steps, asked for {train_steps}")
    assert result.wall_time_s > 0 and math.isfinite(result.wall_time_s), f"{label}: wall time"
    assert result.steps_per_s > 0 and math.isfinite(result.steps_per_s), f"{label}: steps/s"
    d = json.loads(json.dumps(result.to_dict()))
    assert AgentResult.from_dict(d) == result, f"{label}: to_dict/from_dict round trip differs"


def check_agent(agent_or_name: Any, task: Task | None = None, encoder: Encoder | None = None,
                *, train_steps: int = 120, eval_episodes: int = 2, curve_points: int = 2,
                seed: int = 0, **params: Any) -> AgentResult:
    """Train ``agent_or_name`` (a registered name, an Agent class or instance) twice on a tiny
    budget and check its results; return the first result.

    Args:
        agent_or_name: ``"sac"``, ``SACAgent`` or ``SACAgent(...)``.
        task: default :class:`repbench.testing.toy_task.ToyReachTask` (horizon 20).
        encoder: a fitted encoder; default: the true state (fitted on a tiny random dataset).
        train_steps: environment steps of the tiny budget.
        eval_episodes: evaluation episodes of the tiny budget.
        curve_points: learning-curve points of the tiny budget.
        seed: the training seed.
        params: constructor arguments (with a name or class); small ``learning_starts``,
            ``batch_size`` and ``normalize_steps`` are used unless given.

    Raises:
        AssertionError: naming the first check that failed.
    """
    agent = _build(agent_or_name, params)
    label = f"agent {type(agent).__name__}"
    if task is None:
        from repbench.testing.toy_task import ToyReachTask

        task = ToyReachTask(horizon=20)
    if encoder is None:
        data = task.collect("random", n_episodes=1, steps_per_episode=5, seed=seed,
                            progress=False)
        encoder = TrueStateEncoder().fit(data)
    budget = {"train_steps": train_steps, "seed": seed, "eval_episodes": eval_episodes,
              "curve_points": curve_points, "progress": False}
    first = agent.train(task, encoder, **budget)
    check_result(first, train_steps=train_steps, eval_episodes=eval_episodes,
                 curve_points=curve_points, label=label)
    second = agent.train(task, encoder, **budget)
    assert first.eval_episode_returns == second.eval_episode_returns, (
        f"{label}: two runs with seed {seed} gave different evaluation returns "
        f"({first.eval_episode_returns} vs {second.eval_episode_returns}); seed everything "
        "and reset evaluation episodes with fixed seeds")
    assert first.curve_return == second.curve_return, (
        f"{label}: two runs with seed {seed} gave different learning curves")
    return first
