"""Shared end-to-end fixtures: one real smoke-suite run per test session."""

from __future__ import annotations

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
bootstrap = 10
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
    """`repbench run --suite smoke` into a fresh store, as a user would type it."""
    base = tmp_path_factory.mktemp("smoke")
    store, out = base / "store", base / "leaderboard"
    proc, secs = run_repbench("run", "--suite", "smoke", "--store", str(store), "--out", str(out),
                              "--workers", "2")
    return SuiteRun(store, out, proc.stdout, proc.stderr, secs, proc.returncode)


@pytest.fixture(scope="session")
def mini_suite(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("suites") / "mini.toml"
    p.write_text(MINI_SUITE)
    return p
