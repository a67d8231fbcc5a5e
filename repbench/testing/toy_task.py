"""A tiny, fast, pure-numpy task with the same observation contract as the real ones.

:class:`ToyReachTask` is a point mass in the unit square that must reach a "hole" whose position
changes every episode. Its environment returns the dict observations every repbench task returns
(``image`` uint8 64×64×3 showing the hole and the mass, ``ft`` 6-D, ``proprio``, ``last_action``)
and ``info["true_state"]`` / ``info["is_success"]`` at every ``reset`` and ``step``. Only the
image and the true state reveal where the hole is, so a representation that loses the image
loses the task: the oracle beats a random encoder by a wide margin. Thousands of steps per
second, so tests of encoders, metrics and agents can use it instead of the MuJoCo task.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from repbench.dataset import (
    FT,
    IMAGE,
    LAST_ACTION,
    PROPRIO,
    TRUE_STATE,
    Dataset,
    as_observation_batch,
)
from repbench.errors import ConfigError, DataError
from repbench.task import Policy, Task, action_vector

_HOLE_COLOUR = np.array([40, 90, 230], np.uint8)
_MASS_COLOUR = np.array([230, 50, 40], np.uint8)
_BACKGROUND = np.array([235, 235, 225], np.uint8)


class ToyReachEnv(gym.Env):
    """Point mass reaching a per-episode hole (see :class:`ToyReachTask`).

    State: position p ∈ [-1, 1]², velocity v, hole h ∈ [-0.7, 0.7]². Action a ∈ [-1, 1]² is a
    velocity command: ``v ← 0.5 v + 0.5 a · max_speed``, ``p ← clip(p + v)``. Reward is
    ``-|p - h|`` (dense) plus 1 while inside the hole (|p - h| < ``success_radius``).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"]}

    def __init__(self, horizon: int = 50, image_size: int = 64, max_speed: float = 0.1,
                 success_radius: float = 0.1, seed: int | None = None) -> None:
        self.horizon = horizon
        self.image_size = image_size
        self.max_speed = max_speed
        self.success_radius = success_radius
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = spaces.Dict({
            IMAGE: spaces.Box(0, 255, (image_size, image_size, 3), np.uint8),
            FT: spaces.Box(-np.inf, np.inf, (6,), np.float32),
            PROPRIO: spaces.Box(-np.inf, np.inf, (4,), np.float32),
            LAST_ACTION: spaces.Box(-1.0, 1.0, (2,), np.float32),
        })
        grid = (np.arange(image_size, dtype=np.float32) + 0.5) / image_size * 2.0 - 1.0
        self._gx, self._gy = np.meshgrid(grid, -grid)  # row 0 is the top (y = +1)
        self._pos = np.zeros(2, np.float32)
        self._vel = np.zeros(2, np.float32)
        self._hole = np.zeros(2, np.float32)
        self._last_action = np.zeros(2, np.float32)
        self._force = np.zeros(2, np.float32)
        self._t = 0
        self._first_seed = seed

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        if seed is None and self._first_seed is not None:
            seed, self._first_seed = self._first_seed, None
        super().reset(seed=seed)
        rng = self.np_random
        self._hole = rng.uniform(-0.7, 0.7, 2).astype(np.float32)
        if options and options.get("start_at_hole"):
            self._pos = self._hole.copy()
        else:
            self._pos = rng.uniform(-0.9, 0.9, 2).astype(np.float32)
        self._vel[:] = 0.0
        self._last_action[:] = 0.0
        self._force[:] = 0.0
        self._t = 0
        return self._observation(), self._info()

    def step(self, action: np.ndarray
             ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        a = np.clip(action_vector(action, 2, f"{type(self).__name__}.step", np.float32),
                    -1.0, 1.0)
        self._vel = 0.5 * self._vel + 0.5 * a * self.max_speed
        target = self._pos + self._vel
        clipped = np.clip(target, -1.0, 1.0)
        self._force = (target - clipped) * 100.0  # wall contact force
        self._vel = np.where(target != clipped, 0.0, self._vel).astype(np.float32)
        self._pos = clipped.astype(np.float32)
        self._last_action = a
        self._t += 1
        dist = float(np.linalg.norm(self._pos - self._hole))
        reward = -dist + (1.0 if dist < self.success_radius else 0.0)
        truncated = self._t >= self.horizon
        return self._observation(), reward, False, truncated, self._info()

    def render(self) -> np.ndarray:
        return self._image()

    # -- internals -----------------------------------------------------------------------------
    def true_state(self) -> np.ndarray:
        return np.concatenate([self._pos, self._vel, self._hole]).astype(np.float32)

    def _success(self) -> bool:
        return bool(np.linalg.norm(self._pos - self._hole) < self.success_radius)

    def _image(self) -> np.ndarray:
        img = np.empty((self.image_size, self.image_size, 3), np.uint8)
        img[:] = _BACKGROUND
        d_hole = (self._gx - self._hole[0]) ** 2 + (self._gy - self._hole[1]) ** 2
        img[d_hole < self.success_radius**2] = _HOLE_COLOUR
        d_mass = (self._gx - self._pos[0]) ** 2 + (self._gy - self._pos[1]) ** 2
        img[d_mass < 0.06**2] = _MASS_COLOUR
        return img

    def _observation(self) -> dict[str, np.ndarray]:
        inside = float(self._success())
        ft = np.array([self._force[0], self._force[1], inside, 0.0, 0.0, 0.0], np.float32)
        return {
            IMAGE: self._image(),
            FT: ft,
            PROPRIO: np.concatenate([self._pos, self._vel]).astype(np.float32),
            LAST_ACTION: self._last_action.copy(),
        }

    def _info(self) -> dict[str, Any]:
        return {TRUE_STATE: self.true_state(), "is_success": self._success()}


class ToyReachTask(Task):
    """Reach a per-episode hole with a point mass (pure numpy, for tests and examples).

    Args:
        horizon: steps per episode (truncation).
        image_size: side of the square image observation.
        max_speed: largest displacement per step.
        success_radius: distance to the hole that counts as success.
    """

    task_id = "ToyReach-v0"

    def __init__(self, horizon: int = 50, image_size: int = 64, max_speed: float = 0.1,
                 success_radius: float = 0.1) -> None:
        self.horizon = horizon
        self.image_size = image_size
        self.max_speed = max_speed
        self.success_radius = success_radius
        self.check_params()  # a bad value fails at construction, so at plan time

    def check_params(self) -> None:
        """Raise a one-line :class:`ConfigError` naming the first invalid parameter."""
        def whole(v: Any) -> bool:
            return isinstance(v, (int, np.integer)) and not isinstance(v, bool)

        def real(v: Any) -> bool:
            return isinstance(v, (int, float, np.number)) and not isinstance(v, bool) and bool(
                np.isfinite(v))

        checks = {
            "horizon": (whole(self.horizon) and self.horizon >= 1, "a whole number >= 1"),
            "image_size": (whole(self.image_size) and 8 <= self.image_size <= 512,
                           "a whole number in [8, 512]"),
            "max_speed": (real(self.max_speed) and self.max_speed > 0, "a number > 0"),
            "success_radius": (real(self.success_radius) and self.success_radius > 0,
                               "a number > 0"),
        }
        for name, (ok, what) in checks.items():
            if not ok:
                raise ConfigError(f"{self.task_id}: {name}={getattr(self, name)!r} must be {what}")

    def make_env(self, seed: int | None = None, **overrides: Any) -> ToyReachEnv:
        """A fresh environment; ``seed`` seeds its first ``reset``."""
        params = {**self.get_params(), **overrides}
        return ToyReachEnv(seed=seed, **params)

    def true_state(self, env: Any) -> np.ndarray:
        """z° = [position (2), velocity (2), hole position (2)]."""
        return env.unwrapped.true_state()

    def task_state(self, observations: Mapping[str, np.ndarray]) -> np.ndarray:
        """Position minus hole (2) and velocity (2), float32 [N, 4], from z°."""
        z = np.asarray(as_observation_batch(observations, (TRUE_STATE,), self.task_id)[TRUE_STATE])
        if z.ndim != 2 or z.shape[1] != 6:
            raise DataError(f"{self.task_id} task_state: true_state must be [N, 6], got "
                            f"{list(z.shape)}")
        return np.concatenate([z[:, 0:2] - z[:, 4:6], z[:, 2:4]], axis=1).astype(np.float32)

    def collect(self, kind: str, *, n_episodes: int, steps_per_episode: int, seed: int,
                policy: Policy | None = None, progress: bool = True) -> Dataset:
        """``random``: a random walk starting in the hole (backwards exploration);
        ``on_policy``: ``policy`` (called on one step's observation dict with ``true_state``)."""
        if kind not in ("random", "on_policy"):
            raise ConfigError(f"ToyReach-v0: unknown dataset kind {kind!r}; "
                              "use 'random' or 'on_policy'")
        if kind == "on_policy" and policy is None:
            raise ConfigError("ToyReach-v0: kind='on_policy' needs policy=...")
        from tqdm.auto import tqdm

        env = self.make_env(seed=seed, horizon=max(steps_per_episode, 1))
        rng = np.random.default_rng(seed)
        rows: dict[str, list[Any]] = {k: [] for k in (IMAGE, FT, PROPRIO, LAST_ACTION, "action",
                                                      TRUE_STATE, "reward", "success",
                                                      "episode", "step")}
        for ep in tqdm(range(n_episodes), desc=f"ToyReach {kind}", disable=not progress):
            obs, info = env.reset(seed=seed * 100_003 + ep,
                                  options={"start_at_hole": kind == "random"})
            for t in range(steps_per_episode):
                if policy is None:
                    action = rng.uniform(-1.0, 1.0, 2).astype(np.float32)
                else:
                    action = np.asarray(policy({**obs, TRUE_STATE: info[TRUE_STATE]}),
                                        np.float32).reshape(2)
                for k in (IMAGE, FT, PROPRIO, LAST_ACTION):
                    rows[k].append(obs[k])
                rows[TRUE_STATE].append(info[TRUE_STATE])
                rows["success"].append(info["is_success"])
                obs, reward, _, _, info = env.step(action)
                rows["action"].append(np.clip(action, -1.0, 1.0))
                rows["reward"].append(reward)
                rows["episode"].append(ep)
                rows["step"].append(t)
        return Dataset(
            observations={k: np.stack(rows[k]) for k in (IMAGE, FT, PROPRIO, LAST_ACTION)},
            action=np.stack(rows["action"]).astype(np.float32),
            true_state=np.stack(rows[TRUE_STATE]).astype(np.float32),
            reward=np.asarray(rows["reward"], np.float32),
            success=np.asarray(rows["success"], bool),
            episode=np.asarray(rows["episode"], np.int64),
            step=np.asarray(rows["step"], np.int64),
            metadata={"task": self.task_id, "kind": kind, "seed": seed,
                      "task_params": self.get_params(), "n_episodes": n_episodes,
                      "steps_per_episode": steps_per_episode},
        )
