"""Scripted controllers for the contact tasks: known answers for tests and baselines.

Each is a :data:`repbench.task.Policy`: called on one step's observation dict (``image``, ``ft``,
``proprio``, ``last_action`` and, for the privileged ones, ``true_state``) it returns the action.

SurfacePress-v0:

* :class:`PrivilegedPress` reads the true spring force and plate height from z° (privileged);
* :class:`ForceFeedbackPress` uses only the wrist force/torque and proprioception (what a
  representation must carry);
* :class:`BlindPress` is open loop: push at a constant rate for a number of steps, then hold
  (the best of these shows how far the task can be solved without sensing the spring).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from repbench.dataset import FT, PROPRIO, TRUE_STATE
from repbench_tasks.base import TIP_POSITION
from repbench_tasks.config import TABLE_TOP_Z
from repbench_tasks.press_env import PLATE_XY, Z_LOG_K, Z_PLATE, Z_REST, SurfacePressConfig


def _center_xy(proprio: np.ndarray, gain: float = 200.0) -> np.ndarray:
    """Planar action that brings the tip over the plate's centre (a known, fixed place)."""
    tip = np.asarray(proprio, np.float64)[TIP_POSITION]
    return np.clip(-gain * (tip[:2] - np.asarray(PLATE_XY)), -1.0, 1.0)


class PrivilegedPress:
    """Descend over the plate's centre, slowing down near its top (known from z°), then servo
    the true spring force to the target."""

    def __init__(self, config: SurfacePressConfig | None = None, gain: float = 0.04) -> None:
        self.config = config or SurfacePressConfig()
        self.gain = gain

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        cfg = self.config
        z = np.asarray(obs[TRUE_STATE], np.float64)
        tip = np.asarray(obs[PROPRIO], np.float64)[TIP_POSITION]
        top = TABLE_TOP_Z + cfg.plate_height + z[Z_REST] + z[Z_PLATE]
        force = -(10.0 ** z[Z_LOG_K]) * z[Z_PLATE]
        a = np.zeros(3)
        gap = tip[2] - top
        if force < 0.5 and gap > 0.0:
            a[:2] = _center_xy(obs[PROPRIO])
            a[2] = -float(np.clip(gap / 0.01, 0.3, 1.0))
        else:
            a[2] = float(np.clip(self.gain * (force - cfg.target_force), -1.0, 1.0))
        return a.astype(np.float32)


class ForceFeedbackPress:
    """Descend over the plate's centre until the wrist feels contact, then servo the measured
    axial force (sensor z) to the target. No privileged input."""

    def __init__(self, config: SurfacePressConfig | None = None, gain: float = 0.05,
                 descend: float = 1.0) -> None:
        self.config = config or SurfacePressConfig()
        self.gain = gain
        self.descend = descend

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        fz = float(np.asarray(obs[FT])[2])
        a = np.zeros(3)
        if fz < 0.5:
            a[:2] = _center_xy(obs[PROPRIO])
            a[2] = -self.descend
        else:
            a[2] = float(np.clip(self.gain * (fz - self.config.target_force), -1.0, 1.0))
        return a.astype(np.float32)


class BlindPress:
    """Open loop: ``rate`` downwards for ``steps`` steps, then hold (counts its own calls;
    call :meth:`reset` between episodes)."""

    def __init__(self, rate: float, steps: int) -> None:
        self.rate, self.steps, self.t = rate, steps, 0

    def reset(self) -> None:
        """Start a new episode."""
        self.t = 0

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        a = np.array([0.0, 0.0, -self.rate if self.t < self.steps else 0.0], np.float32)
        self.t += 1
        return a


# -- Door-v0 -------------------------------------------------------------------------------------
class PrivilegedDoor:
    """Reach over the ring (known from z°), go down into it, pull along the door's arc.

    ``shift_yaw`` replaces z°'s configuration (an open-loop script recorded for one
    configuration and replayed on others is this controller with a fixed, wrong configuration).
    """

    def __init__(self, shift_yaw: tuple[float, float] | None = None) -> None:
        self.shift_yaw = shift_yaw

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        from repbench_tasks.door_env import (
            DOOR_H,
            ENGAGE_DEPTH,
            RING_HALF,
            ROD_RADIUS,
            Z_ANGLE,
            Z_SHIFT,
            Z_YAW,
            approach_action,
            pull_direction,
            ring_xy,
        )

        z = np.asarray(obs[TRUE_STATE], np.float64)
        shift, yaw = self.shift_yaw or (z[Z_SHIFT], z[Z_YAW])
        tip = np.asarray(obs[PROPRIO], np.float64)[TIP_POSITION]
        angle = float(z[Z_ANGLE])
        target = np.array([*ring_xy(shift, yaw, angle), TABLE_TOP_Z + DOOR_H - ENGAGE_DEPTH])
        s = tip - target
        engaged = bool(s[2] < ENGAGE_DEPTH - 0.005
                       and np.linalg.norm(s[:2]) < RING_HALF - ROD_RADIUS + 0.003)
        return approach_action(s, pull_direction(yaw, angle), engaged).astype(np.float32)


class ReplayDoor:
    """Open loop: replay a recorded action sequence (call :meth:`reset` between episodes)."""

    def __init__(self, actions: np.ndarray) -> None:
        self.actions, self.t = np.asarray(actions, np.float32), 0

    def reset(self) -> None:
        """Start a new episode."""
        self.t = 0

    def __call__(self, obs: Mapping[str, np.ndarray]) -> np.ndarray:
        a = self.actions[min(self.t, len(self.actions) - 1)]
        self.t += 1
        return a
