"""robosuite 1.5.2 simulations of repbench's tasks: the shared wrist sensing, and the peg-in-hole.

:class:`WristSensing` is a mixin for any single-arm robosuite ``ManipulationEnv`` (repbench's own
or a subclass of one of robosuite's environments): it sets the physics step, samples the wrist
force/torque sensor at every physics substep for the low-pass filter (see
:mod:`repbench_tasks.sensing`), runs robosuite's control path without its per-substep checks and
history buffers, and computes only the robosuite observables repbench keeps.

:class:`PegInHoleSim`: a Panda holding a square peg rigidly, and a hole. The peg is a box welded
into the gripper's ``eef`` body (below the wrist force/torque site, so the sensor feels every
contact on it); it cannot slip. The hole is a fixed ``CompositeObject`` of four box walls on the
table whose planar position is changed per episode through ``model.body_pos`` (a soft reset, no
XML rebuild). Physics runs at ``physics_dt`` (200 Hz by default).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

import numpy as np
from robosuite.environments.manipulation.manipulation_env import ManipulationEnv
from robosuite.models.arenas import TableArena
from robosuite.models.objects import BoxObject, CapsuleObject
from robosuite.models.objects.generated_objects import CompositeObject
from robosuite.models.tasks import ManipulationTask
from robosuite.utils.mjcf_utils import array_to_string, find_elements

from repbench_tasks.config import TABLE_TOP_Z
from repbench_tasks.sensing import weight_wrench

TABLE_FULL_SIZE = (0.8, 0.8, 0.05)
TABLE_OFFSET = (0.0, 0.0, TABLE_TOP_Z)
CONTROL_FREQ = 20

#: Names of the robot's arm bodies whose visual geoms the wrist camera never sees.
ARM_BODY_PREFIXES = ("robot0_link", "robot0_base", "mount0_", "fixed_mount0_")


#: the hand's finger bodies: a tool welded in the hand never collides with them
FINGER_BODIES = ("gripper0_right_leftfinger", "gripper0_right_rightfinger",
                 "gripper0_right_finger_joint1_tip", "gripper0_right_finger_joint2_tip")
#: a rod welded in the hand (SurfacePress-v0, Door-v0): radius, and tip below the grip site (m)
ROD_RADIUS = 0.012
ROD_TIP_IN_SITE = 0.09
#: how far the rod reaches into the hand above the grip site (m)
ROD_IN_HAND = 0.02
#: the rod's whole length (m)
ROD_LENGTH = ROD_TIP_IN_SITE + ROD_IN_HAND


def table_arena(robot_model: Any, table_full_size: tuple[float, float, float],
                table_offset: np.ndarray) -> TableArena:
    """robosuite's table arena, with the robot's base placed at the table (every task's)."""
    robot_model.set_base_xpos(robot_model.base_xpos_offset["table"](table_full_size[0]))
    arena = TableArena(table_full_size=table_full_size, table_friction=(1.0, 5e-3, 1e-4),
                       table_offset=table_offset)
    arena.set_origin([0, 0, 0])
    return arena


def weld_in_hand(robot_model: Any, obj: ET.Element, center_in_eef: float) -> None:
    """Attach an object's body to the end effector, its centre ``center_in_eef`` m along the
    hand's axis (the object moves with the hand: no joint)."""
    obj.set("pos", array_to_string([0, 0, center_in_eef]))
    eef_body = find_elements(root=robot_model.worldbody, tags="body",
                             attribs={"name": "gripper0_right_eef"}, return_first=True)
    eef_body.append(obj)


def hand_rod(name: str, friction: tuple[float, float, float]) -> CapsuleObject:
    """The rod a press or door task holds: its top ``ROD_IN_HAND`` inside the hand, its tip
    ``ROD_TIP_IN_SITE`` below the grip site."""
    return CapsuleObject(name=name, size=[ROD_RADIUS, ROD_LENGTH / 2 - ROD_RADIUS],
                         rgba=[0.85, 0.55, 0.15, 1], joints=None, obj_type="all",
                         density=500.0, friction=friction)


def rod_center_in_eef() -> float:
    """Where :func:`hand_rod`'s centre sits along the hand's axis (m)."""
    return ROD_LENGTH / 2 - ROD_IN_HAND


def exclude_finger_contacts(model: ManipulationTask, body: str) -> ET.Element:
    """No contacts between ``body`` (the tool in the hand) and the fingers; returns the model's
    ``<contact>`` element for further exclusions."""
    contact = find_elements(root=model.root, tags="contact", return_first=True)
    if contact is None:
        contact = ET.SubElement(model.root, "contact")
    for finger in FINGER_BODIES:
        ET.SubElement(contact, "exclude", body1=body, body2=finger)
    return contact


def osc_position_controller(action_scale: float) -> dict[str, Any]:
    """robosuite's OSC_POSE controller config of repbench's tasks: world-frame deltas of at most
    ``action_scale`` m (position) and 0.5 rad (orientation) per step, stiff fixed impedance."""
    return {
        "type": "BASIC",
        "body_parts": {"right": {
            "type": "OSC_POSE", "input_max": 1, "input_min": -1,
            "output_max": [action_scale] * 3 + [0.5] * 3,
            "output_min": [-action_scale] * 3 + [-0.5] * 3,
            "kp": 150, "damping_ratio": 1, "impedance_mode": "fixed",
            "kp_limits": [0, 300], "damping_ratio_limits": [0, 10],
            "position_limits": None, "orientation_limits": None,
            "uncouple_pos_ori": True, "input_type": "delta", "input_ref_frame": "world",
            "interpolation": None, "ramp_ratio": 0.2, "gripper": {"type": "GRIP"},
        }},
    }


class WristSensing:
    """Mixin for a single-arm robosuite ``ManipulationEnv``: physics step, wrist force/torque
    samples per substep, the fast control path and observable pruning.

    Put it first in the bases (``class MySim(WristSensing, ManipulationEnv)``), call
    :meth:`_init_wrist_sensing` before the robosuite ``__init__`` and
    :meth:`_set_model_timestep` at the end of ``_load_model``. After ``_setup_references`` the
    sim has ``ft_site_id``, ``eef_site_id`` (grip site), ``arm_qpos_idx``/``arm_qvel_idx`` and
    ``ft_mass`` (everything below the sensor).
    """

    # attributes robosuite's ManipulationEnv provides (for type checkers)
    sim: Any
    robots: Any
    model: Any
    model_timestep: float
    action_dim: int
    _observables: dict[str, Any]
    _obs_cache: dict[str, Any]

    def _init_wrist_sensing(self, physics_dt: float) -> None:
        """Set the physics step and allocate the per-substep sample buffer."""
        self.physics_dt = physics_dt
        self._live_observables: tuple[Any, ...] | None = None
        # Per-substep wrist samples, filled in place: raw [force, torque] (6), the ft site's
        # rotation (9) and the subtree's centre of mass relative to the site (3).
        self._ft_buf = np.zeros((round(1.0 / (CONTROL_FREQ * physics_dt)) + 1, 18))
        self._n_ft = 0

    # -- model -------------------------------------------------------------------------------
    def initialize_time(self, control_freq: float) -> None:
        super().initialize_time(control_freq)  # type: ignore[misc]
        self.model_timestep = self.physics_dt

    def _set_model_timestep(self) -> None:
        """Write ``physics_dt`` into the model's ``<option timestep>`` (end of ``_load_model``)."""
        option = find_elements(root=self.model.root, tags="option", return_first=True)
        option.set("timestep", repr(float(self.physics_dt)))

    def _setup_references(self) -> None:
        super()._setup_references()  # type: ignore[misc]
        m = self.sim.model
        robot = self.robots[0]
        self.ft_body_id = m.body_name2id("gripper0_right_right_gripper")
        self.ft_site_id = m.site_name2id("gripper0_right_ft_frame")
        force_sensor = robot.gripper["right"].important_sensors["force_ee"]
        torque_sensor = robot.gripper["right"].important_sensors["torque_ee"]
        self.force_adr = int(m.sensor_adr[m.sensor_name2id(force_sensor)])
        self.torque_adr = int(m.sensor_adr[m.sensor_name2id(torque_sensor)])
        self.eef_site_id = m.site_name2id("gripper0_right_grip_site")
        self.arm_qpos_idx = np.array(robot._ref_joint_pos_indexes)
        self.arm_qvel_idx = np.array(robot._ref_joint_vel_indexes)
        # Constant per model: the mass below the sensor and the force that holds it up (world).
        self.ft_mass = float(m.body_subtreemass[self.ft_body_id])
        self.ft_support = -self.ft_mass * np.array(m.opt.gravity, dtype=np.float64)
        self._action_dim = self.action_dim  # robosuite recomputes it from the limits per call
        # Actuator index arrays and control ranges per controlled part (robot.control's clip).
        self._ctrl_parts = {
            part: (np.asarray(idx), m.actuator_ctrlrange[idx, 0].copy(),
                   m.actuator_ctrlrange[idx, 1].copy())
            for part, idx in robot._ref_actuators_indexes_dict.items()}

    def _reset_internal(self) -> None:
        super()._reset_internal()  # type: ignore[misc]
        self._n_ft = 0

    # -- control -------------------------------------------------------------------------------
    def _pre_action(self, action: Any, policy_step: bool = False) -> None:
        # What robot.control does (robosuite 1.5.2, fixed-base robot): on a policy step set the
        # new controller goal; every substep run the controllers on the current state, clip the
        # torques to the actuators' ranges and write them. Left out: its per-substep action
        # checks and duplicate update_state, and its per-step history buffers (recent_qpos,
        # recent_ee_* ...), which only robosuite's observables read and repbench disables.
        # tests/tasks: the rollout equals robosuite's own path bit for bit.
        robot = self.robots[0]
        composite = robot.composite_controller
        if policy_step:
            if len(action) != self._action_dim:
                raise ValueError(f"robosuite action has {len(action)} values, expected "
                                 f"{self._action_dim}")
            composite.update_state()
            composite.set_goal(action)
        applied = composite.run_controller(robot._enabled_parts)
        ctrl = self.sim.data._data.ctrl
        for part, torques in applied.items():
            idx, lo, hi = self._ctrl_parts[part]
            ctrl[idx] = np.clip(torques, lo, hi)
        self._record_ft()

    def _update_observables(self, force: bool = False) -> None:
        # Called every substep: skip the observables repbench has disabled (all but the wrist
        # camera of the default-rendering mode).
        live = self._live_observables
        if live is None:
            super()._update_observables(force)  # type: ignore[misc]
            return
        for observable in live:
            observable.update(timestep=self.model_timestep, obs_cache=self._obs_cache,
                              force=force)

    def keep_observables(self, names: tuple[str, ...]) -> None:
        """Enable only the robosuite observables ``names``; the others are never computed."""
        for name, observable in self._observables.items():
            keep = name in names
            observable.set_enabled(keep)
            observable.set_active(keep)
        self._live_observables = tuple(self._observables[n] for n in names)

    # -- the wrist sensor ------------------------------------------------------------------------
    def raw_ft(self) -> np.ndarray:
        """The wrist sensor's raw [force, torque] in the sensor frame (weight included)."""
        d = self.sim.data._data.sensordata
        return np.concatenate((d[self.force_adr:self.force_adr + 3],
                               d[self.torque_adr:self.torque_adr + 3]))

    def compensated_ft(self) -> np.ndarray:
        """The wrist [force, torque] with the weight below the sensor removed (sensor frame)."""
        m, d = self.sim.model._model, self.sim.data._data
        rot = d.site_xmat[self.ft_site_id].reshape(3, 3)
        weight = weight_wrench(rot, d.subtree_com[self.ft_body_id], d.site_xpos[self.ft_site_id],
                               self.ft_mass, m.opt.gravity)
        return self.raw_ft() - weight

    def _record_ft(self) -> None:
        # In-place copies only (a few microseconds); the weight is removed once per control step
        # for all substeps together in take_ft_samples.
        d = self.sim.data._data
        row = self._ft_buf[self._n_ft]
        row[0:3] = d.sensordata[self.force_adr:self.force_adr + 3]
        row[3:6] = d.sensordata[self.torque_adr:self.torque_adr + 3]
        row[6:15] = d.site_xmat[self.ft_site_id]
        np.subtract(d.subtree_com[self.ft_body_id], d.site_xpos[self.ft_site_id], out=row[15:18])
        self._n_ft = min(self._n_ft + 1, len(self._ft_buf) - 1)

    def take_ft_samples(self) -> np.ndarray:
        """The compensated [force, torque] samples of the substeps since the last call, [n, 6]
        (equal to :meth:`compensated_ft` at each substep), and start a new batch."""
        buf = self._ft_buf[:self._n_ft]
        self._n_ft = 0
        rot = buf[:, 6:15].reshape(-1, 3, 3)
        weight = weight_wrench(rot, buf[:, 15:18], np.zeros(3), self.ft_mass,
                               self.sim.model._model.opt.gravity)
        return buf[:, :6] - weight


def hole_walls(name: str, inner_half: float, wall: float, depth: float) -> CompositeObject:
    """A square hole: four box walls around an opening of half-width ``inner_half``.

    The object's origin is the centre of its footprint; its height is ``depth``.
    """
    outer = inner_half + wall
    half_len_long = outer  # x-walls span the full outer width
    half_len_short = inner_half  # y-walls fit between them
    hz = depth / 2.0
    sizes = [
        (half_len_long, wall / 2, hz), (half_len_long, wall / 2, hz),
        (wall / 2, half_len_short, hz), (wall / 2, half_len_short, hz),
    ]
    c = inner_half + wall / 2
    locs = [(0.0, c, 0.0), (0.0, -c, 0.0), (c, 0.0, 0.0), (-c, 0.0, 0.0)]
    return CompositeObject(
        name=name,
        total_size=[outer, outer, hz],
        geom_types=["box"] * 4,
        geom_sizes=sizes,
        geom_locations=locs,
        geom_names=["wall_py", "wall_ny", "wall_px", "wall_nx"],
        geom_rgbas=[(0.15, 0.35, 0.75, 1.0)] * 4,
        geom_frictions=[(0.3, 0.005, 0.0001)] * 4,
        geom_condims=[4] * 4,
        locations_relative_to_center=True,
        joints=None,
        obj_types="all",
        density=1000.0,
        solref=(0.02, 1.0),
        solimp=(0.9, 0.95, 0.001),
    )


class PegInHoleSim(WristSensing, ManipulationEnv):
    """Single-arm Panda peg-in-hole on robosuite's table arena.

    Args:
        peg_half_width: half the side of the square peg (m).
        peg_length: peg length (m); it sticks out ``peg_length - peg_grip`` below the fingers.
        clearance: gap between the peg and each hole wall when centred (m).
        hole_depth: wall height = insertion depth to the table (m).
        wall_thickness: thickness of the hole's walls (m).
        action_scale: end-effector displacement per step for an action of 1 (m).
        kwargs: passed to :class:`ManipulationEnv` (cameras, renderer flags, ...).
    """

    def __init__(self, *, peg_half_width: float, peg_length: float, clearance: float,
                 hole_depth: float, wall_thickness: float, action_scale: float,
                 physics_dt: float = 0.002, **kwargs: Any) -> None:
        self._init_wrist_sensing(physics_dt)
        self.peg_half_width = peg_half_width
        self.peg_length = peg_length
        self.clearance = clearance
        self.hole_depth = hole_depth
        self.wall_thickness = wall_thickness
        self.table_full_size = TABLE_FULL_SIZE
        self.table_offset = np.array(TABLE_OFFSET)
        self.hole_xy = np.zeros(2)
        super().__init__(robots="Panda", controller_configs=osc_position_controller(action_scale),
                         initialization_noise=None, **kwargs)

    # -- model -------------------------------------------------------------------------------
    def _load_model(self) -> None:
        super()._load_model()
        robot_model = self.robots[0].robot_model
        arena = table_arena(robot_model, self.table_full_size, self.table_offset)

        hw, length = self.peg_half_width, self.peg_length
        self.peg = BoxObject(name="peg", size=[hw, hw, length / 2], rgba=[0.85, 0.55, 0.15, 1],
                             joints=None, obj_type="all", density=500.0,
                             friction=(0.3, 0.005, 0.0001))
        # The peg's top sits 2 cm inside the hand (between the finger pads).
        self.peg_center_in_eef = length / 2 - 0.02
        weld_in_hand(robot_model, self.peg.get_obj(), self.peg_center_in_eef)

        self.hole = hole_walls("hole", hw + self.clearance, self.wall_thickness, self.hole_depth)
        hole_obj = self.hole.get_obj()
        hole_obj.set("pos", array_to_string([0.0, 0.0, TABLE_TOP_Z + self.hole_depth / 2]))
        arena.worldbody.append(hole_obj)

        self.model = ManipulationTask(mujoco_arena=arena, mujoco_robots=[robot_model])
        self._set_model_timestep()
        self.model.merge_assets(self.peg)
        self.model.merge_assets(self.hole)
        exclude_finger_contacts(self.model, self.peg.root_body)

    def _setup_references(self) -> None:
        super()._setup_references()
        m = self.sim.model
        self.hole_body_id = m.body_name2id(self.hole.root_body)
        self.peg_body_id = m.body_name2id(self.peg.root_body)
        self.peg_geom_ids = np.array([m.geom_name2id(g) for g in self.peg.contact_geoms])
        self.hole_geom_ids = np.array([m.geom_name2id(g) for g in self.hole.contact_geoms])
        self.table_geom_id = m.geom_name2id("table_collision")

    def _reset_internal(self) -> None:
        super()._reset_internal()
        if hasattr(self, "hole_body_id"):
            self.set_hole_xy(self.hole_xy)

    # -- task hooks (the gymnasium wrapper computes rewards) -----------------------------------
    def reward(self, action: Any = None) -> float:
        return 0.0

    def _check_success(self) -> bool:
        return False

    # -- helpers -------------------------------------------------------------------------------
    def set_hole_xy(self, xy: np.ndarray) -> None:
        """Move the fixed hole (soft reset: ``model.body_pos``, then kinematics)."""
        self.hole_xy = np.asarray(xy, dtype=np.float64).copy()
        self.sim.model.body_pos[self.hole_body_id][:2] = self.hole_xy
