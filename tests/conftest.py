"""Test-wide settings: never touch the user's store; keep torch to one thread per process."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(autouse=True, scope="session")
def _isolated_store(tmp_path_factory: pytest.TempPathFactory) -> None:
    if not os.environ.get("REPBENCH_STORE"):
        os.environ["REPBENCH_STORE"] = str(tmp_path_factory.mktemp("store"))


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config: pytest.Config) -> None:
    """Benchmarks time one process: ``--benchmark-only`` turns off the two test processes that
    pyproject's addopts ask for (pytest-benchmark would otherwise disable itself under xdist)."""
    if getattr(config.option, "benchmark_only", False) and getattr(config.option, "dist", "no"
                                                                     ) != "no":
        config.option.dist = "no"
        config.option.numprocesses = 0
