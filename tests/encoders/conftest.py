"""Shared fixtures of the encoder tests: small synthetic datasets in the task schema."""

from __future__ import annotations

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
