"""Shared fixtures: one environment of each kind per test session (building one takes ~1 s)."""

from __future__ import annotations

import pytest

import repbench  # noqa: F401  (sets MUJOCO_GL before mujoco is imported)
from repbench_tasks.peg_in_hole import PegInHoleTask


@pytest.fixture(scope="session")
def task() -> PegInHoleTask:
    return PegInHoleTask(horizon=300)


@pytest.fixture(scope="session")
def env(task: PegInHoleTask):
    """The default environment (wrist camera with the tuned renderer)."""
    e = task.make_env()
    yield e.unwrapped
    e.close()


@pytest.fixture(scope="session")
def physics_env():
    """Physics only (no camera): for tests that need many steps but no images."""
    e = PegInHoleTask(horizon=400, camera=False).make_env()
    yield e.unwrapped
    e.close()
