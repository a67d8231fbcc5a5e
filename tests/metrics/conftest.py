"""Shared fixtures of the metric tests: a synthetic true state shaped like the peg-in-hole data."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))  # for _reference

from repbench.testing.metric import synthetic_true_state


def representations(z_true: np.ndarray, seed: int = 0) -> dict[str, np.ndarray]:
    """True state, a non-invertible map (half the dims folded by abs), a random map."""
    rng = np.random.default_rng(seed)
    half = z_true.shape[1] // 2
    return {
        "true": z_true,
        "folded": np.hstack([np.abs(z_true[:, :half]), z_true[:, half:]]),
        "random": rng.standard_normal(z_true.shape),
    }


@pytest.fixture(scope="session")
def realistic() -> tuple[np.ndarray, np.ndarray]:
    """20 episodes x 100 steps, 8 random-walk dims + 2 static (hole) dims."""
    return synthetic_true_state(n_episodes=20, steps=100, dynamic_dims=8, static_dims=2, seed=3)
