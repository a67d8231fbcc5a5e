"""Conformance checks for tasks: run them on your task plugin the way repbench does.

``check_task(name_or_instance)`` raises ``AssertionError`` naming the first failed check.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from repbench.dataset import FT, IMAGE, LAST_ACTION, PROPRIO, Dataset
from repbench.task import Task

_MODALITIES = {IMAGE: np.uint8, FT: np.float32, PROPRIO: np.float32, LAST_ACTION: np.float32}


def _resolve(plugin: Any, kwargs: dict[str, Any]) -> Task:
    if isinstance(plugin, Task):
        return plugin
    if isinstance(plugin, str):
        from repbench.registry import tasks

        return tasks.get(plugin)(**kwargs)
    if isinstance(plugin, type) and issubclass(plugin, Task):
        return plugin(**kwargs)
    raise AssertionError(f"check_task needs a task name, Task subclass or instance, got {plugin!r}")


def _check_obs(obs: Any, space: Any, where: str) -> None:
    assert isinstance(obs, dict), f"{where}: observation must be a dict, got {type(obs)}"
    for key, dtype in _MODALITIES.items():
        assert key in obs, f"{where}: observation lacks modality {key!r} (has {sorted(obs)})"
        arr = np.asarray(obs[key])
        assert arr.dtype == dtype, f"{where}: {key} has dtype {arr.dtype}, expected {dtype}"
        if key != IMAGE:
            assert arr.ndim == 1, f"{where}: {key} must be 1-D, got shape {arr.shape}"
            assert np.all(np.isfinite(arr)), f"{where}: {key} is not finite"
    img = np.asarray(obs[IMAGE])
    assert img.ndim == 3 and img.shape[2] == 3, f"{where}: image must be HxWx3, got {img.shape}"
    assert space.contains(obs), f"{where}: observation outside the observation space"


def _check_info(info: Any, where: str, dim: int | None) -> int:
    assert "true_state" in info, f"{where}: info lacks 'true_state'"
    assert "is_success" in info, f"{where}: info lacks 'is_success'"
    z = np.asarray(info["true_state"])
    assert z.dtype == np.float32 and z.ndim == 1, (
        f"{where}: true_state must be float32 1-D, got {z.dtype} {z.shape}")
    assert np.all(np.isfinite(z)), f"{where}: true_state is not finite"
    assert dim is None or z.shape[0] == dim, (
        f"{where}: true_state changed dimension {dim} -> {z.shape[0]}")
    return int(z.shape[0])


def check_task(plugin: Any, *, n_steps: int = 5, seed: int = 0, env_checker: bool = True,
               **kwargs: Any) -> None:
    """Run the task conformance checks.

    Args:
        plugin: a registered task name, a ``Task`` subclass or an instance.
        n_steps: environment steps to take in the rollout and the tiny collection.
        seed: the seed for reset-determinism and collection checks.
        env_checker: also run gymnasium's ``check_env`` on the unwrapped environment.
        kwargs: constructor arguments when ``plugin`` is a name or class.
    """
    import gymnasium as gym

    task = _resolve(plugin, kwargs)
    assert isinstance(getattr(type(task), "task_id", None), str), "task_id must be a string"
    env = task.make_env(seed=seed)
    try:
        assert isinstance(env.action_space, gym.spaces.Box), "action space must be a Box"
        assert isinstance(env.observation_space, gym.spaces.Dict), "observation space: Dict"
        if env_checker:
            from gymnasium.utils.env_checker import check_env

            check_env(env.unwrapped, skip_render_check=True)
        obs, info = env.reset(seed=seed)
        _check_obs(obs, env.observation_space, "reset")
        dim = _check_info(info, "reset", None)
        z = np.asarray(task.true_state(env))
        assert np.allclose(z, info["true_state"]), "true_state(env) differs from info"
        rng = np.random.default_rng(seed)
        env.action_space.seed(seed)
        for i in range(n_steps):
            action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
            obs, reward, _, _, info = env.step(action)
            _check_obs(obs, env.observation_space, f"step {i}")
            _check_info(info, f"step {i}", dim)
            assert np.isfinite(reward), f"step {i}: reward {reward} is not finite"
        r = np.asarray(task.robot_state(obs))
        assert r.ndim == 1 and np.all(np.isfinite(r)), "robot_state must be finite and 1-D"
        # reset(seed) is fully deterministic, whatever happened before
        o1, i1 = env.reset(seed=seed + 1)
        for _ in range(3):
            env.step(env.action_space.sample())
        o2, i2 = env.reset(seed=seed + 1)
        for key in o1:
            assert np.array_equal(o1[key], o2[key]), f"reset(seed) not deterministic: {key}"
        assert np.array_equal(i1["true_state"], i2["true_state"]), (
            "reset(seed) not deterministic: true_state")
    finally:
        env.close()
    ds = task.collect("random", n_episodes=2, steps_per_episode=n_steps, seed=seed,
                      progress=False)
    assert isinstance(ds, Dataset), f"collect must return a repbench.Dataset, got {type(ds)}"
    ds.validate()
    assert len(ds) == 2 * n_steps, f"collect returned {len(ds)} rows, expected {2 * n_steps}"
    assert ds.true_state.shape[1] == dim, "dataset true_state dimension differs from the env's"
    for key, dtype in _MODALITIES.items():
        assert key in ds.observations, f"dataset lacks modality {key!r}"
        got = ds.observations[key].dtype
        assert got == dtype, f"dataset {key} has dtype {got}, expected {dtype}"
    assert ds.metadata.get("task") == task.task_id, "dataset metadata must name the task"
