"""Gymnasium ids for the registered tasks, following Gymnasium's convention for env packages.

``import repbench`` registers ``repbench/<task id>`` for every task found through the
``repbench.tasks`` entry points (``repbench/PegInHole-v0``, ``repbench/ToyReach-v0``, and a
third-party package's versioned ids), so this works in a fresh interpreter::

    import gymnasium
    import repbench

    env = gymnasium.make("repbench/PegInHole-v0", camera=False)

Registration is lazy: it reads entry-point metadata and registers a string entry point
(:func:`make_env`); no task module, simulator or renderer is imported until ``gymnasium.make``.
Keyword arguments of ``gymnasium.make`` are the task's constructor parameters (plus
``render_mode``). A task registered later by a decorator gets its id from
:func:`register_gym_envs` called again.
"""

from __future__ import annotations

import re
from typing import Any

NAMESPACE = "repbench"
#: Gymnasium's env name with a version suffix (``Name-v0``); other task names get no gym id.
_VERSIONED = re.compile(r"^[\w.-]+-v\d+$")


def make_env(task: str, render_mode: str | None = None, **params: Any) -> Any:
    """The gymnasium entry point of ``repbench/<task>``: build the task, then its env."""
    from repbench.registry import tasks

    overrides = {} if render_mode is None else {"render_mode": render_mode}
    return tasks.get(task)(**params).make_env(**overrides)


def register_gym_envs() -> list[str]:
    """Register ``repbench/<name>`` for every versioned task name not yet known to gymnasium;
    return the ids registered now."""
    import gymnasium as gym

    from repbench.registry import tasks

    added = []
    for name in tasks.names():
        gym_id = f"{NAMESPACE}/{name}"
        if _VERSIONED.match(name) and gym_id not in gym.registry:
            gym.register(id=gym_id, entry_point="repbench.gym_envs:make_env",
                         kwargs={"task": name})
            added.append(gym_id)
    return added
