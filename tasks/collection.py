"""Data collection: backwards exploration from the goal (``random``) and ``on_policy`` rollouts.

:func:`collect` works on any :class:`~repbench_tasks.env.WristTaskEnv` through its collection
hooks (``exploration_options``, ``make_explorer``, ``on_policy_options``, ``collection_stats``);
:class:`BackwardsExplorer` is the peg-in-hole's exploration policy.

Rows are one per step: the observation at step n, the action taken there, the reward it earned,
z° and the success flag at step n. Collection uses one environment and soft resets.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from tqdm.auto import tqdm

from repbench.dataset import Dataset
from repbench.errors import ConfigError
from repbench_tasks.config import whole_number

if TYPE_CHECKING:
    from repbench_tasks.env import WristTaskEnv

KINDS = ("random", "on_policy")


class BackwardsExplorer:
    """Random actions from the inserted peg: out of the hole, around it, and back onto it.

    Every action is uniform noise of amplitude ``noise`` plus a small drift that depends on a
    two-mode Markov chain (so the policy is random, π ≈ 0, and the peg stays in a bounded region
    around the hole, which keeps the first and second differences of the state about zero-mean:
    |mean| <= 0.1 std and <= 0.002 std per joint on 25 x 300 steps):

    * ``wander`` (the start): inside the hole a weak ``upward_bias`` works the peg out; above it
      the walk is unbiased, and it is pushed back once the tip is more than ``ceiling`` above the
      opening or ``radius`` away from the hole's axis. Each step it switches to ``approach`` with
      probability ``p_approach``.
    * ``approach``: a drift of at most ``approach_bias`` towards a point drawn at the switch,
      within ``target_radius`` of the hole's axis and ``target_depth`` below its opening (below
      the hole's floor), so the peg comes down onto the wall tops, into the opening or onto the
      table beside it and pushes there (contact).
      Each step it switches back with probability ``p_leave``.

    Pure backwards exploration leaves the hole within ~15-60 steps and then spends most samples
    in free space (11.5 % contact on 25 x 300 steps); with the approach phases the paper-size
    ``random`` dataset (25 x 300, seed 0) has 37 % of its samples in contact, 63 % in free space
    and 11 % inserted to depth.
    """

    def __init__(self, rng: np.random.Generator, *, noise: float = 0.7, upward_bias: float = 0.15,
                 ceiling: float = 0.04, radius: float = 0.03, p_approach: float = 0.12,
                 p_leave: float = 0.025, approach_bias: float = 0.5,
                 target_radius: float = 0.03, target_depth: float = -0.05) -> None:
        self.rng, self.noise, self.bias = rng, noise, upward_bias
        self.ceiling, self.radius = ceiling, radius
        self.p_approach, self.p_leave = p_approach, p_leave
        self.approach_bias, self.target_radius = approach_bias, target_radius
        self.target_depth = target_depth
        self.approaching = False
        self.target = np.zeros(3)

    def __call__(self, offset: np.ndarray) -> np.ndarray:
        """Action for the tip ``offset`` from the centre of the hole's opening."""
        a = self.rng.uniform(-self.noise, self.noise, 3)
        switch, draw = self.rng.random(), self.rng.uniform(-1.0, 1.0, 2)
        if self.approaching:
            drift = self.target - offset
            norm = float(np.linalg.norm(drift))
            a += drift * min(self.approach_bias / max(norm, 1e-9), 25.0)
            self.approaching = switch >= self.p_leave
        else:
            if offset[2] < 0:  # inside the hole: the weak upward bias works the peg out
                a[2] += self.bias
            elif offset[2] > self.ceiling:  # too high: come back down towards the hole
                a[2] -= 3 * self.bias
            dist = float(np.linalg.norm(offset[:2]))
            if dist > self.radius:
                a[:2] -= 3 * self.bias * offset[:2] / dist
            if switch < self.p_approach and offset[2] > 0:
                self.approaching = True
                self.target = np.array([*(self.target_radius * draw), self.target_depth])
        return np.clip(a, -1.0, 1.0).astype(np.float32)


def check_collect_args(kind: str, n_episodes: Any, steps_per_episode: Any,
                       policy: Callable[..., Any] | None) -> None:
    """Raise a one-line :class:`ConfigError` on a bad :func:`collect` argument."""
    if kind not in KINDS:
        raise ConfigError(f"unknown collection kind {kind!r}; use one of {KINDS}")
    if kind == "on_policy" and policy is None:
        raise ConfigError("collect('on_policy') needs a policy: a callable observation -> action")
    for name, v in (("n_episodes", n_episodes), ("steps_per_episode", steps_per_episode)):
        if not whole_number(v) or v < 1:
            raise ConfigError(f"collect: {name}={v!r} must be a positive integer")


def collect(env: WristTaskEnv, kind: str, *, n_episodes: int, steps_per_episode: int,
            seed: int, policy: Callable[[Mapping[str, np.ndarray]], np.ndarray] | None = None,
            progress: bool = True, explorer_params: Mapping[str, float] | None = None
            ) -> tuple[Dataset, dict[str, Any]]:
    """Roll out ``n_episodes`` x ``steps_per_episode`` steps; return the dataset and statistics.

    ``random`` resets episode ``ep`` with ``env.exploration_options(ep)`` and acts with
    ``env.make_explorer`` (for the peg-in-hole: start inserted in the hole at grid position
    ``ep % G``, or with ``hole_sampling="uniform"`` at a hole drawn uniformly in the grid's
    square, and explore backwards); ``on_policy`` resets with ``env.on_policy_options(ep)``
    (the peg-in-hole: above a hole drawn by the episode's seed) and calls ``policy`` on one
    step's observation dict (no batch axis) with ``true_state`` added.
    ``explorer_params`` override the explorer's keyword arguments (``random``).
    """
    check_collect_args(kind, n_episodes, steps_per_episode, policy)
    seeds = np.random.SeedSequence(seed).generate_state(n_episodes, dtype=np.uint32)
    keys = ("image", "ft", "proprio", "last_action")
    obs_rows: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    actions, states, rewards, successes, contacts = [], [], [], [], []
    action_shape = tuple(env.action_space.shape or ())
    bar = tqdm(total=n_episodes * steps_per_episode, disable=not progress,
               desc=f"{env.task_label} {kind}", unit="step")
    for ep in range(n_episodes):
        ep_seed = int(seeds[ep])
        if kind == "random":
            options = env.exploration_options(ep)
            explore = env.make_explorer(np.random.default_rng(ep_seed),
                                        **dict(explorer_params or {}))
        else:
            options = env.on_policy_options(ep)
        obs, info = env.reset(seed=ep_seed, options=options)
        for _ in range(steps_per_episode):
            if kind == "random":
                action = explore()
            else:
                assert policy is not None
                step_obs = {**obs, "true_state": info["true_state"]}
                action = np.asarray(policy(step_obs), dtype=np.float32).reshape(-1)
                if action.shape != action_shape or not np.all(np.isfinite(action)):
                    raise ConfigError(f"policy returned action {action!r}; expected "
                                      f"{int(np.prod(action_shape))} finite values in [-1, 1]")
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
    force = np.linalg.norm(dataset.observations["ft"][:, :3], axis=1)
    stats = {"contact_share": float(np.mean(contacts)),
             "free_space_share": 1.0 - float(np.mean(contacts)),
             "success_share": float(np.mean(successes)),
             "ft_force_quantiles": {f"q{q}": round(float(np.quantile(force, q / 100)), 3)
                                    for q in (10, 50, 90, 99)},
             "n_steps": n, "episode_seeds": [int(s) for s in seeds],
             **env.collection_stats(dataset.observations)}
    return dataset, stats
