"""The main job end to end: `repbench run --suite smoke`, every stage real."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

from repbench.pipeline.store import Store
from repbench.pipeline.suite import load_suite

from .conftest import SuiteRun, run_repbench

# one xdist worker runs every test of the smoke_run fixture, so the smoke suite runs once
pytestmark = pytest.mark.xdist_group("smoke_run")


def test_smoke_suite_runs_end_to_end(smoke_run: SuiteRun) -> None:
    assert smoke_run.returncode == 0, smoke_run.stdout[-3000:] + smoke_run.stderr[-3000:]
    assert "0 failed, 0 skipped" in smoke_run.stdout
    assert f"leaderboards written to {smoke_run.out}" in smoke_run.stdout
    print(f"smoke suite wall time: {smoke_run.seconds:.0f} s")


def test_smoke_leaderboards_cover_every_pair(smoke_run: SuiteRun) -> None:
    suite = load_suite("smoke")
    enc = pd.read_csv(smoke_run.out / "encoders.csv")
    assert sorted(enc["encoder"]) == sorted(suite.encoders)
    for m in suite.metrics:
        assert enc[m].notna().all(), f"metric {m} missing for some encoder"
    for a in suite.agents:
        assert enc[f"{a}_return"].notna().all() and (enc[f"{a}_seeds"] == len(suite.seeds)).all()
    met = pd.read_csv(smoke_run.out / "metrics.csv")
    assert len(met) == len(suite.agents) * len(suite.metrics)
    assert (met["n_encoders"] == len(suite.encoders)).all()
    html = (smoke_run.out / "index.html").read_text()
    for fig in ("Metric vs RL return", "Latent distance", "smoothness histogram",
                "True-state differences", "Learning curves"):
        assert fig in html


def test_leaderboard_rebuilds_without_recomputing(smoke_run: SuiteRun, tmp_path: Path) -> None:
    # a private copy: tests in the other xdist process add stages to the shared smoke store
    root = shutil.copytree(smoke_run.store, tmp_path / "store",
                           ignore=shutil.ignore_patterns(".tmp"))
    store = Store(root)
    before = {(a.stage, a.key): a.meta["created"] for st in ("metric", "rl", "encoder")
              for a in store.list(st)}
    out2 = tmp_path / "rebuilt"
    proc, _ = run_repbench("leaderboard", "--suite", "smoke", "--store", str(root),
                           "--out", str(out2))
    assert proc.returncode == 0, proc.stderr
    after = {(a.stage, a.key): a.meta["created"] for st in ("metric", "rl", "encoder")
             for a in store.list(st)}
    assert after == before
    pd.testing.assert_frame_equal(pd.read_csv(out2 / "encoders.csv"),
                                  pd.read_csv(smoke_run.out / "encoders.csv"))
