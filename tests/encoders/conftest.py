"""Shared fixtures of the encoder tests: small synthetic datasets in the task schema."""

from __future__ import annotations

import numpy as np
import pytest

from repbench.dataset import Dataset
from repbench.testing.synthetic import synthetic_dataset


@pytest.fixture(scope="session")
def small_dataset() -> Dataset:
    """4 episodes × 30 steps, 64 × 64 images (120 rows)."""
    return synthetic_dataset(n_episodes=4, steps=30, seed=0)


@pytest.fixture(scope="session")
def tiny_dataset() -> Dataset:
    """3 episodes × 8 steps, 64 × 64 images (24 rows)."""
    return synthetic_dataset(n_episodes=3, steps=8, seed=1)


@pytest.fixture(autouse=True)
def one_torch_thread():
    """Encoder tests train small conv nets; with other processes on the same cores, torch's
    thread pool oversubscribes them (measured ~8x slower with 2 threads than with 1)."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="session")
def peg_like_dataset() -> Dataset:
    """The tiny synthetic dataset widened to the peg-in-hole's layout (proprio [N, 20] with the
    tip position at 14:17 and velocity at 17:20, z° [N, 16] with the hole at 14:16) and naming
    ``PegInHole-v0`` in its metadata, so ``Task.task_state`` works without a simulator."""
    d = synthetic_dataset(n_episodes=3, steps=8, seed=1)
    n = len(d)
    proprio = np.zeros((n, 20), np.float32)
    proprio[:, :4] = d.observations["proprio"]
    proprio[:, 14:16] = d.true_state[:, 0:2] * 0.1
    proprio[:, 16] = 0.9
    proprio[:, 17:19] = d.true_state[:, 2:4] * 0.1
    z_true = np.zeros((n, 16), np.float32)
    z_true[:, :4] = d.true_state[:, :4]
    z_true[:, 14:16] = d.true_state[:, 4:6] * 0.1
    obs = {**d.observations, "proprio": proprio}
    return Dataset(observations=obs, action=d.action, true_state=z_true, reward=d.reward,
                   success=d.success, episode=d.episode, step=d.step,
                   metadata={"task": "PegInHole-v0", "params": {}})
