"""Data collection: backwards exploration from the goal (``random``) and ``on_policy`` rollouts.

Rows are one per step: the observation at step n, the action taken there, the reward it earned,
z° and the success flag at step n. Collection uses one environment and soft resets.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from repbench_tasks.env import PegInHoleEnv
from tqdm.auto import tqdm

from repbench.dataset import Dataset
from repbench.errors import ConfigError

KINDS = ("random", "on_policy")


class BackwardsExplorer:
    """Random actions with a weak upward bias, starting from the inserted peg.

    Uniform noise of amplitude ``noise`` plus ``upward_bias`` in z moves the peg out of the hole
    slowly enough that a real share of steps is in contact with the walls; above the opening the
    walk is unbiased, and once the tip is more than ``ceiling`` above the opening or ``radius``
    away from the hole axis it is pushed back, so it keeps exploring near the hole and touching
    it (fixture top, walls, re-insertions).
    """

    def __init__(self, rng: np.random.Generator, *, noise: float = 0.7, upward_bias: float = 0.1,
                 ceiling: float = 0.04, radius: float = 0.03) -> None:
        self.rng, self.noise, self.bias = rng, noise, upward_bias
        self.ceiling, self.radius = ceiling, radius

    def __call__(self, offset: np.ndarray) -> np.ndarray:
        """Action for the tip ``offset`` from the centre of the hole's opening."""
        a = self.rng.uniform(-self.noise, self.noise, 3)
        if offset[2] < 0:  # inside the hole: the weak upward bias works the peg out
            a[2] += self.bias
        elif offset[2] > self.ceiling:  # too high: come back down towards the hole
            a[2] -= 3 * self.bias
        dist = float(np.linalg.norm(offset[:2]))
        if dist > self.radius:
            a[:2] -= 3 * self.bias * offset[:2] / dist
        return np.clip(a, -1.0, 1.0).astype(np.float32)


def collect(env: PegInHoleEnv, kind: str, *, n_episodes: int, steps_per_episode: int,
            seed: int, policy: Callable[[Mapping[str, np.ndarray]], np.ndarray] | None = None,
            progress: bool = True) -> tuple[Dataset, dict[str, Any]]:
    """Roll out ``n_episodes`` x ``steps_per_episode`` steps; return the dataset and statistics.

    ``random`` starts every episode inserted in the hole at grid position ``episode % G`` and
    explores backwards; ``on_policy`` starts above a hole drawn by the episode's seed and calls
    ``policy`` on one step's observation dict (no batch axis) with ``true_state`` added.
    """
    if kind not in KINDS:
        raise ConfigError(f"unknown collection kind {kind!r}; use one of {KINDS}")
    if kind == "on_policy" and policy is None:
        raise ConfigError("collect('on_policy') needs a policy: a callable observation -> action")
    for name, v in (("n_episodes", n_episodes), ("steps_per_episode", steps_per_episode)):
        if not isinstance(v, (int, np.integer)) or v < 1:
            raise ConfigError(f"collect: {name}={v!r} must be a positive integer")
    seeds = np.random.SeedSequence(seed).generate_state(n_episodes, dtype=np.uint32)
    keys = ("image", "ft", "proprio", "last_action")
    obs_rows: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    actions, states, rewards, successes, contacts = [], [], [], [], []
    n_grid = len(env.grid)
    bar = tqdm(total=n_episodes * steps_per_episode, disable=not progress,
               desc=f"PegInHole {kind}", unit="step")
    for ep in range(n_episodes):
        ep_seed = int(seeds[ep])
        if kind == "random":
            options = {"start": "inserted", "hole_index": ep % n_grid}
            explorer = BackwardsExplorer(np.random.default_rng(ep_seed))
        else:
            options = {"start": "above"}
        obs, info = env.reset(seed=ep_seed, options=options)
        for _ in range(steps_per_episode):
            if kind == "random":
                action = explorer(env.tip_offset())
            else:
                assert policy is not None
                step_obs = {**obs, "true_state": info["true_state"]}
                action = np.asarray(policy(step_obs), dtype=np.float32).reshape(-1)
                if action.shape != (3,) or not np.all(np.isfinite(action)):
                    raise ConfigError(f"policy returned action {action!r}; expected 3 finite "
                                      "values in [-1, 1]")
            for k in keys:
                obs_rows[k].append(obs[k])
            states.append(info["true_state"])
            successes.append(info["is_success"])
            contacts.append(info["in_contact"])
            obs, reward, _, _, info = env.step(action)
            actions.append(np.clip(action, -1, 1).astype(np.float32))
            rewards.append(reward)
            bar.update(1)
    bar.close()
    n = n_episodes * steps_per_episode
    dataset = Dataset(
        observations={k: np.stack(v) for k, v in obs_rows.items()},
        action=np.stack(actions), true_state=np.stack(states),
        reward=np.asarray(rewards, np.float32), success=np.asarray(successes, bool),
        episode=np.repeat(np.arange(n_episodes, dtype=np.int64), steps_per_episode),
        step=np.tile(np.arange(steps_per_episode, dtype=np.int64), n_episodes),
    )
    stats = {"contact_share": float(np.mean(contacts)), "success_share": float(np.mean(successes)),
             "n_steps": n, "episode_seeds": [int(s) for s in seeds]}
    return dataset, stats
