"""A two-node Ray cluster on this machine (a head and one worker node, ``ray.cluster_utils``)
runs the tiny ToyReach suite with the results of the local executor, and loses nothing when the
worker node dies with a stage in flight: Ray reruns the lost stage on the head, the stages that
had finished stay as they were in the shared store, and the half-written one leaves only a
temporary folder (no artifact) that the next run's clean-up removes.

The cluster's driver is the real ``repbench run --executor ray --ray-address HOST:PORT`` in a
subprocess; its workers find the ``fault_mlp`` metric (a stage that takes seconds, and logs its
start and end with the process id) through the environment the cluster's nodes are started
with. Until the worker node is killed a placement group holds the head's CPU, so the stages run
on the worker node (and the one killed is certain to be there); then the head takes over. Ray's
temporary folder is the test's own, so the cluster's address file never points a ``ray.init()``
of another test process at this cluster.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from repbench.dataset import Dataset
from repbench.pipeline.store import Store

from .conftest import Cli, alive, children_of, fault_suite

pytest.importorskip("ray", reason="the Ray cluster test needs Ray: pip install 'repbench[ray]'")

import ray
from ray._private import ray_constants
from ray.cluster_utils import Cluster
from ray.util.placement_group import (
    PlacementGroup,
    placement_group,
    remove_placement_group,
)

STAGES = ("dataset", "diagnostics", "encoder", "latents", "metric", "rl")
#: fault_mlp's epochs: seconds of work, so the worker node dies in the middle of the stage
EPOCHS = 8000


@pytest.fixture
def cluster(cli: Cli, monkeypatch: pytest.MonkeyPatch
            ) -> Iterator[tuple[Cluster, object, PlacementGroup]]:
    """A head node and one worker node, one CPU each, and this process connected to it as a
    driver; yields (cluster, worker node, the placement group that holds the head's CPU)."""
    # short: Ray's socket paths live below it and a Unix socket path has ~107 characters
    ray_tmp = tempfile.mkdtemp(prefix="rbray-", dir="/tmp")
    # the nodes' processes (and so every Ray worker) inherit this process's environment
    for name in ("PYTHONPATH", "FAULTS_LOG"):
        monkeypatch.setenv(name, cli.env[name])
    monkeypatch.setenv("RAY_TMPDIR", ray_tmp)
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    cli.env["RAY_TMPDIR"] = ray_tmp
    cli.env.pop("RAY_ADDRESS", None)
    c = Cluster(initialize_head=True, connect=False,
                head_node_args={"num_cpus": 1, "resources": {"head": 1},
                                "include_dashboard": False})
    worker_pids: list[int] = []
    try:
        worker = c.add_node(num_cpus=1)
        c.wait_for_nodes()
        worker_pids.extend(children_of(_raylet_pid(worker)))
        ray.init(address=c.address, log_to_driver=False)
        hold = placement_group([{"CPU": 1, "head": 1}])  # the head's CPU, and only that
        ray.get(hold.ready(), timeout=120)
        yield c, worker, hold
    finally:
        ray.shutdown()
        c.shutdown()
        # remove_node kills the worker node's raylet, which ends its Ray workers; its
        # dashboard and runtime-env agents linger a while: end them (this test started them)
        for pid in worker_pids:
            if alive(pid):
                with contextlib.suppress(OSError):
                    os.kill(pid, signal.SIGKILL)
        shutil.rmtree(ray_tmp, ignore_errors=True)


def _raylet_pid(node: object) -> int:
    return int(node.all_processes[ray_constants.PROCESS_TYPE_RAYLET][0].process.pid)  # type: ignore[attr-defined]


def _stamps(store_root: Path) -> dict[tuple[str, str], tuple[str, int]]:
    """Every verified artifact → (its record's creation time, its meta.json's mtime in ns)."""
    store = Store(store_root)
    return {(a.stage, a.key): (a.meta["created"], (a.path / "meta.json").stat().st_mtime_ns)
            for st in STAGES for a in store.list(st)}


def _start_on(cli: Cli, pids: set[int]) -> dict | None:
    return next((e for e in cli.events()
                 if e["event"] == "start" and e["metric"] == "fault_mlp" and e["pid"] in pids),
                None)


def test_worker_node_lost_mid_stage_reruns_it_and_keeps_finished_stages(
        cli: Cli, cluster: tuple[Cluster, object, PlacementGroup]) -> None:
    c, worker, hold = cluster
    suite = cli.cwd / "cluster.toml"
    suite.write_text(fault_suite("cluster", ["ksg", "regression", "fault_mlp"],
                                 encoders=("oracle", "pca"), epochs=EPOCHS))
    local_store, ray_store = cli.cwd / "local", cli.cwd / "ray"
    # the local executor's run, the reference, beside the Ray run (its own events log)
    local_cli = Cli({**cli.env, "FAULTS_LOG": str(cli.cwd / "local.jsonl")}, cli.cwd,
                    cli.cwd / "local.jsonl")
    local = local_cli.start("run", "--suite", str(suite), "--store", str(local_store),
                            "--out", str(cli.cwd / "local_lb"), "--workers", "1", name="local")
    raylet = _raylet_pid(worker)
    proc = cli.start("run", "--suite", str(suite), "--store", str(ray_store), "--out",
                     str(cli.cwd / "ray_lb"), "--executor", "ray", "--ray-address", c.address,
                     name="ray")
    try:
        lost = None
        deadline = time.time() + 240
        while lost is None and proc.poll() is None and time.time() < deadline:
            lost = _start_on(cli, set(children_of(raylet)))
            time.sleep(0.05)
        assert lost is not None, f"no fault_mlp stage on the worker node: {cli.output('ray')}"
        kept = _stamps(ray_store)  # finished when the node dies
        # <stage>-<key>-<pid>-<tag>: the folder the stage is being written to
        half = [p.name for p in (ray_store / ".tmp").iterdir()
                if p.name.rsplit("-", 3)[2:3] == [str(lost["pid"])]]
        c.remove_node(worker, allow_graceful=False)  # SIGKILL: the node is gone at once
        remove_placement_group(hold)  # the head's CPU is free for the rest of the run
        code = proc.wait(timeout=300)
        local_code = local.wait(timeout=300)
    finally:
        for p in (proc, local):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=30)
    assert local_code == 0, local_cli.output("local")
    out, err = cli.output("ray")
    assert code == 0, out[-3000:] + err[-3000:]
    assert not alive(lost["pid"])

    # the lost stage ran again (on the head) and nothing else did
    assert "stages: 14 computed, 0 reused from the store, 0 failed, 0 skipped" in out, out
    events = [e for e in cli.events() if e["metric"] == "fault_mlp"]
    starts = [e["pid"] for e in events if e["event"] == "start"]
    ends = [e["pid"] for e in events if e["event"] == "end"]
    assert len(starts) == 3 and len(ends) == 2 and lost["pid"] not in ends, events
    assert len(kept) >= 6  # at least dataset, diagnostics, encoders, latents
    after = _stamps(ray_store)
    for k, stamp in kept.items():
        assert after[k] == stamp, f"{k} finished before the node died, and was recomputed"

    # the killed writer left a temporary folder, never an artifact; the next run removes it
    assert len(half) == 1, half
    stage, key = half[0].split("-")[:2]
    art = Store(ray_store).get(stage, key)
    assert art is not None and (stage, key) not in kept
    assert not (ray_store / ".corrupt").exists()
    assert (ray_store / ".tmp" / half[0]).is_dir()
    assert Store(ray_store).clean_tmp() == 1
    assert not (ray_store / ".tmp" / half[0]).exists()

    _assert_same_results(local_store, ray_store, cli.cwd / "local_lb", cli.cwd / "ray_lb")


def _assert_same_results(local_store: Path, ray_store: Path, local_lb: Path,
                         ray_lb: Path) -> None:
    """The same stages, with the same datasets, latents, metric values and RL returns."""
    a_store, b_store = Store(local_store), Store(ray_store)
    keys = set(_stamps(local_store))
    assert keys == set(_stamps(ray_store))
    assert len(keys) == 14
    for stage, key in sorted(keys):
        a, b = a_store.get(stage, key), b_store.get(stage, key)
        assert a is not None and b is not None
        if stage == "dataset":
            assert (Dataset.load(a.file("dataset.npz")).checksum()
                    == Dataset.load(b.file("dataset.npz")).checksum())
        elif stage == "latents":
            with np.load(a.file("latents.npz")) as za, np.load(b.file("latents.npz")) as zb:
                np.testing.assert_array_equal(za["z"], zb["z"], err_msg=key)
        elif stage == "metric":
            assert a.read_json()["value"] == b.read_json()["value"], key
        elif stage == "rl":
            ra, rb = a.read_json(), b.read_json()
            assert (ra["eval_return"], ra["curve_return"]) == (rb["eval_return"],
                                                               rb["curve_return"]), key
    cols = ["encoder", "ksg", "regression", "fault_mlp", "sac_return"]
    boards = [pd.read_csv(lb / "encoders.csv") for lb in (local_lb, ray_lb)]
    for board in boards:
        assert set(cols) <= set(board.columns), board.columns
    pd.testing.assert_frame_equal(
        *(b[cols].sort_values("encoder", ignore_index=True) for b in boards))


def test_a_stage_ray_lost_for_good_fails_in_one_line() -> None:
    from repbench.pipeline.executors import _ray_failure

    msg = _ray_failure(ray.exceptions.NodeDiedError(
        "Task failed because the node it was running on is dead or unavailable. Node IP: "
        "10.0.0.2, node ID: abc.\nTo see node death information, use `ray list nodes`"))
    assert "\n" not in msg
    assert msg.startswith("lost with its Ray node or worker process") and "NodeDiedError" in msg
    assert "run the same command again" in msg
    other = _ray_failure(ray.exceptions.RaySystemError("boom\ntraceback"))
    assert other == "Ray task failed (RaySystemError): System error: boom"
