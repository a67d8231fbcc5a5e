"""SurfacePress-v0: press a spring-mounted plate to 15 ± 2.5 N and hold it (force-decisive).

``SurfacePressTask`` is the repbench plugin (entry point ``SurfacePress-v0``); importing this
module also registers the gymnasium id ``repbench/SurfacePress-v0``. The environment and its
configuration are in :mod:`repbench_tasks.press_env`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from repbench.dataset import PROPRIO, TRUE_STATE, as_observation_batch
from repbench.errors import DataError
from repbench_tasks.base import TIP_POSITION, TIP_VELOCITY, BoxConfigTask
from repbench_tasks.config import TABLE_TOP_Z
from repbench_tasks.press_env import (
    OFF_GRID_DISTANCE,
    PLATE_XY,
    TASK_ID,
    Z_LOG_K,
    Z_PLATE,
    Z_REST,
    Z_SETPOINT,
    SurfacePressConfig,
)

GYM_ID = f"repbench/{TASK_ID}"
#: The episode's configuration (log10 stiffness, rest-height offset) in z°.
CONFIG = slice(Z_LOG_K, Z_REST + 1)
TASK_STATE_DIM = 8


class SurfacePressTask(BoxConfigTask):
    """Press a spring-mounted plate to a target force; stiffness x rest height on a 5x5 grid.

    Every argument is a field of :class:`~repbench_tasks.press_env.SurfacePressConfig` (see
    there); the constructor validates and stores them, nothing else.
    """

    task_id: ClassVar[str] = TASK_ID
    config_class: ClassVar[type] = SurfacePressConfig
    env_class: ClassVar[str] = "repbench_tasks.press_env:PressEnv"
    version: ClassVar[int] = 0
    eval_config_seed: ClassVar[int] = 31_338
    off_grid_distance: ClassVar[float] = OFF_GRID_DISTANCE

    def __init__(self, horizon: int = 60, grid_size: int = 5,
                 stiffness_range: tuple[float, float] = (500.0, 5000.0),
                 rest_height_range: tuple[float, float] = (-0.02, 0.02),
                 config_sampling: str = "grid", target_force: float = 15.0,
                 force_tolerance: float = 2.5, hold_steps: int = 10, image_size: int = 64,
                 fast_render: bool = True, camera: bool = True, start: str = "above",
                 action_scale: float = 0.005, max_lead: float = 0.02,
                 physics_dt: float = 0.005, ft_cutoff_hz: float = 10.0,
                 robot_view: str = "tip") -> None:
        self.horizon = horizon
        self.grid_size = grid_size
        self.stiffness_range = tuple(stiffness_range)
        self.rest_height_range = tuple(rest_height_range)
        self.config_sampling = config_sampling
        self.target_force = target_force
        self.force_tolerance = force_tolerance
        self.hold_steps = hold_steps
        self.image_size = image_size
        self.fast_render = fast_render
        self.camera = camera
        self.start = start
        self.action_scale = action_scale
        self.max_lead = max_lead
        self.physics_dt = physics_dt
        self.ft_cutoff_hz = ft_cutoff_hz
        self.robot_view = robot_view
        self.config()  # validate now: a bad value fails at construction

    def config(self, **overrides: Any) -> SurfacePressConfig:
        """The validated configuration, with ``overrides`` applied."""
        return super().config(**overrides)

    def box_options(self, x: np.ndarray) -> dict[str, float]:
        """Reset options for the box point ``x`` = (log10 stiffness, rest offset)."""
        return {"stiffness": float(10 ** x[0]), "rest_offset": float(x[1])}

    def task_state(self, observations: Mapping[str, np.ndarray]) -> np.ndarray:
        """The pressing state a controller needs, float32 [N, 8]: the tip's planar offset from
        the plate's centre (2, m), its height above the plate's top now (1, m), the spring's
        force error ``(F - F*) / F*`` (1), the setpoint's vertical lead over the tip (1, m) and
        the tip velocity (3, m/s); from ``proprio`` and z°."""
        batch = as_observation_batch(observations, (PROPRIO, TRUE_STATE), TASK_ID)
        proprio = np.asarray(batch[PROPRIO], np.float64)
        z = np.asarray(batch[TRUE_STATE], np.float64)
        if proprio.ndim != 2 or proprio.shape[1] < TIP_VELOCITY.stop or z.ndim != 2 or (
                z.shape[1] <= Z_REST):
            raise DataError(f"{TASK_ID} task_state: expected proprio [N, 20] and true_state "
                            f"[N, 21], got {list(proprio.shape)} and {list(z.shape)}")
        cfg = self.config()
        tip = proprio[:, TIP_POSITION]
        top = TABLE_TOP_Z + cfg.plate_height + z[:, Z_REST] + z[:, Z_PLATE]
        force = -(10.0 ** z[:, Z_LOG_K]) * z[:, Z_PLATE]
        err = (force - cfg.target_force) / cfg.target_force
        out = np.column_stack([tip[:, 0] - PLATE_XY[0], tip[:, 1] - PLATE_XY[1],
                               tip[:, 2] - top, err, z[:, Z_SETPOINT][:, 2],
                               proprio[:, TIP_VELOCITY]])
        return out.astype(np.float32)


def register_gym() -> None:
    """Register ``repbench/SurfacePress-v0`` with gymnasium (idempotent)."""
    SurfacePressTask.register_gym()


register_gym()
