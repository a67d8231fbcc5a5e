"""SurfacePress-v0: press a spring-mounted plate to a target force (robosuite 1.5.2, Panda).

The Panda holds a rigid pusher rod (welded into the hand below the wrist force/torque sensor, as
the peg-in-hole's peg). A square plate rides on a vertical slide joint with a linear spring; what
varies per episode is the spring's stiffness ``k`` and the plate's rest height. The task: press
the plate until the spring carries ``target_force`` ± ``force_tolerance`` newtons, and hold it
there for ``hold_steps`` consecutive steps.

Action: the pusher tip's *setpoint* moves by ``[-1, 1]^3 * action_scale`` per 20 Hz step (the
orientation held straight down). Unlike the peg-in-hole, the setpoint is held between steps
(position control of a real arm): it is clipped to at most ``max_lead`` from the tip, and the
stiff OSC pushes the tip towards it. That is what makes the task need force: with robosuite's
goal re-based on the achieved pose each step, a constant action is a constant force whatever
the spring, and an open-loop push would solve every configuration. With a held setpoint the
force follows ``k`` and the rest height (the series stiffness of arm and spring), which the
wrist camera hardly shows and the force/torque sensor measures.

z° (21-D): arm joint positions (7) and velocities (7), the setpoint's offset from the tip (3:
the controller's state), the plate's displacement from rest and its velocity (2), and the
episode's configuration: ``log10(k)`` and the rest-height offset (2).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np
from robosuite.environments.manipulation.manipulation_env import ManipulationEnv
from robosuite.models.objects import BoxObject
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
from repbench_tasks.sim import (
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

TASK_ID = "SurfacePress-v0"
START_KINDS = ("above", "pressed")
#: Planar position of the plate's centre on the table (m).
PLATE_XY = (0.0, 0.0)
#: The pusher rod: capsule radius, length below the grip site to the tip (m).
#: Layout of z°.
Z_SETPOINT = slice(2 * N_ARM, 2 * N_ARM + 3)
Z_PLATE = 2 * N_ARM + 3
Z_PLATE_VEL = 2 * N_ARM + 4
Z_LOG_K = 2 * N_ARM + 5
Z_REST = 2 * N_ARM + 6
TRUE_STATE_DIM = 2 * N_ARM + 7
#: Off-grid (held-out) configurations lie at least this far from every grid point, in units of
#: the configuration box's side per axis (a quarter of the 5 x 5 grid's spacing).
OFF_GRID_DISTANCE = 0.0625


@dataclass(frozen=True)
class SurfacePressConfig:
    """Every hyperparameter of :class:`~repbench_tasks.surface_press.SurfacePressTask`."""

    horizon: int = 60
    """Episode length in control steps (20 Hz)."""
    grid_size: int = 5
    """Configurations form a ``grid_size x grid_size`` grid: stiffness (log-spaced) x rest
    height."""
    stiffness_range: tuple[float, float] = (500.0, 5000.0)
    """Spring stiffness range (N/m); grid values are log-spaced."""
    rest_height_range: tuple[float, float] = (-0.02, 0.02)
    """Range of the plate's rest height relative to ``plate_height`` (m)."""
    config_sampling: str = "grid"
    """``"grid"``: one of the grid configurations per episode; ``"off_grid"``: uniform in
    (log stiffness, rest height), at least a quarter grid spacing from every grid point
    (held-out data)."""
    target_force: float = 15.0
    """Spring force to reach (N)."""
    force_tolerance: float = 2.5
    """Half-width of the accepted force band (N)."""
    hold_steps: int = 10
    """Consecutive in-band steps for success."""
    plate_height: float = 0.10
    """Nominal height of the plate's top above the table at rest (m)."""
    plate_half: float = 0.06
    """Half the side of the square plate (m)."""
    plate_mass: float = 0.3
    """Plate mass (kg); its weight is compensated (the rest height is where it rests)."""
    damping_ratio: float = 0.5
    """Damping of the plate's spring relative to critical (``2 sqrt(k m)``)."""
    max_lead: float = 0.02
    """Largest distance between the setpoint and the pusher tip (m)."""
    image_size: int = 64
    """Wrist image side (pixels)."""
    fast_render: bool = True
    """Tuned software rendering; False uses robosuite's default camera observable."""
    camera: bool = True
    """False: physics only, the ``image`` observation is all zeros."""
    start: str = "above"
    """Default start: ``"above"`` the plate (RL) or ``"pressed"`` at the target force
    (backwards exploration)."""
    start_offset: float = 0.02
    """Half-width of the uniform planar offset of an ``"above"`` start from the plate's centre
    (m)."""
    start_height: tuple[float, float] = (0.02, 0.05)
    """Range of the tip's height above the plate's rest top for an ``"above"`` start (m)."""
    action_scale: float = 0.005
    """Setpoint displacement for an action of 1 (m per step)."""
    physics_dt: float = 0.005
    """Physics step (s)."""
    ft_cutoff_hz: float = 10.0
    """Cut-off of the 2nd-order Butterworth low-pass on the wrist force/torque."""
    robot_view: str = "tip"
    """What the RL agent observes of the robot beside μ_z: ``"tip"`` (position and velocity
    of the pusher tip) or ``"proprio"`` (20 numbers)."""

    # -- derived -------------------------------------------------------------------------------
    def config_box(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners of the configuration box in (log10 k, rest offset)."""
        k, h = self.stiffness_range, self.rest_height_range
        return (np.array([np.log10(k[0]), h[0]]), np.array([np.log10(k[1]), h[1]]))

    def grid_configs(self) -> np.ndarray:
        """The ``grid_size**2`` configurations (log10 k, rest offset), row-major [G, 2]."""
        return box_grid(*self.config_box(), self.grid_size)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    # -- validation ----------------------------------------------------------------------------
    def validate(self) -> SurfacePressConfig:
        """Raise :class:`ConfigError` (one line, naming the field and the fix) on a bad value."""
        def bad(name: str, msg: str) -> ConfigError:
            return ConfigError(f"{TASK_ID}: {name}={getattr(self, name)!r} {msg}")

        check_box_config(self, bad, ("horizon", "grid_size", "hold_steps", "image_size"),
                         {"start": START_KINDS})
        for name in ("target_force", "force_tolerance", "plate_height", "plate_half",
                     "plate_mass", "damping_ratio", "max_lead", "action_scale", "physics_dt",
                     "ft_cutoff_hz"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise bad(name, "must be a positive finite number")
        k_lo, k_hi = self.stiffness_range
        if not (np.isfinite(k_lo) and np.isfinite(k_hi) and 50 <= k_lo <= k_hi <= 50_000):
            raise bad("stiffness_range", "must be (low, high) N/m with 50 <= low <= high <= "
                                         "50000 (default (500, 5000))")
        h_lo, h_hi = self.rest_height_range
        if not (np.isfinite(h_lo) and np.isfinite(h_hi) and -0.05 <= h_lo <= h_hi <= 0.05):
            raise bad("rest_height_range", "must be (low, high) m with -0.05 <= low <= high <= "
                                           "0.05 (default (-0.02, 0.02))")
        if self.force_tolerance >= self.target_force:
            raise bad("force_tolerance", f"must be below target_force={self.target_force} N")
        travel = self.target_force * 2 / k_lo
        if self.plate_height + h_lo - travel < 0.01:
            raise bad("plate_height", f"leaves the softest spring no room to press "
                                      f"{2 * self.target_force:.0f} N (needs plate_height + "
                                      f"rest low - {travel:.3f} m >= 0.01 m); raise it or "
                                      "stiffen stiffness_range")
        if self.plate_half > 0.2:
            raise bad("plate_half", "must be at most 0.2 m (the table is 0.8 m wide)")
        if not 8 <= self.image_size <= 512:
            raise bad("image_size", "must be an integer in [8, 512] (default 64)")
        lo, hi = self.start_height
        if not 0 <= lo <= hi <= 0.25:
            raise bad("start_height", "must be (low, high) with 0 <= low <= high <= 0.25 m")
        if not 0 <= self.start_offset <= self.plate_half:
            raise bad("start_offset", "must be in [0, plate_half] m (start above the plate)")
        if self.max_lead < self.action_scale:
            raise bad("max_lead", f"must be at least action_scale={self.action_scale} m")
        check_timing(self, bad)
        return self


class PressSim(WristSensing, ManipulationEnv):
    """Panda with a pusher rod and a spring-mounted plate on robosuite's table arena.

    Args:
        plate_half: half the plate's side (m).
        plate_height: the plate top's nominal rest height above the table (m).
        plate_mass: plate mass (kg), weight compensated.
        action_scale: unused by the model (the controller's step is ``max_lead``).
        max_lead: the controller's largest position step (its ``output_max``, m).
        physics_dt: physics step (s).
        kwargs: passed to :class:`ManipulationEnv` (cameras, renderer flags, ...).
    """

    plate_thickness = 0.01

    def __init__(self, *, plate_half: float, plate_height: float, plate_mass: float,
                 max_lead: float, physics_dt: float = 0.005, **kwargs: Any) -> None:
        self._init_wrist_sensing(physics_dt)
        self.plate_half = plate_half
        self.plate_height = plate_height
        self.plate_mass = plate_mass
        self.table_full_size = TABLE_FULL_SIZE
        self.table_offset = np.array(TABLE_OFFSET)
        self.stiffness = 1000.0
        self.rest_offset = 0.0
        self.damping = 1.0
        super().__init__(robots="Panda", controller_configs=osc_position_controller(max_lead),
                         initialization_noise=None, **kwargs)

    def _load_model(self) -> None:
        super()._load_model()
        robot_model = self.robots[0].robot_model
        arena = table_arena(robot_model, self.table_full_size, self.table_offset)

        self.rod = hand_rod("pusher", friction=(0.8, 0.005, 0.0001))
        weld_in_hand(robot_model, self.rod.get_obj(), rod_center_in_eef())

        t = self.plate_thickness
        volume = (2 * self.plate_half) ** 2 * t
        self.plate = BoxObject(
            name="plate", size=[self.plate_half, self.plate_half, t / 2],
            rgba=[0.2, 0.45, 0.8, 1], density=self.plate_mass / volume,
            friction=(0.8, 0.005, 0.0001), solref=(0.01, 1.0), solimp=(0.9, 0.95, 0.001),
            joints=[{"name": "spring", "type": "slide", "axis": "0 0 1", "limited": "true",
                     "range": "-0.07 0.02", "stiffness": "1000", "damping": "10",
                     "armature": "0.01"}],
            obj_type="all")
        plate_obj = self.plate.get_obj()
        plate_obj.set("pos", array_to_string([*PLATE_XY, self.plate_z0()]))
        plate_obj.set("gravcomp", "1")
        # a visual stem under the plate (moves with it; its foot is hidden in the table)
        ET.SubElement(plate_obj, "geom", name="plate_stem", type="cylinder",
                      size=array_to_string([0.015, 0.09]), pos="0 0 -0.095",
                      rgba="0.55 0.55 0.6 1", contype="0", conaffinity="0", group="1",
                      mass="0")
        arena.worldbody.append(plate_obj)

        self.model = ManipulationTask(mujoco_arena=arena, mujoco_robots=[robot_model])
        self._set_model_timestep()
        self.model.merge_assets(self.rod)
        self.model.merge_assets(self.plate)
        exclude_finger_contacts(self.model, self.rod.root_body)

    def plate_z0(self) -> float:
        """World height of the plate body's centre at the nominal rest height."""
        return TABLE_TOP_Z + self.plate_height - self.plate_thickness / 2

    def _setup_references(self) -> None:
        super()._setup_references()
        m = self.sim.model
        self.plate_body_id = m.body_name2id(self.plate.root_body)
        self.rod_body_id = m.body_name2id(self.rod.root_body)
        joint = m.joint_name2id(self.plate.joints[0])
        self.spring_qpos_adr = int(m.jnt_qposadr[joint])
        self.spring_dof_adr = int(m.jnt_dofadr[joint])
        self.spring_joint_id = joint
        self.rod_geom_ids = np.array([m.geom_name2id(g) for g in self.rod.contact_geoms])
        self.plate_geom_ids = np.array([m.geom_name2id(g) for g in self.plate.contact_geoms])
        self.table_geom_id = m.geom_name2id("table_collision")

    def _reset_internal(self) -> None:
        super()._reset_internal()
        if hasattr(self, "plate_body_id"):
            self.set_spring(self.stiffness, self.rest_offset, self.damping)

    def reward(self, action: Any = None) -> float:
        return 0.0

    def _check_success(self) -> bool:
        return False

    def set_spring(self, stiffness: float, rest_offset: float, damping: float) -> None:
        """Set the spring (soft reset: ``model.jnt_stiffness``, ``dof_damping`` and the plate
        body's rest height in ``model.body_pos``)."""
        self.stiffness, self.rest_offset, self.damping = stiffness, rest_offset, damping
        m = self.sim.model
        m.jnt_stiffness[self.spring_joint_id] = stiffness
        m.dof_damping[self.spring_dof_adr] = damping
        m.body_pos[self.plate_body_id][2] = self.plate_z0() + rest_offset


class PressExplorer:
    """Random actions from the pressed plate: off it, around it, and back onto it.

    As the peg-in-hole's :class:`~repbench_tasks.collection.BackwardsExplorer`: uniform noise of
    amplitude ``noise`` plus a drift from a two-mode Markov chain, so the data stay near the
    goal. ``wander`` (the start): a weak ``upward_bias`` lifts the pusher off the plate; above
    ``ceiling`` it is pushed back down, and back towards the plate's centre beyond ``radius``.
    Each step it switches with probability ``p_approach`` to ``approach``: a drift towards a
    setpoint drawn at the switch within ``target_radius`` of the centre and
    ``depth`` (uniform in ``target_depth``) below the plate's rest top, i.e. a press of a random
    depth; each step it switches back with probability ``p_leave``.

    Measured on 10 x 150 steps (seed 0, grid configurations 0-9): 66 % of the samples in
    contact, 19 % with the spring force in the 15 ± 2.5 N band, median wrist force 8.6 N,
    90th percentile 20 N.
    """

    def __init__(self, rng: np.random.Generator, *, noise: float = 0.6,
                 upward_bias: float = 0.3, ceiling: float = 0.05, radius: float = 0.03,
                 p_approach: float = 0.08, p_leave: float = 0.06, approach_bias: float = 0.6,
                 target_radius: float = 0.03,
                 target_depth: tuple[float, float] = (0.0, 0.04)) -> None:
        self.rng, self.noise, self.bias = rng, noise, upward_bias
        self.ceiling, self.radius = ceiling, radius
        self.p_approach, self.p_leave = p_approach, p_leave
        self.approach_bias, self.target_radius = approach_bias, target_radius
        self.target_depth = target_depth
        self.approaching = False
        self.target = np.zeros(3)

    def __call__(self, offset: np.ndarray) -> np.ndarray:
        """Action for the tip ``offset`` from the plate's top centre at rest."""
        a = self.rng.uniform(-self.noise, self.noise, 3)
        switch, draw = self.rng.random(), self.rng.uniform(-1.0, 1.0, 3)
        if self.approaching:
            drift = self.target - offset
            norm = float(np.linalg.norm(drift))
            a += drift * min(self.approach_bias / max(norm, 1e-9), 25.0)
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
                lo, hi = self.target_depth
                depth = lo + (hi - lo) * (draw[2] + 1) / 2
                self.target = np.array([*(self.target_radius * draw[:2]), -depth])
        return np.clip(a, -1.0, 1.0).astype(np.float32)


class PressEnv(WristTaskEnv):
    """Panda pressing a spring-mounted plate (see the module docstring).

    Args:
        config: task hyperparameters.
        render_mode: ``"rgb_array"`` makes :meth:`render` return the last wrist image.

    ``reset`` options: ``start`` (``"above"``/``"pressed"``), ``config_index`` (grid
    configuration) or ``stiffness`` and ``rest_offset`` (explicit, within the configuration
    box).
    """

    task_label: ClassVar[str] = "SurfacePress"
    tool_in_site: float = ROD_TIP_IN_SITE

    def __init__(self, config: SurfacePressConfig | None = None,
                 render_mode: str | None = None) -> None:
        cfg = (config or SurfacePressConfig()).validate()
        super().__init__(cfg, render_mode)
        self._osc_position_max = cfg.max_lead
        self.grid = cfg.grid_configs()
        self._is_tool[self.sim.rod_geom_ids] = True
        self._is_obstacle[np.concatenate((self.sim.plate_geom_ids,
                                          [self.sim.table_geom_id]))] = True
        c = np.asarray(PLATE_XY)
        lo = np.array([*(c - cfg.plate_half - 0.08), TABLE_TOP_Z + 0.005])
        hi = np.array([*(c + cfg.plate_half + 0.08), TABLE_TOP_Z + 0.30])
        self.tip_bounds = (lo, hi)
        self.log_k, self.rest_offset = (float(v) for v in self.grid[len(self.grid) // 2])
        self._setpoint = np.zeros(3)
        self._in_band = 0

    def _build_sim(self, **render_kwargs: Any) -> PressSim:
        cfg = self.config
        return PressSim(plate_half=cfg.plate_half, plate_height=cfg.plate_height,
                        plate_mass=cfg.plate_mass, max_lead=cfg.max_lead,
                        physics_dt=cfg.physics_dt, **render_kwargs)

    # -- episode hooks ---------------------------------------------------------------------------
    def _configure(self, options: dict[str, Any]) -> None:
        start = options.get("start", self.config.start)
        if start not in START_KINDS:
            raise ValueError(f"reset option start={start!r} must be one of {START_KINDS}")
        self.log_k, self.rest_offset = self._choose_config(options)

    @property
    def stiffness(self) -> float:
        """This episode's spring stiffness (N/m)."""
        return float(10.0 ** self.log_k)

    def _apply_configuration(self) -> None:
        k = self.stiffness
        damping = 2 * self.config.damping_ratio * np.sqrt(k * self.config.plate_mass)
        self.sim.set_spring(k, self.rest_offset, damping)

    def plate_top_rest(self) -> np.ndarray:
        """World position of the centre of the plate's top at rest."""
        cfg = self.config
        return np.array([*PLATE_XY, TABLE_TOP_Z + cfg.plate_height + self.rest_offset])

    def _start_tool(self, options: dict[str, Any]) -> np.ndarray:
        top = self.plate_top_rest()
        cfg = self.config
        if options.get("start", cfg.start) == "pressed":
            self._press_depth = cfg.target_force / self.stiffness
            return top - np.array([0.0, 0.0, self._press_depth])
        self._press_depth = 0.0
        off = self.np_random.uniform(-cfg.start_offset, cfg.start_offset, 2)
        lo, hi = cfg.start_height
        return top + np.array([*off, self.np_random.uniform(lo, hi)])

    def _after_reset(self, options: dict[str, Any]) -> None:
        # a "pressed" start: the plate already at the target force under the tip
        self.data.qpos[self.sim.spring_qpos_adr] = -self._press_depth
        self._in_band = 0
        self._setpoint = np.zeros(3)  # set from the tip after mj_forward (first step)
        self._setpoint_ready = False
        self._start_lead = (ARM_PRESS_LEAD_PER_N * self.config.target_force
                            if self._press_depth > 0 else 0.0)

    def _position_goal(self, tip: np.ndarray, action: np.ndarray) -> np.ndarray:
        """The held setpoint, moved by ``action * action_scale``, at most ``max_lead`` from the
        tip and inside the workspace."""
        if not self._setpoint_ready:
            self._setpoint = tip - np.array([0.0, 0.0, self._start_lead])
            self._setpoint_ready = True
        sp = np.clip(self._setpoint + action * self.config.action_scale, *self.tip_bounds)
        lead = np.clip(sp - tip, -self.config.max_lead, self.config.max_lead)
        self._setpoint = tip + lead
        return self._setpoint

    def setpoint_offset(self) -> np.ndarray:
        """The setpoint minus the tip (m): what the controller pushes with."""
        if not self._setpoint_ready:
            return np.array([0.0, 0.0, -self._start_lead])
        return self._setpoint - self.tip_position()

    def plate_displacement(self) -> float:
        """The plate's displacement from rest (m, negative: pressed down)."""
        return float(self.data.qpos[self.sim.spring_qpos_adr])

    def spring_force(self) -> float:
        """The force the spring carries (N, positive when pressed)."""
        return -self.stiffness * self.plate_displacement()

    def tip_offset(self) -> np.ndarray:
        """Pusher tip minus the centre of the plate's top at rest (m)."""
        return self.tip_position() - self.plate_top_rest()

    def _reward(self) -> tuple[float, bool]:
        cfg = self.config
        force = self.spring_force()
        in_band = abs(force - cfg.target_force) <= cfg.force_tolerance
        self._in_band = self._in_band + 1 if in_band else 0
        return press_reward(force, self.tip_offset(), self.plate_displacement(),
                            self._in_band, cfg)

    def _info(self, success: bool | None = None) -> dict[str, Any]:
        if success is None:  # at reset: nothing held yet
            success = False
        return super()._info(success)

    def _extra_info(self) -> dict[str, Any]:
        return {"spring_force": self.spring_force(), "stiffness": self.stiffness,
                "rest_offset": self.rest_offset, "in_band_steps": self._in_band}

    def true_state(self) -> np.ndarray:
        """z° (21-D, float32): arm q (7), q̇ (7), setpoint offset (3), plate displacement and
        velocity (2), log10 stiffness and rest-height offset (2)."""
        d = self.data
        return np.concatenate((
            d.qpos[self._arm_q], d.qvel[self._arm_v], self.setpoint_offset(),
            [d.qpos[self.sim.spring_qpos_adr], d.qvel[self.sim.spring_dof_adr],
             self.log_k, self.rest_offset])).astype(np.float32)

    # -- collection hooks --------------------------------------------------------------------------
    def exploration_options(self, episode: int) -> dict[str, Any]:
        """Start pressed at the target force; grid: configuration ``episode % G``; off-grid:
        drawn by the environment (held-out data)."""
        if self.config.config_sampling == "grid":
            return {"start": "pressed", "config_index": episode % len(self.grid)}
        return {"start": "pressed"}

    def make_explorer(self, rng: np.random.Generator, **params: Any
                      ) -> Callable[[], np.ndarray]:
        """:class:`PressExplorer` on the tip's offset from the plate's top."""
        explorer = PressExplorer(rng, **params)
        return lambda: explorer(self.tip_offset())

    def on_policy_options(self, episode: int) -> dict[str, Any]:
        return {"start": "above"}

    def collection_stats(self, observations: dict[str, np.ndarray]) -> dict[str, Any]:
        return {}

    # -- internals -------------------------------------------------------------------------------
    def _choose_config(self, options: dict[str, Any]) -> tuple[float, float]:
        cfg = self.config
        lo, hi = cfg.config_box()
        if "stiffness" in options or "rest_offset" in options:
            k = float(options.get("stiffness", 10 ** ((lo[0] + hi[0]) / 2)))
            h = float(options.get("rest_offset", (lo[1] + hi[1]) / 2))
            x = np.array([np.log10(max(k, 1e-9)), h])
            if np.any(x < lo - 1e-9) or np.any(x > hi + 1e-9):
                raise ValueError(f"reset options stiffness={k}, rest_offset={h} lie outside "
                                 f"stiffness_range={cfg.stiffness_range}, "
                                 f"rest_height_range={cfg.rest_height_range}")
            return float(x[0]), float(x[1])
        return pick_box_config(options, self.grid, lo, hi, cfg.config_sampling, self.np_random,
                               OFF_GRID_DISTANCE)


#: Setpoint lead per newton that the stiff OSC needs (measured at 15 N: 3.2 mm with k = 500 N/m,
#: 4.6 mm with k = 5000 N/m), for a "pressed" start.
ARM_PRESS_LEAD_PER_N = 0.00027


def press_reward(force: float, tip_offset: np.ndarray, plate_displacement: float,
                 in_band_steps: int, cfg: SurfacePressConfig) -> tuple[float, bool]:
    """Dense shaped reward and success of one step.

    * reach (no spring force yet): ``1 - tanh(10 d)`` in ``(0, 1]``, ``d`` the tip's distance
      from the plate's top centre at rest;
    * press (force above 0.5 N but out of the band): ``1 + 2 exp(-((F - F*) / F*)^2)`` in
      ``(1, 3]``, rising towards the target force;
    * in band: ``5``; ``10`` once held ``hold_steps`` consecutive steps (success).

    Every stage pays more than any earlier one.
    """
    err = force - cfg.target_force
    if abs(err) <= cfg.force_tolerance:
        if in_band_steps >= cfg.hold_steps:
            return 10.0, True
        return 5.0, False
    if force > 0.5:
        return 1.0 + 2.0 * float(np.exp(-((err / cfg.target_force) ** 2))), False
    d = float(np.linalg.norm(tip_offset))
    return 1.0 - float(np.tanh(10.0 * d)), False
