"""A peg-like synthetic dataset for the task-information and probe metrics (no simulator)."""

from __future__ import annotations

import numpy as np


def peg_like(n_episodes: int = 60, steps: int = 40, seed: int = 0) -> dict[str, np.ndarray]:
    """Holes uniform in a square (one per episode); the tip does a bounded random walk around
    its hole; robot state = [tip (2), tip velocity (2), two joint-like functions of the tip]; task
    state = [tip − hole (2), tip velocity (2)]; the "expert" action pulls the tip to the hole.

    Returns arrays ``hole, tip, robot_state, task_state, action, episode`` and representations
    ``z_hole`` (the hole), ``z_cubic`` (an invertible nonlinear map of it), ``z_tip`` (a copy of
    the robot state's tip: nothing the agent lacks) and ``z_random`` (independent noise), each
    with two extra noise dimensions.
    """
    rng = np.random.default_rng(seed)
    hole = rng.uniform(-1.0, 1.0, (n_episodes, 2))
    off = np.zeros((n_episodes, steps, 2))
    off[:, 0] = rng.uniform(-0.3, 0.3, (n_episodes, 2))
    for t in range(1, steps):
        off[:, t] = 0.9 * off[:, t - 1] + 0.05 * rng.standard_normal((n_episodes, 2))
    vel = np.diff(off, axis=1, prepend=off[:, :1])
    tip = hole[:, None] + off
    episode = np.repeat(np.arange(n_episodes), steps)
    hole_r = np.repeat(hole, steps, axis=0)
    tip_r, off_r, vel_r = (a.reshape(-1, 2) for a in (tip, off, vel))
    n = len(episode)
    nuisance = np.stack([np.sin(tip_r.sum(1)), tip_r.prod(1)], axis=1)  # joint-like: f(tip)
    robot = np.hstack([tip_r, vel_r, nuisance])
    task = np.hstack([off_r, vel_r])
    action = np.clip(-3.0 * off_r - 2.0 * vel_r, -1, 1) + 0.05 * rng.standard_normal((n, 2))

    def noisy(a: np.ndarray) -> np.ndarray:
        return np.hstack([a, rng.standard_normal((n, 2))])

    return {"hole": hole_r, "tip": tip_r, "robot_state": robot, "task_state": task,
            "action": action, "episode": episode,
            "z_hole": noisy(hole_r), "z_cubic": noisy(np.sinh(2.5 * hole_r)),
            "z_tip": noisy(tip_r), "z_random": rng.standard_normal((n, 4))}
