"""Door-v0: hook a ring on a cabinet door with a rod held in the hand and pull the door open.

The Panda holds a rigid rod (welded into the hand below the wrist force/torque sensor, as the
peg-in-hole's peg and SurfacePress's pusher). A cabinet stands on the table with a door on its
front face, hinged about a vertical axis; the door can only be *pulled* open (its joint stops at
closed, and the cabinet blocks its back). The only handle is a ring on the door's top, in front
of the panel near its free edge: the rod must go down into the ring (10 mm clearance each side)
and then pull the ring along the door's arc. What varies per episode is the hinge's pose: its
position along the cabinet's front (``hinge_shift``) and the cabinet's yaw about the hinge, so
the ring lies somewhere in a ~10 cm x 9 cm patch and the direction to pull varies with it.

Action: the rod tip moves by ``[-1, 1]^3 * action_scale`` per 20 Hz step (orientation held
straight down, robosuite's OSC re-based on the achieved pose, as in the peg-in-hole).

z° (18-D): arm joint positions (7) and velocities (7), the door's opening angle and its velocity
(2), and the episode's configuration: the hinge shift (m) and the yaw (rad) (2).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np
from robosuite.environments.manipulation.manipulation_env import ManipulationEnv
from robosuite.models.tasks import ManipulationTask
from robosuite.utils.mjcf_utils import array_to_string

from repbench.errors import ConfigError
from repbench_tasks.config import (
    TABLE_TOP_Z,
    box_grid,
    check_box_config,
    check_timing,
    pick_box_config,
)
from repbench_tasks.env import N_ARM, WristTaskEnv
from repbench_tasks.rewards import reach_reward
from repbench_tasks.sim import (
    ROD_RADIUS,
    ROD_TIP_IN_SITE,
    TABLE_FULL_SIZE,
    TABLE_OFFSET,
    WristSensing,
    exclude_finger_contacts,
    hand_rod,
    osc_position_controller,
    rod_center_in_eef,
    table_arena,
    weld_in_hand,
)

TASK_ID = "Door-v0"
START_KINDS = ("above", "engaged")
REACH_REWARDS = ("distance", "staged")
#: Nominal hinge axis on the table (world x, y; m). The door spans -y from it, facing -x (the
#: robot).
HINGE_XY = (0.06, 0.10)
#: Door panel: thickness, width, height (m).
DOOR_T, DOOR_W, DOOR_H = 0.02, 0.20, 0.12
#: The ring: inner half-width, wall thickness, height (m), its walls flush with the door's top.
RING_HALF, RING_WALL, RING_DEPTH = 0.022, 0.006, 0.03   # 10 mm clearance around the rod
#: The ring's centre in the door frame (x towards the robot is negative; y along the door).
RING_XY = (-(DOOR_T + RING_HALF + RING_WALL), -(DOOR_W - 0.03))
#: Engagement point: the ring's centre, this far below the door's top (m).
ENGAGE_DEPTH = 0.015
#: The staged reach reward's alignment zone about the ring's mouth (m): within this of its
#: axis and below this height above the door's top (the peg-in-hole's eps_align, eps_height).
ALIGN_XY, ALIGN_HEIGHT = 0.01, 0.02
#: The rod: capsule radius, tip distance below the grip site (m).
#: Layout of z°.
Z_ANGLE = 2 * N_ARM
Z_ANGLE_VEL = 2 * N_ARM + 1
Z_SHIFT = 2 * N_ARM + 2
Z_YAW = 2 * N_ARM + 3
TRUE_STATE_DIM = 2 * N_ARM + 4
#: Off-grid configurations lie at least this far from every grid point (box-side units).
OFF_GRID_DISTANCE = 0.0625


@dataclass(frozen=True)
class DoorConfig:
    """Every hyperparameter of :class:`~repbench_tasks.door.DoorTask`."""

    horizon: int = 60
    """Episode length in control steps (20 Hz)."""
    grid_size: int = 5
    """Configurations form a ``grid_size x grid_size`` grid: hinge shift x yaw."""
    shift_range: tuple[float, float] = (-0.08, 0.08)
    """Range of the hinge's shift along world y (m)."""
    yaw_range: tuple[float, float] = (-0.25, 0.25)
    """Range of the cabinet's yaw about the hinge (rad)."""
    config_sampling: str = "grid"
    """``"grid"``: one of the grid configurations per episode; ``"off_grid"``: uniform in the
    box, at least a quarter grid spacing from every grid point (held-out data)."""
    success_angle: float = 0.3
    """Opening angle that counts as open (rad)."""
    hinge_damping: float = 0.3
    """Viscous damping of the hinge (N m s/rad)."""
    hinge_stiffness: float = 0.5
    """Spring pulling the door closed (N m/rad)."""
    hinge_friction: float = 0.05
    """Dry friction of the hinge (N m)."""
    image_size: int = 64
    """Wrist image side (pixels)."""
    fast_render: bool = True
    """Tuned software rendering; False uses robosuite's default camera observable."""
    camera: bool = True
    """False: physics only, the ``image`` observation is all zeros."""
    start: str = "above"
    """Default start: ``"above"`` the door at a fixed place (RL) or ``"engaged"`` with the rod in
    the ring (exploration)."""
    start_xyz: tuple[float, float] = (-0.02, -0.07)
    """Planar position of an ``"above"`` start (m, world); the same for every configuration."""
    start_offset: float = 0.01
    """Half-width of the uniform planar jitter of an ``"above"`` start (m)."""
    start_height: float = 0.07
    """Tip height above the door's top at an ``"above"`` start (m)."""
    action_scale: float = 0.02
    """Tip displacement for an action of 1 (m per step)."""
    physics_dt: float = 0.005
    """Physics step (s)."""
    ft_cutoff_hz: float = 10.0
    """Cut-off of the 2nd-order Butterworth low-pass on the wrist force/torque."""
    robot_view: str = "tip"
    """What the RL agent observes of the robot beside μ_z: ``"tip"`` or ``"proprio"``."""
    reach_reward: str = "staged"
    """Reward before the rod is in the ring: ``"staged"`` (the peg-in-hole's reach and alignment
    stages about the ring's mouth, which pay more above the ring than on the door's top beside
    it; the default since version 1) or ``"distance"`` (to the engagement point); see
    :func:`door_reward`."""

    def config_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners of the configuration box in (hinge shift, yaw)."""
        s, y = self.shift_range, self.yaw_range
        return np.array([s[0], y[0]]), np.array([s[1], y[1]])

    def grid_configs(self) -> np.ndarray:
        """The ``grid_size**2`` configurations (shift, yaw), row-major [G, 2]."""
        return box_grid(*self.config_box(), self.grid_size)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def validate(self) -> DoorConfig:
        """Raise :class:`ConfigError` (one line, naming the field and the fix) on a bad value."""
        def bad(name: str, msg: str) -> ConfigError:
            return ConfigError(f"{TASK_ID}: {name}={getattr(self, name)!r} {msg}")

        check_box_config(self, bad, ("horizon", "grid_size", "image_size"),
                         {"start": START_KINDS, "reach_reward": REACH_REWARDS})
        for name in ("action_scale", "physics_dt", "ft_cutoff_hz", "success_angle",
                     "start_height"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise bad(name, "must be a positive finite number")
        for name in ("hinge_damping", "hinge_stiffness", "hinge_friction", "start_offset"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise bad(name, "must be a finite number >= 0")
        lo, hi = self.shift_range
        if not -0.1 <= lo <= hi <= 0.1:
            raise bad("shift_range", "must be (low, high) m with -0.1 <= low <= high <= 0.1 "
                                     "(default (-0.08, 0.08))")
        lo, hi = self.yaw_range
        if not -0.5 <= lo <= hi <= 0.5:
            raise bad("yaw_range", "must be (low, high) rad with -0.5 <= low <= high <= 0.5 "
                                   "(default (-0.25, 0.25))")
        if self.success_angle > 1.2:
            raise bad("success_angle", "must be at most 1.2 rad (the door opens to 1.5)")
        if not 8 <= self.image_size <= 512:
            raise bad("image_size", "must be an integer in [8, 512] (default 64)")
        if self.start_offset > 0.05:
            raise bad("start_offset", "must be in [0, 0.05] m")
        if self.start_height > 0.2:
            raise bad("start_height", "must be at most 0.2 m")
        if self.action_scale > 0.05:
            raise bad("action_scale", "must be at most 0.05 m per step")
        check_timing(self, bad)
        return self


def _rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


def ring_xy(shift: float, yaw: float, angle: float) -> np.ndarray:
    """World planar position of the ring's centre for a configuration and opening angle.

    The door rotates about the hinge by ``yaw - angle`` (opening turns it clockwise seen from
    above, swinging the free edge towards the robot)."""
    hinge = np.array([HINGE_XY[0], HINGE_XY[1] + shift])
    return hinge + _rot_z(yaw - angle) @ np.asarray(RING_XY)


def ring_xy_batch(shift: np.ndarray, yaw: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """:func:`ring_xy` for arrays [N] -> [N, 2]."""
    a = np.asarray(yaw, np.float64) - np.asarray(angle, np.float64)
    c, s = np.cos(a), np.sin(a)
    rx, ry = RING_XY
    return np.column_stack([HINGE_XY[0] + c * rx - s * ry,
                            HINGE_XY[1] + np.asarray(shift, np.float64) + s * rx + c * ry])


def engage_point(shift: float, yaw: float, angle: float) -> np.ndarray:
    """World position of the engagement point (inside the ring, ``ENGAGE_DEPTH`` below the
    door's top)."""
    return np.array([*ring_xy(shift, yaw, angle), TABLE_TOP_Z + DOOR_H - ENGAGE_DEPTH])


def pull_direction(yaw: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Unit planar direction the ring moves in as the door opens, [N, 2] (or [2])."""
    a = np.asarray(yaw, np.float64) - np.asarray(angle, np.float64)
    c, s = np.cos(a), np.sin(a)
    rx, ry = RING_XY
    # -d/d(angle) of R(a) r = R'(a) r with a sign flip
    d = -np.stack([-s * rx - c * ry, c * rx - s * ry], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


class DoorSim(WristSensing, ManipulationEnv):
    """Panda with a rod and a cabinet whose door is hinged about a vertical axis.

    Args:
        hinge_damping, hinge_stiffness, hinge_friction: the hinge's dynamics.
        max_step: the controller's largest position step (its ``output_max``, m).
        physics_dt: physics step (s).
        kwargs: passed to :class:`ManipulationEnv` (cameras, renderer flags, ...).
    """

    def __init__(self, *, hinge_damping: float, hinge_stiffness: float, hinge_friction: float,
                 max_step: float, physics_dt: float = 0.005, **kwargs: Any) -> None:
        self._init_wrist_sensing(physics_dt)
        self.hinge_params = (hinge_damping, hinge_stiffness, hinge_friction)
        self.table_full_size = TABLE_FULL_SIZE
        self.table_offset = np.array(TABLE_OFFSET)
        self.shift, self.yaw = 0.0, 0.0
        super().__init__(robots="Panda", controller_configs=osc_position_controller(max_step),
                         initialization_noise=None, **kwargs)

    def _load_model(self) -> None:
        super()._load_model()
        robot_model = self.robots[0].robot_model
        arena = table_arena(robot_model, self.table_full_size, self.table_offset)

        self.rod = hand_rod("rod", friction=(0.5, 0.005, 0.0001))
        weld_in_hand(robot_model, self.rod.get_obj(), rod_center_in_eef())
        arena.worldbody.append(self._cabinet_xml())

        self.model = ManipulationTask(mujoco_arena=arena, mujoco_robots=[robot_model])
        self._set_model_timestep()
        self.model.merge_assets(self.rod)
        contact = exclude_finger_contacts(self.model, self.rod.root_body)
        ET.SubElement(contact, "exclude", body1="door_frame", body2="door_leaf")

    def _cabinet_xml(self) -> ET.Element:
        """The cabinet (fixed, origin on the hinge axis at table height) and its door leaf."""
        damping, stiffness, friction = self.hinge_params
        frame = ET.Element("body", name="door_frame",
                           pos=array_to_string([*HINGE_XY, TABLE_TOP_Z]))

        def box(parent: ET.Element, name: str, half: list[float], pos: list[float],
                rgba: str) -> None:
            ET.SubElement(parent, "geom", name=name, type="box", size=array_to_string(half),
                          pos=array_to_string(pos), rgba=rgba, group="1",
                          friction="0.5 0.005 0.0001", solref="0.01 1",
                          solimp="0.9 0.95 0.001")

        depth = 0.18
        # the cabinet: 1 cm taller than the door, so a rod sliding over it cannot catch the
        # door's back edge; its front face is the door's stop
        box(frame, "door_cabinet", [depth / 2, DOOR_W / 2 + 0.01, (DOOR_H + 0.01) / 2],
            [depth / 2 + 0.001, -DOOR_W / 2, (DOOR_H + 0.01) / 2], "0.55 0.4 0.3 1")
        leaf = ET.SubElement(frame, "body", name="door_leaf", pos="0 0 0")
        ET.SubElement(leaf, "joint", name="door_hinge", type="hinge", axis="0 0 -1",
                      limited="true", range="0 1.5", damping=repr(damping),
                      stiffness=repr(stiffness), frictionloss=repr(friction),
                      armature="0.01")
        ET.SubElement(leaf, "inertial", pos=array_to_string([-DOOR_T / 2, -DOOR_W / 2,
                                                             DOOR_H / 2]),
                      mass="0.6", diaginertia="0.003 0.002 0.003")
        # the panel clears the table by 1 cm (no friction on the table top)
        box(leaf, "door_panel", [DOOR_T / 2, DOOR_W / 2, DOOR_H / 2 - 0.005],
            [-DOOR_T / 2, -DOOR_W / 2, DOOR_H / 2 + 0.005], "0.25 0.45 0.75 1")
        cx, cy = RING_XY
        zc = DOOR_H - RING_DEPTH / 2
        outer = RING_HALF + RING_WALL
        hz = RING_DEPTH / 2
        walls = {  # name: (half sizes, centre)
            "front": ([RING_WALL / 2, outer, hz], [cx - RING_HALF - RING_WALL / 2, cy, zc]),
            "back": ([RING_WALL / 2, outer, hz], [cx + RING_HALF + RING_WALL / 2, cy, zc]),
            "left": ([RING_HALF, RING_WALL / 2, hz], [cx, cy + RING_HALF + RING_WALL / 2, zc]),
            "right": ([RING_HALF, RING_WALL / 2, hz], [cx, cy - RING_HALF - RING_WALL / 2, zc]),
        }
        for name, (half, pos) in walls.items():
            box(leaf, f"door_ring_{name}", half, pos, "0.9 0.2 0.2 1")
        return frame

    def _setup_references(self) -> None:
        super()._setup_references()
        m = self.sim.model
        self.frame_body_id = m.body_name2id("door_frame")
        self.rod_body_id = m.body_name2id(self.rod.root_body)
        joint = m.joint_name2id("door_hinge")
        self.hinge_qpos_adr = int(m.jnt_qposadr[joint])
        self.hinge_dof_adr = int(m.jnt_dofadr[joint])
        self.rod_geom_ids = np.array([m.geom_name2id(g) for g in self.rod.contact_geoms])
        self.door_geom_ids = np.array([i for i in range(m._model.ngeom)
                                       if (m.geom_id2name(i) or "").startswith("door_")])
        self.table_geom_id = m.geom_name2id("table_collision")

    def _reset_internal(self) -> None:
        super()._reset_internal()
        if hasattr(self, "frame_body_id"):
            self.set_hinge_pose(self.shift, self.yaw)

    def reward(self, action: Any = None) -> float:
        return 0.0

    def _check_success(self) -> bool:
        return False

    def set_hinge_pose(self, shift: float, yaw: float) -> None:
        """Move the cabinet (soft reset: ``model.body_pos`` and ``body_quat`` of its frame)."""
        self.shift, self.yaw = float(shift), float(yaw)
        m = self.sim.model
        m.body_pos[self.frame_body_id] = [HINGE_XY[0], HINGE_XY[1] + shift, TABLE_TOP_Z]
        m.body_quat[self.frame_body_id] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]


class DoorExplorer:
    """Random actions from the rod in the ring: working the door open and shut, leaving the ring
    and coming back to it (as :class:`~repbench_tasks.press_env.PressExplorer`).

    ``wander``: uniform noise with a weak ``upward_bias`` (the rod leaves the ring); above
    ``ceiling`` over the engagement point it is pushed back down, and back towards it beyond
    ``radius``. With probability ``p_approach`` per step it switches to ``approach``: a drift
    towards the engagement point (rod into the ring) and, once in it, along the pull direction
    (``pull`` > 0 opens, < 0 closes, drawn at the switch); it leaves with ``p_leave`` per step.
    """

    def __init__(self, rng: np.random.Generator, *, noise: float = 0.6,
                 upward_bias: float = 0.25, ceiling: float = 0.06, radius: float = 0.05,
                 p_approach: float = 0.1, p_leave: float = 0.05,
                 approach_bias: float = 0.7) -> None:
        self.rng, self.noise, self.bias = rng, noise, upward_bias
        self.ceiling, self.radius = ceiling, radius
        self.p_approach, self.p_leave, self.approach_bias = p_approach, p_leave, approach_bias
        self.approaching = False
        self.pull = 1.0

    def __call__(self, offset: np.ndarray, direction: np.ndarray, engaged: bool) -> np.ndarray:
        """Action for the tip ``offset`` from the engagement point, the ring's planar opening
        ``direction`` and whether the rod is in the ring."""
        a = self.rng.uniform(-self.noise, self.noise, 3)
        switch = self.rng.random()
        if self.approaching:
            a += self.approach_bias * approach_action(offset, direction, engaged, self.pull)
            self.approaching = switch >= self.p_leave
        else:
            a[2] += self.bias
            if offset[2] > self.ceiling:
                a[2] -= 3 * self.bias
            dist = float(np.linalg.norm(offset[:2]))
            if dist > self.radius:
                a[:2] -= 3 * self.bias * offset[:2] / dist
            if switch < self.p_approach:
                self.approaching = True
                self.pull = 1.0 if self.rng.random() < 0.7 else -1.0
        return np.clip(a, -1.0, 1.0).astype(np.float32)


class DoorEnv(WristTaskEnv):
    """Panda pulling a hinged door open by a ring (see the module docstring).

    Args:
        config: task hyperparameters.
        render_mode: ``"rgb_array"`` makes :meth:`render` return the last wrist image.

    ``reset`` options: ``start`` (``"above"``/``"engaged"``), ``config_index`` (grid
    configuration) or ``shift`` and ``yaw`` (explicit, within the configuration box).
    """

    task_label: ClassVar[str] = "Door"
    tool_in_site: float = ROD_TIP_IN_SITE

    def __init__(self, config: DoorConfig | None = None,
                 render_mode: str | None = None) -> None:
        cfg = (config or DoorConfig()).validate()
        super().__init__(cfg, render_mode)
        self.grid = cfg.grid_configs()
        self._is_tool[self.sim.rod_geom_ids] = True
        self._is_obstacle[np.concatenate((self.sim.door_geom_ids,
                                          [self.sim.table_geom_id]))] = True
        lo = np.array([-0.25, -0.30, TABLE_TOP_Z + 0.01])
        hi = np.array([0.30, 0.30, TABLE_TOP_Z + 0.35])
        self.tip_bounds = (lo, hi)
        self.shift, self.yaw = (float(v) for v in self.grid[len(self.grid) // 2])

    def _build_sim(self, **render_kwargs: Any) -> DoorSim:
        cfg = self.config
        return DoorSim(hinge_damping=cfg.hinge_damping, hinge_stiffness=cfg.hinge_stiffness,
                       hinge_friction=cfg.hinge_friction, max_step=cfg.action_scale,
                       physics_dt=cfg.physics_dt, **render_kwargs)

    # -- episode hooks ---------------------------------------------------------------------------
    def _configure(self, options: dict[str, Any]) -> None:
        start = options.get("start", self.config.start)
        if start not in START_KINDS:
            raise ValueError(f"reset option start={start!r} must be one of {START_KINDS}")
        self.shift, self.yaw = self._choose_config(options)

    def _apply_configuration(self) -> None:
        self.sim.set_hinge_pose(self.shift, self.yaw)

    def _start_tool(self, options: dict[str, Any]) -> np.ndarray:
        cfg = self.config
        if options.get("start", cfg.start) == "engaged":
            return engage_point(self.shift, self.yaw, 0.0)
        off = self.np_random.uniform(-cfg.start_offset, cfg.start_offset, 2)
        return np.array([*(np.asarray(cfg.start_xyz) + off),
                         TABLE_TOP_Z + DOOR_H + cfg.start_height])

    # -- state -----------------------------------------------------------------------------------
    def door_angle(self) -> float:
        """The door's opening angle (rad, 0 closed)."""
        return float(self.data.qpos[self.sim.hinge_qpos_adr])

    def engage_point(self) -> np.ndarray:
        """World position of the engagement point now (it moves with the door)."""
        return engage_point(self.shift, self.yaw, self.door_angle())

    def tip_offset(self) -> np.ndarray:
        """Rod tip minus the engagement point (m)."""
        return self.tip_position() - self.engage_point()

    def engaged(self) -> bool:
        """Whether the rod's tip is inside the ring (below its top, within its walls)."""
        s = self.tip_offset()
        return bool(s[2] < ENGAGE_DEPTH - 0.005
                    and np.linalg.norm(s[:2]) < RING_HALF - ROD_RADIUS + 0.003)

    def pull_direction(self) -> np.ndarray:
        """Unit planar direction the ring moves in as the door opens."""
        return pull_direction(self.yaw, self.door_angle())

    def _reward(self) -> tuple[float, bool]:
        return door_reward(self.tip_offset(), self.door_angle(), self.engaged(), self.config)

    def _extra_info(self) -> dict[str, Any]:
        return {"door_angle": self.door_angle(), "engaged": self.engaged(),
                "shift": self.shift, "yaw": self.yaw}

    def true_state(self) -> np.ndarray:
        """z° (18-D, float32): arm q (7), q̇ (7), door angle and its velocity (2), hinge shift
        and yaw (2)."""
        d = self.data
        return np.concatenate((
            d.qpos[self._arm_q], d.qvel[self._arm_v],
            [d.qpos[self.sim.hinge_qpos_adr], d.qvel[self.sim.hinge_dof_adr],
             self.shift, self.yaw])).astype(np.float32)

    # -- collection hooks --------------------------------------------------------------------------
    def exploration_options(self, episode: int) -> dict[str, Any]:
        """Start with the rod in the ring; grid: configuration ``episode % G``; off-grid: drawn
        by the environment (held-out data)."""
        if self.config.config_sampling == "grid":
            return {"start": "engaged", "config_index": episode % len(self.grid)}
        return {"start": "engaged"}

    def make_explorer(self, rng: np.random.Generator, **params: Any
                      ) -> Callable[[], np.ndarray]:
        """:class:`DoorExplorer` on the tip's offset from the engagement point."""
        explorer = DoorExplorer(rng, **params)
        return lambda: explorer(self.tip_offset(), self.pull_direction(), self.engaged())

    def on_policy_options(self, episode: int) -> dict[str, Any]:
        return {"start": "above"}

    # -- internals -------------------------------------------------------------------------------
    def _choose_config(self, options: dict[str, Any]) -> tuple[float, float]:
        cfg = self.config
        lo, hi = cfg.config_box()
        if "shift" in options or "yaw" in options:
            x = np.array([float(options.get("shift", (lo[0] + hi[0]) / 2)),
                          float(options.get("yaw", (lo[1] + hi[1]) / 2))])
            if np.any(x < lo - 1e-9) or np.any(x > hi + 1e-9):
                raise ValueError(f"reset options shift={x[0]}, yaw={x[1]} lie outside "
                                 f"shift_range={cfg.shift_range}, yaw_range={cfg.yaw_range}")
            return float(x[0]), float(x[1])
        return pick_box_config(options, self.grid, lo, hi, cfg.config_sampling, self.np_random,
                               OFF_GRID_DISTANCE)


def approach_action(offset: np.ndarray, direction: np.ndarray, engaged: bool,
                    pull: float = 1.0) -> np.ndarray:
    """The privileged reach-hook-pull action, in ``[-1, 1]^3``: over the ring, down into it,
    then along the opening ``direction`` (``pull`` < 0 closes) while staying centred in it."""
    a = np.zeros(3)
    if engaged:
        a[:2] = pull * direction - 60.0 * offset[:2]
        a[2] = -60.0 * offset[2]
    elif float(np.linalg.norm(offset[:2])) > 0.006:
        a[:2] = -100.0 * offset[:2]
        a[2] = 100.0 * (0.03 - offset[2])  # travel 1.5 cm above the ring's top
    else:
        a[:2] = -100.0 * offset[:2]
        a[2] = -100.0 * offset[2]
    return np.clip(a, -1.0, 1.0)


def door_reward(tip_offset: np.ndarray, angle: float, engaged: bool, cfg: DoorConfig
                ) -> tuple[float, bool]:
    """Dense shaped reward and success of one step.

    * reach (rod not in the ring), ``reach_reward="distance"``: ``1 - tanh(10 d)`` in
      ``(0, 1]``, ``d`` the tip's distance from the engagement point;
    * reach, ``reach_reward="staged"``: the peg-in-hole's stages
      (:mod:`repbench_tasks.rewards`) about the ring's mouth ``m`` (the engagement point raised
      to the door's top): alignment, tip within ``ALIGN_XY`` of the ring's axis and below
      ``ALIGN_HEIGHT`` above ``m``, ``1.5 - d_xy / (2 ALIGN_XY)`` in ``(1, 1.5]`` (below the
      engaged reward: going in pays); otherwise
      ``1 - (tanh(10 |s|) + tanh(10 d_xy)) / 2`` in ``(0, 1]`` with ``s`` the tip minus ``m``;
      so hovering over the ring pays more than resting on the door's top beside it, which the
      distance reward pays nearly in full;
    * engaged: ``2 + 6 * angle / success_angle`` in ``[2, 8)``;
    * open (angle >= ``success_angle``, however it got there): ``10`` (success).
    """
    if angle >= cfg.success_angle:
        return 10.0, True
    if engaged:
        return 2.0 + 6.0 * max(angle, 0.0) / cfg.success_angle, False
    if cfg.reach_reward == "staged":
        s = np.asarray(tip_offset, np.float64) - np.array([0.0, 0.0, ENGAGE_DEPTH])
        dxy = float(np.linalg.norm(s[:2]))
        if dxy < ALIGN_XY and s[2] < ALIGN_HEIGHT:
            return 1.5 - 0.5 * dxy / ALIGN_XY, False
        return reach_reward(s), False
    d = float(np.linalg.norm(tip_offset))
    return 1.0 - float(np.tanh(10.0 * d)), False
