"""The shared plugin base of repbench's robosuite tasks.

:class:`RobosuiteTask` turns a config dataclass (with ``validate()``) and a
:class:`~repbench_tasks.env.WristTaskEnv` subclass into a :class:`repbench.Task`: validated
construction, environments (physics only when no encoder reads the image), the ``random`` and
``on_policy`` datasets with their metadata, the robot state the agent sees beside μ_z, and the
gymnasium id ``repbench/<task_id>``.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from repbench.dataset import FT, IMAGE, PROPRIO, Dataset
from repbench.errors import ConfigError
from repbench.task import Policy, Task
from repbench_tasks.config import off_grid_point, whole_number

#: Layout of every robosuite task's ``proprio``: joint positions (7), joint velocities (7),
#: tool-point position (3), tool-point linear velocity (3).
TIP_POSITION = slice(14, 17)
TIP_VELOCITY = slice(17, 20)
#: Evaluation episode ``i`` resets with seed ``EVAL_SEED_BASE + i`` (as in ``repbench.rl``).
EVAL_SEED_BASE = 10_000


class RobosuiteTask(Task):
    """Base of the robosuite task plugins. Subclasses set ``task_id``, ``config_class`` and
    ``env_class`` (``"module:Class"``, imported on first use) and store their constructor
    arguments, which must be the fields of ``config_class`` (scikit-learn style)."""

    #: The frozen dataclass of hyperparameters (with ``validate() -> self``).
    config_class: ClassVar[type]
    #: ``"repbench_tasks.module:EnvClass"``: the gymnasium environment, built from a config.
    env_class: ClassVar[str]

    @classmethod
    def sensing(cls) -> str:
        """The default sensors, from ``config_class``'s defaults: camera size and the F/T
        sensor's low-pass cutoff."""
        defaults = {f.name: f.default for f in dataclasses.fields(cls.config_class)}
        n, cutoff = defaults.get("image_size"), defaults.get("ft_cutoff_hz")
        if not isinstance(n, int) or not isinstance(cutoff, (int, float)):
            return ""  # a config without these defaults: say nothing rather than guess
        return f"{n}x{n} wrist RGB, 6-axis wrist F/T ({cutoff:g} Hz low-pass), proprioception"

    def config(self, **overrides: Any) -> Any:
        """The validated configuration, with ``overrides`` applied."""
        params = {**self.get_params(), **overrides}
        fields = {f.name: f for f in dataclasses.fields(self.config_class)}
        unknown = sorted(set(params) - set(fields))
        if unknown:
            raise ConfigError(f"{self.task_id}: unknown parameter(s) {unknown}; known: "
                              f"{sorted(fields)}")
        for name, value in params.items():  # TOML/JSON give lists where the config has pairs
            if str(fields[name].type).startswith("tuple") and isinstance(value, list):
                params[name] = tuple(value)
        return self.config_class(**params).validate()

    def _env_type(self) -> type:
        import importlib

        module, _, name = self.env_class.partition(":")
        return getattr(importlib.import_module(module), name)

    def make_env(self, seed: int | None = None, **overrides: Any) -> gym.Env:
        """A fresh environment (≈1 s to build).

        ``overrides`` replace constructor parameters (e.g. ``camera=False`` for physics only);
        ``render_mode`` is passed to the environment. ``seed`` seeds the first ``reset``.
        """
        render_mode = overrides.pop("render_mode", None)
        env = self._env_type()(self.config(**overrides), render_mode=render_mode)
        if seed is not None:
            env.reset(seed=seed)
        return env

    def make_agent_env(self, seed: int | None = None, *,
                       modalities: Sequence[str] = (IMAGE, FT, PROPRIO)) -> gym.Env:
        """The environment an agent trains in: physics only (no rendering, the ``image`` all
        zeros) when ``modalities`` does not include ``image``."""
        if IMAGE in modalities and not getattr(self, "camera", True):
            raise ConfigError(f"{self.task_id}: camera=False but the encoder reads the wrist "
                              "'image'; set camera = true in task_params or use an encoder "
                              "without the image")
        return self.make_env(seed=seed, camera=IMAGE in modalities)

    def robot_state(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
        """What the agent sees of the robot beside μ_z (``robot_view``): the tool point's
        position and velocity (6-D, the default) or the 20-D ``proprio``."""
        proprio = np.asarray(observation[PROPRIO], dtype=np.float32)
        if getattr(self, "robot_view", "tip") == "tip":
            return np.concatenate([proprio[..., TIP_POSITION], proprio[..., TIP_VELOCITY]], -1)
        return proprio

    def true_state(self, env: Any) -> np.ndarray:
        """z° of ``env`` now (the environment's ``true_state()``)."""
        return env.unwrapped.true_state()

    def collect(self, kind: str, *, n_episodes: int, steps_per_episode: int, seed: int,
                policy: Policy | None = None, progress: bool = True) -> Dataset:
        """Collect ``random`` (the task's backwards exploration, configurations cycling through
        the grid by episode) or ``on_policy`` data; see
        :func:`repbench_tasks.collection.collect`. The contact share is in the metadata."""
        from repbench.pipeline.store import library_versions
        from repbench_tasks.collection import check_collect_args, collect

        check_collect_args(kind, n_episodes, steps_per_episode, policy)  # before the env build
        env = self.make_env(horizon=max(steps_per_episode, 1))
        t0 = time.perf_counter()
        try:
            dataset, stats = collect(env.unwrapped, kind, n_episodes=n_episodes,
                                     steps_per_episode=steps_per_episode, seed=seed,
                                     policy=policy, progress=progress)
        finally:
            env.close()
        dataset.metadata = {
            "task": self.task_id, "task_version": self.version,
            "params": _jsonable(self.get_params()),
            "kind": kind, "seed": int(seed), "n_episodes": int(n_episodes),
            "steps_per_episode": int(steps_per_episode),
            "library_versions": library_versions(),
            "collection_seconds": round(time.perf_counter() - t0, 3), **stats,
        }
        return dataset

    @classmethod
    def register_gym(cls) -> None:
        """Register ``repbench/<task_id>`` with gymnasium (idempotent)."""
        gym_id = f"repbench/{cls.task_id}"
        if gym_id not in gym.registry:
            gym.register(id=gym_id, entry_point=_GymFactory(cls), disable_env_checker=False)


class BoxConfigTask(RobosuiteTask):
    """A task whose per-episode configuration is a point of a 2-D box, drawn from a grid over it
    (training data) or off the grid (held out); its config has ``config_box()`` and
    ``grid_configs()``. Subclasses set ``eval_config_seed`` and ``off_grid_distance`` and say
    how a point of the box becomes reset options (:meth:`box_options`)."""

    #: Seed of the off-grid configurations of the evaluation episodes.
    eval_config_seed: ClassVar[int]
    #: Off-grid configurations lie at least this far from every grid point (box-side units).
    off_grid_distance: ClassVar[float]

    def box_options(self, x: np.ndarray) -> dict[str, float]:
        """The reset options that put an episode at the box point ``x``."""
        raise NotImplementedError

    def evaluation_resets(self, n: int) -> list[dict[str, Any]]:
        """``n`` fixed evaluation episodes: every grid configuration once (in order), then
        configurations off the grid (at least ``off_grid_distance`` from every grid point),
        each with its own reset seed ``EVAL_SEED_BASE + i``."""
        if not whole_number(n) or n < 1:
            raise ConfigError(f"{self.task_id}: evaluation episodes n={n!r} must be a positive "
                              "int")
        cfg = self.config()
        grid = cfg.grid_configs()
        lo, hi = cfg.config_box()
        rng = np.random.default_rng(self.eval_config_seed)
        resets: list[dict[str, Any]] = []
        for i in range(n):
            seed = EVAL_SEED_BASE + i
            if i < len(grid):
                resets.append({"seed": seed, "options": {"config_index": i}})
                continue
            x = off_grid_point(rng, grid, lo, hi, self.off_grid_distance)
            resets.append({"seed": seed, "options": self.box_options(x)})
        return resets


class _GymFactory:
    """gymnasium entry point: constructor parameters (+ ``render_mode``) -> environment."""

    def __init__(self, cls: type[RobosuiteTask]) -> None:
        self.cls = cls

    def __call__(self, **kwargs: Any) -> gym.Env:
        params = {k: v for k, v in kwargs.items() if k != "render_mode"}
        return self.cls(**params).make_env(render_mode=kwargs.get("render_mode"))


def _jsonable(params: dict[str, Any]) -> dict[str, Any]:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in params.items()}
