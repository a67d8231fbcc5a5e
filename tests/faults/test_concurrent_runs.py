"""Two runs on one store at once compute every stage once; a dead process's lock never blocks."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

from repbench.pipeline.store import Store

from .conftest import Cli, fault_suite

SUMMARY = re.compile(r"stages: (\d+) computed, (\d+) reused from the store, (\d+) failed")


def test_two_runs_on_one_store_compute_each_stage_once(cli: Cli) -> None:
    suite = cli.cwd / "twice.toml"
    suite.write_text(fault_suite("twice", ["ksg", "fault_mlp"], epochs=300))
    store = cli.cwd / "store"
    runs = [cli.start("run", "--suite", str(suite), "--store", str(store), "--out",
                      str(cli.cwd / f"lb{n}"), "--workers", "1", name=f"run{n}")
            for n in (1, 2)]
    try:
        codes = [p.wait(timeout=300) for p in runs]
    finally:
        for p in runs:
            if p.poll() is None:
                p.kill()
    outputs = [cli.output(f"run{n}") for n in (1, 2)]
    assert codes == [0, 0], outputs
    summaries = [SUMMARY.search(out) for out, _ in outputs]
    assert all(summaries), outputs
    computed = [int(m.group(1)) for m in summaries if m]
    reused = [int(m.group(2)) for m in summaries if m]
    n_stages = len(list(store.glob("*/*/meta.json")))
    assert n_stages == 7  # dataset, diagnostics, encoder, latents, 2 metrics, 1 RL run
    said = "\n".join(f"run{n}: {line.strip()}" for n, (out, _) in enumerate(outputs, 1)
                     for line in out.splitlines()
                     if line.lstrip().startswith(("done", "reused", "FAILED")))
    assert sum(computed) == n_stages, said  # each stage computed by one run only
    assert [c + r for c, r in zip(computed, reused, strict=True)] == [n_stages, n_stages]
    starts = Counter(e["metric"] for e in cli.events() if e["event"] == "start")
    assert starts == {"fault_mlp": 1}


_HOLDER = """
import sys, time
from repbench.pipeline.store import Store
with Store(sys.argv[1]).lock("metric", "k") as held:
    print("held" if held else "busy", flush=True)
    time.sleep(600)
"""


def test_a_lock_is_free_once_its_holder_is_killed(tmp_path: Path) -> None:
    store = Store(tmp_path)
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(tmp_path)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        with store.lock("metric", "k", wait=False) as free:
            assert not free  # a live holder: busy
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=10)
    finally:
        if holder.poll() is None:
            holder.kill()
    assert store.lock_path("metric", "k").exists()  # the lock file stays behind ...
    start = time.time()
    with store.lock("metric", "k", wait=False) as free:
        assert free  # ... and blocks nobody
    assert time.time() - start < 1
