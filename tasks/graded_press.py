"""SurfacePress-v1: SurfacePress-v0 with a reward graded by the force error (issue 57's pilot).

The robot, the spring-mounted plate, the configuration grid (stiffness x rest height), the
sensors, the action and the success test (the spring force within ``target_force`` ±
``force_tolerance`` for ``hold_steps`` consecutive steps) are SurfacePress-v0's
(:mod:`repbench_tasks.press_env`). Only the reward in contact differs:

* v0 pays ``1 + 2 exp(-((F - F*) / F*)^2)`` out of the band (nearly flat: 2.56 at 7.5 N off,
  3 at the target) and a flat 5 in it, so an agent whose representation knows the force to
  ±4 N (the F/T VAEs, ``studies/surface_press_why``) earns what a blind one earns;
* v1 pays ``1 + 4 exp(-((F - F*) / w)^2)`` with ``w = reward_width`` (5 N by default) in
  contact, in the band or not (4.12 at the band's edge, 1.21 at 7.5 N off), and 10 once the
  press is held (success), as v0. The return then grows with how precisely the agent holds the
  force, which is what its representation must carry and the wrist camera cannot see.

``GradedPressTask`` is the repbench plugin (entry point ``SurfacePress-v1``); importing this
module also registers the gymnasium id ``repbench/SurfacePress-v1``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from repbench.errors import ConfigError
from repbench_tasks.press_env import TASK_ID as V0_ID
from repbench_tasks.press_env import PressEnv, SurfacePressConfig
from repbench_tasks.surface_press import SurfacePressTask

TASK_ID = "SurfacePress-v1"
GYM_ID = f"repbench/{TASK_ID}"


@dataclass(frozen=True)
class GradedPressConfig(SurfacePressConfig):
    """Every hyperparameter of :class:`GradedPressTask`: SurfacePress-v0's and the width of
    the graded force reward."""

    reward_width: float = 5.0
    """Width (N) of the Gaussian of the force error that the contact reward pays."""

    def validate(self) -> GradedPressConfig:
        """Raise :class:`ConfigError` (one line, naming the field and the fix) on a bad value."""
        v = self.reward_width
        if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) or not (
                np.isfinite(v) and v > 0):
            raise ConfigError(f"{TASK_ID}: reward_width={v!r} must be a positive finite number "
                              "of newtons (default 5.0)")
        try:
            super().validate()
        except ConfigError as exc:
            raise ConfigError(str(exc).replace(V0_ID, TASK_ID)) from None
        return self


def graded_press_reward(force: float, tip_offset: np.ndarray, in_band_steps: int,
                        cfg: GradedPressConfig) -> tuple[float, bool]:
    """Reward and success of one step.

    * reach (no spring force yet, ≤ 0.5 N): ``1 - tanh(10 d)`` in ``(0, 1]``, ``d`` the tip's
      distance from the plate's top centre at rest (as v0);
    * contact: ``1 + 4 exp(-((F - F*) / w)^2)`` in ``(1, 5]``;
    * ``10`` once the force has been in ``F* ± force_tolerance`` for ``hold_steps``
      consecutive steps (success, as v0).
    """
    err = force - cfg.target_force
    if abs(err) <= cfg.force_tolerance and in_band_steps >= cfg.hold_steps:
        return 10.0, True
    if force > 0.5:
        return 1.0 + 4.0 * float(np.exp(-((err / cfg.reward_width) ** 2))), False
    return 1.0 - float(np.tanh(10.0 * float(np.linalg.norm(tip_offset)))), False


class GradedPressEnv(PressEnv):
    """:class:`~repbench_tasks.press_env.PressEnv` with :func:`graded_press_reward`."""

    def __init__(self, config: GradedPressConfig | None = None,
                 render_mode: str | None = None) -> None:
        super().__init__(config or GradedPressConfig(), render_mode)

    def _reward(self) -> tuple[float, bool]:
        cfg = self.config
        force = self.spring_force()
        in_band = abs(force - cfg.target_force) <= cfg.force_tolerance
        self._in_band = self._in_band + 1 if in_band else 0
        return graded_press_reward(force, self.tip_offset(), self._in_band, cfg)


class GradedPressTask(SurfacePressTask):
    """SurfacePress-v0 with the graded force reward (module docstring). Every argument is a
    field of :class:`GradedPressConfig`; the constructor validates and stores them."""

    task_id: ClassVar[str] = TASK_ID
    config_class: ClassVar[type] = GradedPressConfig
    env_class: ClassVar[str] = "repbench_tasks.graded_press:GradedPressEnv"
    version: ClassVar[int] = 0

    def __init__(self, horizon: int = 60, grid_size: int = 5,
                 stiffness_range: tuple[float, float] = (500.0, 5000.0),
                 rest_height_range: tuple[float, float] = (-0.02, 0.02),
                 config_sampling: str = "grid", target_force: float = 15.0,
                 force_tolerance: float = 2.5, hold_steps: int = 10, image_size: int = 64,
                 fast_render: bool = True, camera: bool = True, start: str = "above",
                 action_scale: float = 0.005, max_lead: float = 0.02,
                 physics_dt: float = 0.005, ft_cutoff_hz: float = 10.0,
                 robot_view: str = "tip", reward_width: float = 5.0) -> None:
        self.reward_width = reward_width  # before the base validates get_params()
        super().__init__(horizon=horizon, grid_size=grid_size, stiffness_range=stiffness_range,
                         rest_height_range=rest_height_range, config_sampling=config_sampling,
                         target_force=target_force, force_tolerance=force_tolerance,
                         hold_steps=hold_steps, image_size=image_size,
                         fast_render=fast_render, camera=camera, start=start,
                         action_scale=action_scale, max_lead=max_lead, physics_dt=physics_dt,
                         ft_cutoff_hz=ft_cutoff_hz, robot_view=robot_view)

    def config(self, **overrides: Any) -> GradedPressConfig:
        """The validated configuration, with ``overrides`` applied."""
        return super().config(**overrides)


def register_gym() -> None:
    """Register ``repbench/SurfacePress-v1`` with gymnasium (idempotent)."""
    GradedPressTask.register_gym()


register_gym()
