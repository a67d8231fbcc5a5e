"""The peg-in-hole task of the paper (robosuite 1.5.2, Panda, wrist camera + force/torque).

``PegInHoleTask`` is the repbench plugin (entry point ``PegInHole-v0``); importing this module
also registers the gymnasium id ``repbench/PegInHole-v0``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from repbench.dataset import PROPRIO, TRUE_STATE, as_observation_batch
from repbench.errors import ConfigError, DataError
from repbench_tasks.base import EVAL_SEED_BASE, TIP_POSITION, TIP_VELOCITY, RobosuiteTask
from repbench_tasks.config import TABLE_TOP_Z, PegInHoleConfig, whole_number

__all__ = ["EVAL_HOLE_SEED", "EVAL_SEED_BASE", "GYM_ID", "HOLE_XY", "TIP_POSITION",
           "TIP_VELOCITY", "PegInHoleTask"]

#: The hole's planar position in z°.
HOLE_XY = slice(14, 16)

GYM_ID = "repbench/PegInHole-v0"
#: Seed of the off-grid hole positions of the evaluation episodes.
EVAL_HOLE_SEED = 31_337


class PegInHoleTask(RobosuiteTask):
    """Peg-in-hole with a 5x5 grid of hole positions (the paper's §IV task).

    Every argument is a field of :class:`~repbench_tasks.config.PegInHoleConfig` (see there);
    the constructor validates and stores them, nothing else.
    """

    task_id: ClassVar[str] = "PegInHole-v0"
    config_class: ClassVar[type] = PegInHoleConfig
    env_class: ClassVar[str] = "repbench_tasks.env:PegInHoleEnv"
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
        return super().config(**overrides)

    def evaluation_resets(self, n: int) -> list[dict[str, Any]]:
        """``n`` fixed evaluation episodes: every grid position once (in order), then hole
        positions off the grid (uniform in the grid's square, at least 1 cm from every grid
        position), each with its own reset seed. The same for every encoder and agent."""
        if not whole_number(n) or n < 1:
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


def register_gym() -> None:
    """Register ``repbench/PegInHole-v0`` with gymnasium (idempotent)."""
    PegInHoleTask.register_gym()


register_gym()
