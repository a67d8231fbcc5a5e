"""The peg-in-hole task of the paper (robosuite 1.5.2, Panda, wrist camera + force/torque).

``PegInHoleTask`` is the repbench plugin (entry point ``PegInHole-v0``); importing this module
also registers the gymnasium id ``repbench/PegInHole-v0``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from repbench.dataset import FT, IMAGE, PROPRIO, TRUE_STATE, Dataset, as_observation_batch
from repbench.errors import ConfigError, DataError
from repbench.task import Policy, Task
from repbench_tasks.config import TABLE_TOP_Z, PegInHoleConfig

#: Layout of ``proprio``: joint positions (7), joint velocities (7), tip position (3), tip
#: linear velocity (3).
TIP_POSITION = slice(14, 17)
TIP_VELOCITY = slice(17, 20)
#: The hole's planar position in z°.
HOLE_XY = slice(14, 16)

GYM_ID = "repbench/PegInHole-v0"
#: Evaluation episode ``i`` resets with seed ``EVAL_SEED_BASE + i`` (as in ``repbench.rl``).
EVAL_SEED_BASE = 10_000
#: Seed of the off-grid hole positions of the evaluation episodes.
EVAL_HOLE_SEED = 31_337


class PegInHoleTask(Task):
    """Peg-in-hole with a 5x5 grid of hole positions (the paper's §IV task).

    Every argument is a field of :class:`~repbench_tasks.config.PegInHoleConfig` (see there);
    the constructor validates and stores them, nothing else.
    """

    task_id: ClassVar[str] = "PegInHole-v0"
    #: 1: the agents' robot state defaults to the tip's position and velocity (``robot_view``).
    version: ClassVar[int] = 1

    def __init__(self, horizon: int = 100, grid_size: int = 5, grid_extent: float = 0.16,
                 grid_center: tuple[float, float] = (0.0, 0.0), hole_sampling: str = "grid",
                 clearance: float = 0.002, image_size: int = 64, fast_render: bool = True,
                 camera: bool = True, start: str = "above", start_offset: float = 0.03,
                 action_scale: float = 0.02, physics_dt: float = 0.005,
                 ft_cutoff_hz: float = 10.0, robot_view: str = "tip") -> None:
        self.horizon = horizon
        self.grid_size = grid_size
        self.grid_extent = grid_extent
        self.grid_center = tuple(grid_center)
        self.hole_sampling = hole_sampling
        self.clearance = clearance
        self.image_size = image_size
        self.fast_render = fast_render
        self.camera = camera
        self.start = start
        self.start_offset = start_offset
        self.action_scale = action_scale
        self.physics_dt = physics_dt
        self.ft_cutoff_hz = ft_cutoff_hz
        self.robot_view = robot_view
        self.config()  # validate now: a bad value fails at construction

    def config(self, **overrides: Any) -> PegInHoleConfig:
        """The validated configuration, with ``overrides`` applied."""
        params = {**self.get_params(), **overrides}
        fields = {f.name for f in dataclasses.fields(PegInHoleConfig)}
        unknown = sorted(set(params) - fields)
        if unknown:
            raise ConfigError(f"PegInHole-v0: unknown parameter(s) {unknown}; known: "
                              f"{sorted(fields)}")
        if "grid_center" in params:
            params["grid_center"] = tuple(params["grid_center"])
        return PegInHoleConfig(**params).validate()

    def make_env(self, seed: int | None = None, **overrides: Any) -> gym.Env:
        """A fresh :class:`~repbench_tasks.env.PegInHoleEnv` (≈1 s to build).

        ``overrides`` replace constructor parameters (e.g. ``camera=False`` for physics only);
        ``render_mode`` is passed to the environment. ``seed`` seeds the first ``reset``.
        """
        from repbench_tasks.env import PegInHoleEnv

        render_mode = overrides.pop("render_mode", None)
        env = PegInHoleEnv(self.config(**overrides), render_mode=render_mode)
        if seed is not None:
            env.reset(seed=seed)
        return env

    def make_agent_env(self, seed: int | None = None, *,
                       modalities: Sequence[str] = (IMAGE, FT, PROPRIO)) -> gym.Env:
        """The environment an agent trains in: physics only (no rendering, the ``image`` all
        zeros) when ``modalities`` does not include ``image``."""
        if IMAGE in modalities and not self.camera:
            raise ConfigError("PegInHole-v0: camera=False but the encoder reads the wrist "
                              "'image'; set camera = true in task_params or use an encoder "
                              "without the image")
        return self.make_env(seed=seed, camera=IMAGE in modalities)

    def robot_state(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
        """What the agent sees of the robot beside μ_z (``robot_view``): the peg tip's position
        and velocity (6-D, the default) or the 20-D ``proprio``."""
        proprio = np.asarray(observation[PROPRIO], dtype=np.float32)
        if self.robot_view == "tip":
            return np.concatenate([proprio[..., TIP_POSITION], proprio[..., TIP_VELOCITY]], -1)
        return proprio

    def evaluation_resets(self, n: int) -> list[dict[str, Any]]:
        """``n`` fixed evaluation episodes: every grid position once (in order), then hole
        positions off the grid (uniform in the grid's square, at least 1 cm from every grid
        position), each with its own reset seed. The same for every encoder and agent."""
        if not isinstance(n, (int, np.integer)) or n < 1:
            raise ConfigError(f"PegInHole-v0: evaluation episodes n={n!r} must be a positive int")
        cfg = self.config()
        grid = cfg.grid_positions()
        rng = np.random.default_rng(EVAL_HOLE_SEED)
        resets: list[dict[str, Any]] = []
        for i in range(n):
            seed = EVAL_SEED_BASE + i
            if i < len(grid):
                resets.append({"seed": seed, "options": {"hole_index": i}})
                continue
            while True:
                xy = np.asarray(cfg.grid_center) + rng.uniform(-cfg.grid_extent / 2,
                                                               cfg.grid_extent / 2, 2)
                if len(grid) == 1 or np.min(np.linalg.norm(grid - xy, axis=1)) >= 0.01:
                    break
            resets.append({"seed": seed, "options": {"hole_xy": [float(v) for v in xy]}})
        return resets

    def true_state(self, env: Any) -> np.ndarray:
        """z° of ``env`` now: arm joint positions and velocities, hole planar position."""
        return env.unwrapped.true_state()

    def task_state(self, observations: Mapping[str, np.ndarray]) -> np.ndarray:
        """Peg tip minus the centre of the hole's opening (3, m) and tip velocity (3, m/s),
        float32 [N, 6], from ``proprio`` and z° (the hole position) of an observation batch."""
        batch = as_observation_batch(observations, (PROPRIO, TRUE_STATE), "PegInHole-v0")
        proprio, z_true = batch[PROPRIO], batch[TRUE_STATE]
        if proprio.ndim != 2 or proprio.shape[1] < TIP_VELOCITY.stop or z_true.ndim != 2 or (
                z_true.shape[1] < HOLE_XY.stop):
            raise DataError(f"PegInHole-v0 task_state: expected proprio [N, 20] and true_state "
                            f"[N, 16], got {list(proprio.shape)} and {list(z_true.shape)}")
        top = np.concatenate([z_true[:, HOLE_XY],
                              np.full((len(z_true), 1), TABLE_TOP_Z + self.config().hole_depth)],
                             axis=1)
        offset = proprio[:, TIP_POSITION].astype(np.float64) - top
        return np.concatenate([offset, proprio[:, TIP_VELOCITY]], axis=1).astype(np.float32)

    def collect(self, kind: str, *, n_episodes: int, steps_per_episode: int, seed: int,
                policy: Policy | None = None, progress: bool = True) -> Dataset:
        """Collect ``random`` (backwards exploration from the inserted peg, hole positions
        cycling through the grid by episode) or ``on_policy`` data; see
        :func:`repbench_tasks.collection.collect`. The contact share is in the metadata."""
        import time

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


def _jsonable(params: dict[str, Any]) -> dict[str, Any]:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in params.items()}


def _make_gym_env(**kwargs: Any) -> gym.Env:
    return PegInHoleTask(**{k: v for k, v in kwargs.items() if k != "render_mode"}).make_env(
        render_mode=kwargs.get("render_mode"))


def register_gym() -> None:
    """Register ``repbench/PegInHole-v0`` with gymnasium (idempotent)."""
    if GYM_ID not in gym.registry:
        gym.register(id=GYM_ID, entry_point=_make_gym_env, disable_env_checker=False)


register_gym()
