"""Shared fixtures: one environment per module (building one takes about a second)."""

from __future__ import annotations

import pytest
from repbench_tasks.peg_in_hole import PegInHoleTask

import repbench  # noqa: F401  (sets MUJOCO_GL before mujoco is imported)


@pytest.fixture(scope="module")
def task() -> PegInHoleTask:
    return PegInHoleTask(horizon=300)


@pytest.fixture(scope="module")
def env(task: PegInHoleTask):
    e = task.make_env()
    yield e.unwrapped
    e.close()
