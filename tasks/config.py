"""Hyperparameters of the peg-in-hole task and their validation (one-line ``ConfigError``s), the
type and timing checks every task config shares (``check_types``, ``check_timing``), and the
configuration box of the tasks whose per-episode configuration is a point in a 2-D box on a grid
(SurfacePress-v0, Door-v0: ``box_grid``, ``off_grid_point``, ``pick_box_config``,
``check_box_config``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from repbench.errors import ConfigError

#: Height of the table top in the world frame (m); the hole stands on it.
TABLE_TOP_Z = 0.8
#: Table half-size (robosuite's default table arena is 0.8 m x 0.8 m, centred at the origin).
TABLE_HALF = 0.4
#: Below this clearance MuJoCo's soft contacts (penetration ~0.3 mm under load) and the OSC
#: tracking error (~0.3 mm) make the peg jam or pass through walls: the solver cannot resolve it.
MIN_CLEARANCE = 0.0005
START_KINDS = ("above", "inserted")
HOLE_SAMPLING = ("grid", "uniform")
#: What the RL agent sees of the robot beside μ_z (:meth:`PegInHoleTask.robot_state`).
ROBOT_VIEWS = ("proprio", "tip")
#: How a config-box task draws an episode's configuration: a grid point, or a point off the grid.
CONFIG_SAMPLING = ("grid", "off_grid")


def whole_number(v: Any) -> bool:
    """Whether ``v`` is an integer (Python's or numpy's) and not a bool: ``True`` is no step
    count (the check the ToyReach test task makes)."""
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


def check_types(cfg: Any, bad: Callable[[str, str], ConfigError]) -> None:
    """Type checks of a task config's float/bool/pair fields (before any arithmetic)."""
    def number(v: Any) -> bool:
        return isinstance(v, (int, float, np.number)) and not isinstance(v, bool)

    for f in fields(cfg):
        v = getattr(cfg, f.name)
        if f.type == "float" and not number(v):
            raise bad(f.name, f"must be a number (default {f.default!r})")
        if f.type == "bool" and not isinstance(v, (bool, np.bool_)):
            raise bad(f.name, "must be true or false")
        if f.type == "str" and not isinstance(v, str):
            raise bad(f.name, f"must be a string (default {f.default!r})")
        if f.type == "tuple[float, float]" and not (
                isinstance(v, (tuple, list)) and len(v) == 2 and all(map(number, v))):
            raise bad(f.name, f"must be a pair of numbers (default {list(f.default)!r})")


def check_timing(cfg: Any, bad: Callable[[str, str], ConfigError]) -> None:
    """The physics step divides the 20 Hz control period; the F/T cut-off is below Nyquist."""
    steps = (1.0 / 20.0) / cfg.physics_dt
    if abs(steps - round(steps)) > 1e-6 or cfg.physics_dt > 0.01:
        raise bad("physics_dt", "must divide the 0.05 s control period and be <= 0.01 s")
    if cfg.ft_cutoff_hz >= 0.5 / cfg.physics_dt:
        raise bad("ft_cutoff_hz", f"must be below the Nyquist rate {0.5 / cfg.physics_dt} Hz")


def box_grid(low: np.ndarray, high: np.ndarray, n: int) -> np.ndarray:
    """The ``n x n`` grid over the 2-D box ``[low, high]``, row-major [n², 2]; with ``n == 1``
    the box's centre."""
    axes = [np.linspace(low[i], high[i], n) if n > 1 else np.array([(low[i] + high[i]) / 2])
            for i in range(2)]
    a, b = np.meshgrid(*axes, indexing="ij")
    return np.stack([a.ravel(), b.ravel()], axis=1)


def off_grid_point(rng: np.random.Generator, grid: np.ndarray, low: np.ndarray,
                   high: np.ndarray, min_distance: float) -> np.ndarray:
    """A point drawn uniformly in the box ``[low, high]`` and at least ``min_distance`` (in
    units of the box's side per axis) from every ``grid`` point: a held-out configuration."""
    low, high = np.asarray(low, np.float64), np.asarray(high, np.float64)
    span = np.where(high > low, high - low, 1.0)
    for _ in range(10_000):
        x = rng.uniform(low, high)
        if len(grid) <= 1 or np.min(np.linalg.norm((grid - x) / span, axis=1)) >= min_distance:
            return x
    raise ConfigError(f"no configuration at least {min_distance} from the grid in 10000 draws; "
                      "use a coarser grid")


def pick_box_config(options: dict[str, Any], grid: np.ndarray, low: np.ndarray,
                    high: np.ndarray, sampling: str, rng: np.random.Generator,
                    min_distance: float) -> tuple[float, float]:
    """An episode's configuration when its reset ``options`` name none explicitly: grid point
    ``options["config_index"]``, else a random grid point (``sampling="grid"``) or a point off
    the grid (:func:`off_grid_point`)."""
    if "config_index" in options:
        idx = int(options["config_index"])
        if not 0 <= idx < len(grid):
            raise ValueError(f"reset option config_index={idx} must be in [0, {len(grid)})")
        return float(grid[idx, 0]), float(grid[idx, 1])
    if sampling == "grid":
        idx = int(rng.integers(len(grid)))
        return float(grid[idx, 0]), float(grid[idx, 1])
    x = off_grid_point(rng, grid, low, high, min_distance)
    return float(x[0]), float(x[1])


def check_box_config(cfg: Any, bad: Callable[[str, str], ConfigError],
                     integers: tuple[str, ...], choices: dict[str, tuple[str, ...]]) -> None:
    """The checks every config-box task's config starts with: field types, ``integers``
    positive, ``grid_size`` at most 50, ``config_sampling``, then each field of ``choices`` and
    ``robot_view`` one of their values."""
    check_types(cfg, bad)
    for name in integers:
        v = getattr(cfg, name)
        if not whole_number(v) or v < 1:
            raise bad(name, "must be a positive integer")
    if cfg.grid_size > 50:
        raise bad("grid_size", "must be an integer in [1, 50] (5 by default)")
    for name, allowed in {"config_sampling": CONFIG_SAMPLING, **choices,
                          "robot_view": ROBOT_VIEWS}.items():
        if getattr(cfg, name) not in allowed:
            raise bad(name, f"must be one of {allowed}")


@dataclass(frozen=True)
class PegInHoleConfig:
    """Every hyperparameter of :class:`~repbench_tasks.peg_in_hole.PegInHoleTask`."""

    horizon: int = 100
    """Episode length in control steps (20 Hz)."""
    grid_size: int = 5
    """Hole positions form a ``grid_size x grid_size`` grid (the paper: 5 x 5 = 25)."""
    grid_extent: float = 0.16
    """Side of the square the grid spans (m)."""
    grid_center: tuple[float, float] = (0.0, 0.0)
    """Planar centre of the grid on the table (m)."""
    hole_sampling: str = "grid"
    """``"grid"``: one of the grid positions per episode; ``"uniform"``: anywhere in the square."""
    clearance: float = 0.002
    """Gap between peg and each hole wall when centred (m)."""
    peg_half_width: float = 0.012
    """Half the side of the square peg (m)."""
    peg_length: float = 0.12
    """Peg length (m)."""
    hole_depth: float = 0.04
    """Height of the hole's walls = full insertion depth (m)."""
    wall_thickness: float = 0.02
    """Thickness of the hole's walls (m)."""
    image_size: int = 64
    """Wrist image side (pixels)."""
    fast_render: bool = True
    """Tuned software rendering (no MSAA, no reflections, unseen geometry culled); False uses
    robosuite's default camera observable (same picture, ~10x slower on CPU)."""
    camera: bool = True
    """False: physics only, the ``image`` observation is all zeros (benchmarks, state-based RL)."""
    start: str = "above"
    """Default start distribution: ``"above"`` the hole (RL) or ``"inserted"`` (backwards
    exploration)."""
    start_offset: float = 0.03
    """Half-width of the uniform planar offset of an ``"above"`` start (m)."""
    start_height: tuple[float, float] = (0.02, 0.06)
    """Range of the peg tip's height above the hole for an ``"above"`` start (m)."""
    action_scale: float = 0.02
    """End-effector displacement for an action of 1 (m per step)."""
    physics_dt: float = 0.005
    """Physics step (s); the paper used a maximum step of 0.005 s."""
    ft_cutoff_hz: float = 10.0
    """Cut-off of the 2nd-order Butterworth low-pass on the wrist force/torque."""
    success_tolerance: float = 0.01
    """Inserted "to depth" means within this distance of the bottom (m)."""
    robot_view: str = "tip"
    """The robot state the RL agent observes beside μ_z: ``"tip"`` (default; the peg tip's
    position and velocity, 6 numbers; chosen by measurement, see ``repbench/suites/quick.toml``)
    or ``"proprio"`` (joint positions and velocities, tip position and velocity: 20 numbers)."""

    # -- derived -------------------------------------------------------------------------------
    @property
    def hole_outer_half(self) -> float:
        return self.peg_half_width + self.clearance + self.wall_thickness

    def grid_positions(self) -> np.ndarray:
        """The ``grid_size**2`` planar hole positions, row-major, float64 [G, 2]."""
        n = self.grid_size
        offs = np.linspace(-self.grid_extent / 2, self.grid_extent / 2, n) if n > 1 else np.zeros(1)
        gx, gy = np.meshgrid(offs + self.grid_center[0], offs + self.grid_center[1], indexing="ij")
        return np.stack([gx.ravel(), gy.ravel()], axis=1)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    # -- validation ----------------------------------------------------------------------------
    def validate(self) -> PegInHoleConfig:
        """Raise :class:`ConfigError` (one line, naming the field and the fix) on a bad value."""
        def bad(name: str, msg: str) -> ConfigError:
            return ConfigError(f"PegInHole-v0: {name}={getattr(self, name)!r} {msg}")

        check_types(self, bad)  # types first: "wide" for a float must name the field, not numpy

        if not whole_number(self.horizon) or self.horizon < 1:
            raise bad("horizon", "must be a positive integer number of steps")
        if not whole_number(self.grid_size) or not 1 <= self.grid_size <= 50:
            raise bad("grid_size", "must be an integer in [1, 50] (the paper uses 5)")
        if not np.isfinite(self.grid_extent) or self.grid_extent < 0:
            raise bad("grid_extent", "must be a finite length >= 0 in metres")
        if len(self.grid_center) != 2:
            raise bad("grid_center", "must be a planar (x, y) position")
        if self.hole_sampling not in HOLE_SAMPLING:
            raise bad("hole_sampling", f"must be one of {HOLE_SAMPLING}")
        if self.robot_view not in ROBOT_VIEWS:
            raise bad("robot_view", f"must be one of {ROBOT_VIEWS}")
        if self.start not in START_KINDS:
            raise bad("start", f"must be one of {START_KINDS}")
        for name in ("peg_half_width", "peg_length", "hole_depth", "wall_thickness",
                     "action_scale", "physics_dt", "ft_cutoff_hz", "success_tolerance"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise bad(name, "must be a positive finite number")
        if not np.isfinite(self.clearance) or self.clearance < MIN_CLEARANCE:
            raise bad("clearance", f"is below {MIN_CLEARANCE} m, which MuJoCo's soft contacts and "
                                   "the OSC tracking error cannot resolve; use a larger clearance")
        if self.clearance > self.peg_half_width:
            raise bad("clearance", f"exceeds the peg half-width {self.peg_half_width} m: that is "
                                   "no longer a fit; use a smaller clearance")
        reach = (max(abs(self.grid_center[0]), abs(self.grid_center[1])) + self.grid_extent / 2
                 + self.hole_outer_half)
        if reach > TABLE_HALF:
            raise ConfigError(
                f"PegInHole-v0: grid_center={tuple(self.grid_center)!r}, "
                f"grid_extent={self.grid_extent!r} puts the hole off the table (needs "
                f"|centre| + extent/2 + {self.hole_outer_half:.3f} <= {TABLE_HALF} m); "
                "shrink grid_extent or move grid_center")
        if self.peg_length - 0.02 < self.hole_depth + 0.03:
            raise bad("peg_length", f"must reach {self.hole_depth + 0.05:.3f} m (hole depth + "
                                    "5 cm) so the fingers clear the walls when inserted")
        if not whole_number(self.image_size) or not 8 <= self.image_size <= 512:
            raise bad("image_size", "must be an integer in [8, 512] (the paper uses 64)")
        lo, hi = self.start_height
        if not 0 <= lo <= hi <= 0.25:
            raise bad("start_height", "must be (low, high) with 0 <= low <= high <= 0.25 m")
        if not 0 <= self.start_offset <= 0.1:
            raise bad("start_offset", "must be in [0, 0.1] m")
        if self.success_tolerance >= self.hole_depth:
            raise bad("success_tolerance", "must be smaller than hole_depth")
        check_timing(self, bad)
        return self
