"""Gymnasium environments around repbench's robosuite simulations.

:class:`WristTaskEnv` is the shared base: a single-arm Panda simulation with
:class:`~repbench_tasks.sim.WristSensing`, driven by Cartesian position actions with the
gripper's orientation held, observed through the wrist camera, the filtered wrist force/torque
and proprioception. :class:`PegInHoleEnv` (``repbench/PegInHole-v0``) is the paper's task.

Action: the tool point's Cartesian displacement, ``[-1, 1]^3`` times ``action_scale`` metres per
20 Hz step (robosuite's OSC in the world frame); the grip site's orientation is held at
``target_rot`` by commanding the orientation error every step (robosuite 1.5.2 re-bases OSC
goals on the achieved pose, so an unheld orientation drifts after contact).

Observation dict: ``image`` (wrist camera, uint8, upright), ``ft`` (wrist force/torque minus the
weight below the sensor, low-pass filtered), ``proprio`` (joint positions and velocities, tool
position and velocity), ``last_action``. ``info["true_state"]`` is z°: the arm's generalized
position and velocity plus the task's per-episode configuration (for the peg-in-hole: the hole's
planar position).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from repbench.errors import DataError, RepbenchError
from repbench.task import action_vector
from repbench_tasks.config import START_KINDS, PegInHoleConfig
from repbench_tasks.rendering import WRIST_CAMERA, WristRenderer
from repbench_tasks.rewards import RewardParams, staged_reward
from repbench_tasks.sensing import LowPass
from repbench_tasks.sim import TABLE_TOP_Z, PegInHoleSim

#: The grip site's orientation held during every episode: the gripper's axis (site z) points
#: straight down and the fingers close along the world y axis.
TARGET_ROT = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
ORI_OUTPUT_MAX = 0.5  # rad per step for an orientation action of 1 (controller config)
N_ARM = 7
PROPRIO_DIM = 2 * N_ARM + 6
TRUE_STATE_DIM = 2 * N_ARM + 2

for _name in ("robosuite", "robosuite_logs"):
    logging.getLogger(_name).setLevel(logging.ERROR)


class EnvironmentClosedError(RepbenchError, gym.error.ClosedEnvironmentError, RuntimeError):
    """``step`` or ``reset`` of an environment after its ``close()`` (gymnasium's
    ``ClosedEnvironmentError``, and a RuntimeError)."""


class WristTaskEnv(gym.Env):
    """Base of repbench's robosuite environments (see the module docstring).

    Subclasses build the simulation in :meth:`_build_sim` (a robosuite environment with
    :class:`~repbench_tasks.sim.WristSensing`) and implement the per-episode hooks:
    :meth:`_configure` (choose the episode's configuration from ``options`` and
    ``self.np_random``), :meth:`_apply_configuration` (write it into the model),
    :meth:`_start_tool` (the tool point's start position), :meth:`_reward` and
    :meth:`true_state`; the data-collection hooks are :meth:`exploration_options`,
    :meth:`make_explorer` and :meth:`on_policy_options`.

    ``config`` must have ``horizon``, ``image_size``, ``camera``, ``fast_render``,
    ``action_scale``, ``physics_dt`` and ``ft_cutoff_hz``.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 20}
    #: Label of progress bars and messages.
    task_label: ClassVar[str] = "task"
    #: The grip site's orientation held every step (world frame, columns = site axes).
    target_rot: ClassVar[np.ndarray] = TARGET_ROT
    #: Observation sizes.
    proprio_dim: ClassVar[int] = PROPRIO_DIM
    #: How far below the grip site (along its z axis) the tool point lies (m).
    tool_in_site: float = 0.0

    def __init__(self, config: Any, render_mode: str | None = None) -> None:
        self.config = cfg = config.validate()
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        default_render = cfg.camera and not cfg.fast_render
        self.sim = self._build_sim(
            has_renderer=False, has_offscreen_renderer=default_render,
            use_camera_obs=default_render, camera_names=WRIST_CAMERA,
            camera_heights=cfg.image_size, camera_widths=cfg.image_size, control_freq=20,
            horizon=10**9, ignore_done=True, hard_reset=False)
        self._disable_observables(keep_camera=default_render)
        self.model: mujoco.MjModel = self.sim.sim.model._model
        self.data: mujoco.MjData = self.sim.sim.data._data
        self._ik_data = mujoco.MjData(self.model)
        self._renderer = (WristRenderer(self.model, self.data, cfg.image_size)
                          if cfg.camera and cfg.fast_render else None)
        self._flip_default = False
        if default_render:
            import robosuite.macros as macros

            self._flip_default = macros.IMAGE_CONVENTION != "opencv"
        self._filter = LowPass(cfg.ft_cutoff_hz, 1.0 / cfg.physics_dt)
        #: The controller's largest position step per control step (its ``output_max``, m).
        self._osc_position_max = cfg.action_scale
        self._arm_q = self.sim.arm_qpos_idx
        self._arm_v = self.sim.arm_qvel_idx
        self._is_tool = np.zeros(self.model.ngeom, bool)  # set by subclasses (in_contact)
        self._is_obstacle = np.zeros(self.model.ngeom, bool)
        #: (low, high) corners of the box the tool point's targets are clipped to.
        self.tip_bounds = (np.full(3, -np.inf), np.full(3, np.inf))

        size = cfg.image_size
        self.observation_space = spaces.Dict({
            "image": spaces.Box(0, 255, (size, size, 3), np.uint8),
            "ft": spaces.Box(-np.inf, np.inf, (6,), np.float32),
            "proprio": spaces.Box(-np.inf, np.inf, (self.proprio_dim,), np.float32),
            "last_action": spaces.Box(-1.0, 1.0, (3,), np.float32),
        })
        self.action_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
        self._t = 0
        self._closed = False
        self._last_action = np.zeros(3, np.float32)
        self._image = np.zeros((size, size, 3), np.uint8)
        self._ft = np.zeros(6)

    # -- hooks -----------------------------------------------------------------------------------
    def _build_sim(self, **render_kwargs: Any) -> Any:
        """The robosuite simulation (a :class:`~repbench_tasks.sim.WristSensing` env)."""
        raise NotImplementedError

    def _configure(self, options: dict[str, Any]) -> None:
        """Choose this episode's configuration (``options``, else ``self.np_random``)."""
        raise NotImplementedError

    def _apply_configuration(self) -> None:
        """Write the chosen configuration into the model (after ``mj_resetData``)."""
        raise NotImplementedError

    def _start_tool(self, options: dict[str, Any]) -> np.ndarray:
        """World position of the tool point at the start (may draw from ``np_random``)."""
        raise NotImplementedError

    def _after_reset(self, options: dict[str, Any]) -> None:
        """Set task state after the arm is placed (before ``mj_forward``); default: nothing."""

    def _reward(self) -> tuple[float, bool]:
        """Reward and success flag of the current state (after a step)."""
        raise NotImplementedError

    def true_state(self) -> np.ndarray:
        """z° (float32)."""
        raise NotImplementedError

    def _extra_info(self) -> dict[str, Any]:
        """Task-specific ``info`` entries."""
        return {}

    def exploration_options(self, episode: int) -> dict[str, Any]:
        """``reset`` options of episode ``episode`` of the ``random`` dataset."""
        raise NotImplementedError

    def make_explorer(self, rng: np.random.Generator, **params: Any
                      ) -> Callable[[], np.ndarray]:
        """The ``random`` dataset's exploration policy for one episode: a callable returning
        the next action (reading the environment's state)."""
        raise NotImplementedError

    def on_policy_options(self, episode: int) -> dict[str, Any]:
        """``reset`` options of episode ``episode`` of the ``on_policy`` dataset."""
        return {}

    def collection_stats(self, observations: dict[str, np.ndarray]) -> dict[str, Any]:
        """Extra statistics of a collected dataset for its metadata; default none."""
        return {}

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start an episode; ``options`` are task-specific (see the subclass)."""
        self._check_open("reset")
        super().reset(seed=seed)
        options = dict(options or {})
        self._configure(options)

        mujoco.mj_resetData(self.model, self.data)  # also clears solver warm starts: determinism
        self._apply_configuration()
        obs_rs = self.sim.reset()
        tool = self._start_tool(options)
        q = self._solve_ik(tool - self.target_rot[:, 2] * self.tool_in_site)
        self.data.qpos[self._arm_q] = q
        self.data.qvel[:] = 0.0
        self._after_reset(options)
        mujoco.mj_forward(self.model, self.data)
        for ctrl in self.sim.robots[0].composite_controller.part_controllers.values():
            ctrl.update(force=True)
            if hasattr(ctrl, "reset_goal"):
                ctrl.reset_goal()
        self._filter.reset(np.zeros(6))
        self._ft = np.zeros(6)
        self._t = 0
        self._last_action = np.zeros(3, np.float32)
        if self.sim.use_camera_obs:
            self._make_default_context_current()
            obs_rs = self.sim._get_observations(force_update=True)
        self._update_image(obs_rs)
        return self._obs(), self._info()

    def step(self, action: np.ndarray
             ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Move the tool point by ``action * action_scale`` (clipped to the workspace)."""
        self._check_open("step")
        owner = f"{type(self).__name__}.step"
        a = action_vector(action, 3, owner)
        if not np.all(np.isfinite(a)):  # before clipping, which made an infinite action 1
            raise DataError(f"{owner}: action must be finite, got {action!r}; actions are "
                            "numbers in [-1, 1]")
        a = np.clip(a, -1.0, 1.0)
        tip = self.tip_position()
        target = self._position_goal(tip, a)
        rot = self.data.site_xmat[self.sim.eef_site_id].reshape(3, 3)
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, (self.target_rot @ rot.T).ravel())
        rotvec = np.empty(3)
        mujoco.mju_quat2Vel(rotvec, quat, 1.0)
        command = np.concatenate(((target - tip) / self._osc_position_max,
                                  np.clip(rotvec / ORI_OUTPUT_MAX, -1, 1), [self._gripper()]))
        self.sim.take_ft_samples()  # drop samples from before this step (reset)
        self._make_default_context_current()
        obs_rs = self.sim.step(command)[0]
        self._ft = self._filter(self.sim.take_ft_samples())
        self._t += 1
        self._last_action = a.astype(np.float32)
        self._update_image(obs_rs)
        reward, success = self._reward()
        truncated = self._t >= self.config.horizon
        return self._obs(), float(reward), False, truncated, self._info(success)

    def render(self) -> np.ndarray | None:
        """The last wrist image (``render_mode="rgb_array"``)."""
        return self._image.copy() if self.render_mode == "rgb_array" else None

    def close(self) -> None:
        self._closed = True
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if getattr(self, "sim", None) is not None:
            self.sim.close()

    def _check_open(self, method: str) -> None:
        if self._closed:
            raise EnvironmentClosedError(
                f"{type(self).__name__}.{method}: this environment is closed (its simulation "
                "was released by close()); make a new environment (task.make_env() or "
                "gymnasium.make)")

    # -- state -----------------------------------------------------------------------------------
    def tip_position(self) -> np.ndarray:
        """World position of the tool point (m): ``tool_in_site`` below the grip site."""
        site = self.sim.eef_site_id
        rot = self.data.site_xmat[site].reshape(3, 3)
        return self.data.site_xpos[site] + rot[:, 2] * self.tool_in_site

    def in_contact(self) -> bool:
        """Whether a tool geom touches an obstacle geom (the task's objects, the table)."""
        n = self.data.ncon
        if n == 0:
            return False
        g1, g2 = self.data.contact.geom1[:n], self.data.contact.geom2[:n]
        tool, obstacle = self._is_tool, self._is_obstacle
        hit = (tool[g1] & obstacle[g2]) | (tool[g2] & obstacle[g1])
        return bool(hit.any())

    # -- internals -------------------------------------------------------------------------------
    def _position_goal(self, tip: np.ndarray, action: np.ndarray) -> np.ndarray:
        """The tool point's goal for this step: moved by ``action * action_scale`` from where it
        is (robosuite's OSC re-bases its goal on the achieved pose), clipped to the workspace."""
        return np.clip(tip + action * self.config.action_scale, *self.tip_bounds)

    def _gripper(self) -> float:
        """The gripper command every step: -1 open, 1 closed."""
        return -1.0

    def _solve_ik(self, site_target: np.ndarray, iters: int = 200) -> np.ndarray:
        """Damped least squares for the grip site's position and orientation (kinematics only,
        from the robot's nominal configuration, so the answer depends on the target alone)."""
        m, d = self.model, self._ik_data
        d.qpos[:] = self.data.qpos
        site = self.sim.eef_site_id
        jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        lo, hi = m.jnt_range[self.sim.robots[0]._ref_joint_indexes].T
        target_rot = self.target_rot
        for _ in range(iters):
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            rot = d.site_xmat[site].reshape(3, 3)
            err_p = site_target - d.site_xpos[site]
            err_r = 0.5 * sum(np.cross(rot[:, i], target_rot[:, i]) for i in range(3))
            err = np.concatenate((err_p, err_r))
            if np.linalg.norm(err) < 1e-7:
                break
            mujoco.mj_jacSite(m, d, jacp, jacr, site)
            jac = np.vstack((jacp, jacr))[:, self._arm_v]
            dq = jac.T @ np.linalg.solve(jac @ jac.T + 1e-6 * np.eye(6), err)
            d.qpos[self._arm_q] = np.clip(d.qpos[self._arm_q] + dq, lo, hi)
        return d.qpos[self._arm_q].copy()

    def _make_default_context_current(self) -> None:
        # robosuite renders without making its GL context current; with another context in the
        # process (a second environment, a renderer) it would read another context's buffer.
        ctx = getattr(self.sim.sim, "_render_context_offscreen", None)
        if self.sim.use_camera_obs and ctx is not None:
            ctx.gl_ctx.make_current()

    def _disable_observables(self, keep_camera: bool) -> None:
        self.sim.keep_observables((f"{WRIST_CAMERA}_image",) if keep_camera else ())

    def _update_image(self, obs_rs: Any) -> None:
        if not self.config.camera:
            return
        if self._renderer is not None:
            self._image = self._renderer.render()
        elif obs_rs is not None and f"{WRIST_CAMERA}_image" in obs_rs:
            img = obs_rs[f"{WRIST_CAMERA}_image"]
            self._image = np.ascontiguousarray(img[::-1] if self._flip_default else img)

    def _proprio(self) -> np.ndarray:
        """Joint positions (7) and velocities (7), tool position (3) and velocity (3)."""
        d = self.data
        tip_vel = np.empty(6)
        mujoco.mj_objectVelocity(self.model, d, mujoco.mjtObj.mjOBJ_SITE, self.sim.eef_site_id,
                                 tip_vel, 0)
        return np.concatenate((d.qpos[self._arm_q], d.qvel[self._arm_v],
                               self.tip_position(), tip_vel[3:]))

    def _obs(self) -> dict[str, np.ndarray]:
        return {
            "image": self._image.copy(),
            "ft": self._ft.astype(np.float32),
            "proprio": self._proprio().astype(np.float32),
            "last_action": self._last_action.copy(),
        }

    def _info(self, success: bool | None = None) -> dict[str, Any]:
        if success is None:
            success = self._reward()[1]
        return {"true_state": self.true_state(), "is_success": bool(success),
                "in_contact": self.in_contact(), **self._extra_info()}


class PegInHoleEnv(WristTaskEnv):
    """Panda peg-in-hole with wrist camera and force/torque (see the module docstring).

    Args:
        config: validated task hyperparameters.
        render_mode: ``"rgb_array"`` makes :meth:`render` return the last wrist image.
    """

    task_label: ClassVar[str] = "PegInHole"

    def __init__(self, config: PegInHoleConfig | None = None,
                 render_mode: str | None = None) -> None:
        cfg = (config or PegInHoleConfig()).validate()
        super().__init__(cfg, render_mode)
        self.grid = cfg.grid_positions()
        self.tip_in_site = cfg.peg_length - 0.02  # tip distance below the grip site (m)
        self.tool_in_site = self.tip_in_site
        self.reward_params = RewardParams(
            hole_depth=cfg.hole_depth, clearance=cfg.clearance,
            success_tolerance=cfg.success_tolerance)
        self._is_peg = self._is_tool
        self._is_peg[self.sim.peg_geom_ids] = True
        # the hole's walls and the table
        self._is_obstacle[np.concatenate((self.sim.hole_geom_ids, [self.sim.table_geom_id]))] = True
        lo = np.array([*(np.asarray(cfg.grid_center) - cfg.grid_extent / 2 - 0.12),
                       TABLE_TOP_Z - 0.01])
        hi = np.array([*(np.asarray(cfg.grid_center) + cfg.grid_extent / 2 + 0.12),
                       TABLE_TOP_Z + 0.30])
        self.tip_bounds = (lo, hi)
        self.hole_xy = self.grid[len(self.grid) // 2].copy()

    def _build_sim(self, **render_kwargs: Any) -> PegInHoleSim:
        cfg = self.config
        return PegInHoleSim(
            peg_half_width=cfg.peg_half_width, peg_length=cfg.peg_length,
            clearance=cfg.clearance, hole_depth=cfg.hole_depth,
            wall_thickness=cfg.wall_thickness, action_scale=cfg.action_scale,
            physics_dt=cfg.physics_dt, **render_kwargs)

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start an episode. ``options``: ``start`` (``"above"``/``"inserted"``),
        ``hole_index`` (grid position) or ``hole_xy`` (planar position)."""
        return super().reset(seed=seed, options=options)

    def step(self, action: np.ndarray
             ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Move the peg tip by ``action * action_scale`` (clipped to the workspace)."""
        return super().step(action)

    # -- episode hooks ---------------------------------------------------------------------------
    def _configure(self, options: dict[str, Any]) -> None:
        start = options.get("start", self.config.start)
        if start not in START_KINDS:
            raise ValueError(f"reset option start={start!r} must be one of {START_KINDS}")
        self.hole_xy = self._choose_hole(options)

    def _apply_configuration(self) -> None:
        self.sim.set_hole_xy(self.hole_xy)

    def _start_tool(self, options: dict[str, Any]) -> np.ndarray:
        top = TABLE_TOP_Z + self.config.hole_depth
        if options.get("start", self.config.start) == "inserted":
            return np.array([*self.hole_xy, TABLE_TOP_Z + 0.002])
        lo, hi = self.config.start_height
        off = self.np_random.uniform(-self.config.start_offset, self.config.start_offset, 2)
        return np.array([*(self.hole_xy + off), top + self.np_random.uniform(lo, hi)])

    def _reward(self) -> tuple[float, bool]:
        return staged_reward(self.tip_offset(), self.reward_params)

    def _extra_info(self) -> dict[str, Any]:
        return {"hole_xy": self.hole_xy.copy()}

    # -- collection hooks --------------------------------------------------------------------------
    def exploration_options(self, episode: int) -> dict[str, Any]:
        """Start inserted; grid sampling: at grid position ``episode % G``; uniform sampling:
        at a hole the environment draws anywhere in the grid's square (held-out data)."""
        if self.config.hole_sampling == "grid":
            return {"start": "inserted", "hole_index": episode % len(self.grid)}
        return {"start": "inserted"}

    def make_explorer(self, rng: np.random.Generator, **params: Any
                      ) -> Callable[[], np.ndarray]:
        """:class:`~repbench_tasks.collection.BackwardsExplorer` on the tip's offset."""
        from repbench_tasks.collection import BackwardsExplorer

        explorer = BackwardsExplorer(rng, **params)
        return lambda: explorer(self.tip_offset())

    def on_policy_options(self, episode: int) -> dict[str, Any]:
        return {"start": "above"}

    # -- state -----------------------------------------------------------------------------------
    def tip_offset(self) -> np.ndarray:
        """Peg tip minus the centre of the hole's opening (``z < 0``: inside)."""
        top = np.array([*self.hole_xy, TABLE_TOP_Z + self.config.hole_depth])
        return self.tip_position() - top

    def true_state(self) -> np.ndarray:
        """z°: arm joint positions (7), velocities (7), hole planar position (2); float32."""
        return np.concatenate((self.data.qpos[self._arm_q], self.data.qvel[self._arm_v],
                               self.hole_xy)).astype(np.float32)

    def peg_in_hand_offset(self) -> float:
        """Distance between the peg and where the hand holds it (0 when rigid; for tests)."""
        site = self.sim.eef_site_id
        rot = self.data.site_xmat[site].reshape(3, 3)
        expected = self.data.site_xpos[site] + rot[:, 2] * self.sim.peg_center_in_eef
        return float(np.linalg.norm(self.data.xpos[self.sim.peg_body_id] - expected))

    # -- internals -------------------------------------------------------------------------------
    def _choose_hole(self, options: dict[str, Any]) -> np.ndarray:
        cfg = self.config
        if "hole_xy" in options:
            xy = np.asarray(options["hole_xy"], dtype=np.float64).reshape(2)
            half = cfg.grid_extent / 2 + 1e-9
            if np.any(np.abs(xy - np.asarray(cfg.grid_center)) > half):
                raise ValueError(f"reset option hole_xy={xy.tolist()} lies outside the grid "
                                 f"square (centre {cfg.grid_center}, extent {cfg.grid_extent})")
            return xy
        if "hole_index" in options:
            idx = int(options["hole_index"])
            if not 0 <= idx < len(self.grid):
                raise ValueError(f"reset option hole_index={idx} must be in [0, {len(self.grid)})")
            return self.grid[idx].copy()
        if cfg.hole_sampling == "grid":
            return self.grid[int(self.np_random.integers(len(self.grid)))].copy()
        off = self.np_random.uniform(-cfg.grid_extent / 2, cfg.grid_extent / 2, 2)
        return np.asarray(cfg.grid_center, dtype=np.float64) + off
