from __future__ import annotations

import pytest

from repbench.testing.toy_task import ToyReachTask

from .rl_test_encoders import NoiseEncoder, TrueStateEncoder


@pytest.fixture(scope="session")
def toy_task() -> ToyReachTask:
    return ToyReachTask(horizon=30)


@pytest.fixture(scope="session")
def toy_dataset(toy_task):
    return toy_task.collect("random", n_episodes=3, steps_per_episode=20, seed=0,
                            progress=False)


@pytest.fixture(scope="session")
def state_encoder(toy_dataset) -> TrueStateEncoder:
    return TrueStateEncoder().fit(toy_dataset)


@pytest.fixture(scope="session")
def noise_encoder(toy_dataset) -> NoiseEncoder:
    return NoiseEncoder(latent_dim=6).fit(toy_dataset)
