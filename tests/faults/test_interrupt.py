"""Ctrl-C during a stage: nothing half-done is stored, the run says so and exits 130."""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path

import pytest

from repbench.pipeline.store import Store

from .conftest import Cli, fault_suite

EPOCHS = 4000
INTERRUPTED = "interrupted; finished stages are kept in the store"


def _fault_mlp_values(store: Path) -> list[float]:
    return [a.read_json()["value"] for a in Store(store).list("metric")
            if a.meta["config"]["metric"] == "fault_mlp"]


@pytest.mark.parametrize("workers", [1, 2])
def test_ctrl_c_during_a_stage_stores_nothing_of_it(cli: Cli, workers: int) -> None:
    suite = cli.cwd / "faults.toml"
    suite.write_text(fault_suite("faults", ["fault_mlp"], epochs=EPOCHS))
    store = cli.cwd / "store"
    args = ("run", "--suite", str(suite), "--store", str(store), "--out", str(cli.cwd / "lb"),
            "--workers", str(workers))
    proc = cli.start(*args)
    try:
        start = cli.wait_for("start", "fault_mlp", proc)
        proc.send_signal(signal.SIGINT)  # what the terminal sends the foreground group
        if workers > 1:  # the terminal signals every process of the group, workers too
            os.kill(start["pid"], signal.SIGINT)
        code = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    out, err = cli.output()
    assert code == 130, (out, err)
    assert INTERRUPTED in err
    # nothing but the one line: no traceback, no resource tracker's "leaked semaphore" warning
    # (a worker killed while it held tqdm's multiprocessing lock left one behind)
    for noise in ("Traceback", "KeyboardInterrupt", "resource_tracker", "leaked"):
        assert noise not in out + err, err
    assert len([line for line in err.splitlines() if line.strip()
                and not line.lstrip().startswith("stages:")]) == 1, err
    assert _fault_mlp_values(store) == []  # the interrupted stage was not committed
    assert not any(e["event"] == "end" and e.get("n_iter") == EPOCHS for e in cli.events())

    rerun = cli.run(*args)
    assert rerun.returncode == 0, rerun.stdout[-2000:] + rerun.stderr[-2000:]
    assert _fault_mlp_values(store) == [float(EPOCHS)]  # recomputed, uninterrupted
    record = next(store.glob("metric/*/record.json"))
    assert json.loads(record.read_text())["values"]["value"] == EPOCHS
