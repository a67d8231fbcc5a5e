"""Test-wide settings: never touch the user's store; keep torch to one thread per process."""

from __future__ import annotations

import os

import pytest


@pytest.fixture(autouse=True, scope="session")
def _isolated_store(tmp_path_factory: pytest.TempPathFactory) -> None:
    if not os.environ.get("REPBENCH_STORE"):
        os.environ["REPBENCH_STORE"] = str(tmp_path_factory.mktemp("store"))
