"""Interrupt with kill -9 and resume; the Ray executor gives the same results as local."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from repbench.dataset import Dataset
from repbench.pipeline.store import Store

from .conftest import repbench_cmd, run_repbench

STAGES = ("dataset", "encoder", "latents", "metric", "rl", "diagnostics")


def _artifacts(store_root: Path) -> dict[tuple[str, str], str]:
    store = Store(store_root)
    return {(a.stage, a.key): a.meta["created"] + json.dumps(a.meta["files"])
            for st in STAGES for a in store.list(st)}


@pytest.fixture(scope="module")
def resumed_store(mini_suite: Path, tmp_path_factory: pytest.TempPathFactory
                  ) -> tuple[Path, Path, dict, str]:
    base = tmp_path_factory.mktemp("resume")
    store, out = base / "store", base / "out"
    args = ["run", "--suite", str(mini_suite), "--store", str(store), "--out", str(out),
            "--workers", "2"]
    proc = subprocess.Popen(repbench_cmd(*args), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.time() + 600
        while time.time() < deadline and proc.poll() is None:
            if store.exists() and len(_artifacts(store)) >= 4:
                break
            time.sleep(0.2)
        assert proc.poll() is None, "the run finished before it could be interrupted"
        os.killpg(proc.pid, signal.SIGKILL)  # the runner and its workers, mid-stage
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    finished_before = _artifacts(store)
    second, _ = run_repbench(*args)
    assert second.returncode == 0, second.stdout[-2000:] + second.stderr[-2000:]
    return store, out, finished_before, second.stdout


def test_kill_9_then_resume_recomputes_nothing_finished(resumed_store) -> None:  # type: ignore[no-untyped-def]
    store, out, before, stdout = resumed_store
    assert len(before) >= 4
    after = _artifacts(store)
    for key, stamp in before.items():
        assert after[key] == stamp, f"{key} was recomputed after resume"
    assert f"reusing {len(before)} finished stages" in stdout
    assert len(after) > len(before)
    enc = pd.read_csv(out / "encoders.csv")
    assert sorted(enc["encoder"]) == ["oracle", "pca", "random"]
    assert enc[["ksg", "regression", "coherence", "sac_return"]].notna().all().all()


@pytest.mark.slow  # the fast equivalent in the default run: tests/faults/test_ray_cluster.py
def test_ray_executor_matches_local(resumed_store, mini_suite: Path,  # type: ignore[no-untyped-def]
                                    tmp_path: Path) -> None:
    """The mini suite under ``--executor ray`` stores what the local executor stores. Behind
    ``-m slow`` (the longest test of the default run, ~5 min on 2 loaded cores): the Ray
    cluster test runs 14 stages on Ray and compares datasets, latents, metric values, RL
    returns and the board with a local run bit for bit (``_assert_same_results``)."""
    pytest.importorskip("ray")
    local_store, local_out, _, _ = resumed_store
    ray_store, ray_out = tmp_path / "store", tmp_path / "out"
    proc, _ = run_repbench("run", "--suite", str(mini_suite), "--store", str(ray_store),
                           "--out", str(ray_out), "--executor", "ray", "--workers", "2")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    local, ray = _artifacts(local_store), _artifacts(ray_store)
    assert set(local) == set(ray)  # the same plan, the same keys
    for stage in ("dataset", "encoder", "latents", "metric"):
        for k in (k for k in local if k[0] == stage):
            a = Store(local_store).get(*k)
            b = Store(ray_store).get(*k)
            assert a is not None and b is not None
            if stage == "metric":
                assert a.read_json()["value"] == b.read_json()["value"], k
            elif stage == "dataset":  # identical arrays (files differ: timings, zip dates)
                assert (Dataset.load(a.file("dataset.npz")).checksum()
                        == Dataset.load(b.file("dataset.npz")).checksum()), k
            elif stage == "latents":
                with np.load(a.file("latents.npz")) as za, np.load(b.file("latents.npz")) as zb:
                    np.testing.assert_array_equal(za["z"], zb["z"], err_msg=str(k))
    cols = ["encoder", "ksg", "regression", "coherence"]
    pd.testing.assert_frame_equal(
        pd.read_csv(local_out / "encoders.csv")[cols].sort_values("encoder", ignore_index=True),
        pd.read_csv(ray_out / "encoders.csv")[cols].sort_values("encoder", ignore_index=True))
