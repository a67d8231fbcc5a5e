"""Shared end-to-end fixtures: one real smoke-suite run per test session (shared by the xdist
worker processes: the first to need it runs it under a file lock, the others read its result)."""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

MINI_SUITE = """
name = "mini"
description = "A cut-down smoke suite for the resume and executor tests."
tasks = ["PegInHole-v0"]
encoders = ["oracle", "pca", "random"]
metrics = ["ksg", "regression", "coherence"]
agents = ["sac"]
seeds = [0]
[dataset]
random_episodes = 4
random_steps = 30
on_policy_episodes = 0
on_policy_steps = 10
[encoder_training]
latent_dim = 8
epochs = 1
batch_size = 32
[rl]
train_steps = 200
eval_episodes = 2
curve_points = 2
full_state_train_steps = 200
[metric_settings]
bootstrap = 20
[task_params."PegInHole-v0"]
horizon = 30
[agent_params.sac]
learning_starts = 100
batch_size = 32
"""


@dataclass
class SuiteRun:
    store: Path
    out: Path
    stdout: str
    stderr: str
    seconds: float
    returncode: int


def repbench_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "repbench.cli", *args]


def run_repbench(*args: str, timeout: float = 900
                 ) -> tuple[subprocess.CompletedProcess[str], float]:
    start = time.time()
    proc = subprocess.run(repbench_cmd(*args), capture_output=True, text=True, timeout=timeout)
    return proc, time.time() - start


@pytest.fixture(scope="session")
def smoke_run(tmp_path_factory: pytest.TempPathFactory) -> SuiteRun:
    """`repbench run --suite smoke` into a fresh store, as a user would type it; once per test
    session, whichever xdist worker asks first."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the session's folder, above every worker's own
    base, done = root / "smoke_shared", root / "smoke_shared.json"
    with (root / "smoke_shared.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if done.is_file():
            saved = json.loads(done.read_text())
            return SuiteRun(Path(saved["store"]), Path(saved["out"]), saved["stdout"],
                            saved["stderr"], saved["seconds"], saved["returncode"])
        base.mkdir(exist_ok=True)
        store, out = base / "store", base / "leaderboard"
        try:
            proc, secs = run_repbench("run", "--suite", "smoke", "--store", str(store), "--out",
                                      str(out), "--workers", "2")
            run = SuiteRun(store, out, proc.stdout, proc.stderr, secs, proc.returncode)
        except subprocess.TimeoutExpired as exc:  # every test that needs it fails, once
            run = SuiteRun(store, out, str(exc.stdout or ""), f"timed out: {exc}",
                           float(exc.timeout), -9)
        done.write_text(json.dumps({**run.__dict__, "store": str(store), "out": str(out)}))
        return run


@pytest.fixture(scope="session")
def mini_suite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("suites") / "mini.toml"
    p.write_text(MINI_SUITE)
    return p
