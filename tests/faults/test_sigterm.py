"""SIGTERM (``kill PID``, a scheduler's or container's stop) stops a run as Ctrl-C does: the
same one-line "interrupted" message, no traceback, nothing half-done stored, the finished stages
kept, and exit code 143 (128 + SIGTERM, as a shell reports a process the signal ended). Before:
exit 143 with no message (Python's default action for the signal)."""

from __future__ import annotations

import signal
import time

import pytest

from .conftest import Cli, alive, children_of, fault_suite
from .test_interrupt import EPOCHS, INTERRUPTED, _fault_mlp_values


@pytest.mark.parametrize("workers", [1, 2])
def test_sigterm_stops_a_run_like_ctrl_c(cli: Cli, workers: int) -> None:
    suite = cli.cwd / "faults.toml"
    suite.write_text(fault_suite("faults", ["fault_mlp"], epochs=EPOCHS))
    store = cli.cwd / "store"
    args = ("run", "--suite", str(suite), "--store", str(store), "--out", str(cli.cwd / "lb"),
            "--workers", str(workers))
    proc = cli.start(*args)
    try:
        cli.wait_for("start", "fault_mlp", proc)
        workers_before = children_of(proc.pid)
        proc.send_signal(signal.SIGTERM)  # to the parent alone, as `kill PID` does
        code = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    out, err = cli.output()
    assert code == 143, (out, err)
    assert INTERRUPTED in err, err
    assert len([line for line in err.splitlines() if line.strip()
                and not line.lstrip().startswith("stages:")]) == 1, err
    for noise in ("Traceback", "KeyboardInterrupt", "resource_tracker", "leaked"):
        assert noise not in out + err, err
    assert _fault_mlp_values(store) == []  # the interrupted stage was not committed
    assert (store / "dataset").is_dir()  # the stages finished before it are kept
    deadline = time.time() + 10
    while any(alive(p) for p in workers_before) and time.time() < deadline:
        time.sleep(0.1)
    assert not any(alive(p) for p in workers_before)

    rerun = cli.run(*args)
    assert rerun.returncode == 0, rerun.stdout[-2000:] + rerun.stderr[-2000:]
    assert "reused from the store" in rerun.stdout
    assert _fault_mlp_values(store) == [float(EPOCHS)]
