"""kill -9 of a run: its pool workers die with it, and the next run cleans their leftovers."""

from __future__ import annotations

import os
import signal
import time

from .conftest import Cli, alive, children_of, fault_suite


def test_workers_die_with_a_killed_run_and_the_next_run_cleans_up(cli: Cli) -> None:
    suite = cli.cwd / "kill.toml"
    suite.write_text(fault_suite("kill", ["fault_mlp"], epochs=40000))  # ~30 s: still running
    store = cli.cwd / "store"
    args = ("run", "--suite", str(suite), "--store", str(store), "--out", str(cli.cwd / "lb"),
            "--workers", "2")
    proc = cli.start(*args)
    children: list[int] = []
    try:
        worker = cli.wait_for("start", "fault_mlp", proc)["pid"]
        children = children_of(proc.pid)
        assert worker in children
        leftovers = list((store / ".tmp").glob("metric-*"))
        assert leftovers, "the metric stage is being written in the store's .tmp"
        os.kill(proc.pid, signal.SIGKILL)  # the run only, not its process group
        proc.wait(timeout=10)
        deadline = time.time() + 10
        while time.time() < deadline and any(alive(c) for c in children):
            time.sleep(0.2)
        assert not [c for c in children if alive(c)], "pool workers outlived their run"
    finally:  # never leave a process of this test behind
        for pid in [proc.pid, *children_of(proc.pid), *children]:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert all(p.exists() for p in leftovers)  # killed mid-stage: its folder is left behind

    suite.write_text(fault_suite("kill", ["fault_mlp"], epochs=50))  # the next run, any suite
    rerun = cli.run(*args)
    assert rerun.returncode == 0, rerun.stdout[-2000:] + rerun.stderr[-2000:]
    assert "removed 1 temporary stage folders left by killed runs" in rerun.stdout
    assert not any(p.exists() for p in leftovers)
    assert [p for p in (store / ".tmp").iterdir() if p.is_dir()] == []
