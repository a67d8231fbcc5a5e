"""Held-out backwards exploration: with hole_sampling="uniform" the holes leave the grid."""

from __future__ import annotations

import numpy as np

from repbench_tasks.peg_in_hole import HOLE_XY, PegInHoleTask


def test_uniform_hole_sampling_puts_random_episodes_off_the_grid() -> None:
    task = PegInHoleTask(horizon=5, hole_sampling="uniform", camera=False)
    ds = task.collect("random", n_episodes=3, steps_per_episode=3, seed=1000, progress=False)
    holes = ds.true_state[::3, HOLE_XY].astype(np.float64)
    grid = np.asarray(task.make_env().unwrapped.grid)
    nearest = np.abs(holes[:, None, :] - grid[None]).max(-1).min(1)
    assert (nearest > 1e-3).all()  # no hole sits on one of the 25 training positions
    half = task.grid_extent / 2 + 1e-6
    assert (np.abs(holes - np.asarray(task.grid_center)) <= half).all()
    grid_task = PegInHoleTask(horizon=5, camera=False)
    grid_ds = grid_task.collect("random", n_episodes=2, steps_per_episode=3, seed=1000,
                                progress=False)
    np.testing.assert_allclose(grid_ds.true_state[::3, HOLE_XY], grid[:2], atol=1e-6)
