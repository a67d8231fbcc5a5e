"""A stage's value does not depend on how many stages run beside it (``--workers``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from repbench.pipeline.store import Store, git_commit

from .conftest import Cli, fault_suite

METRICS = ["ksg", "regression", "fault_threads"]


def _metrics(store: Path) -> dict[tuple[str, str], dict]:
    return {(a.key, a.meta["config"]["metric"]): a.read_json()
            for a in Store(store).list("metric")}


def test_stage_values_and_threads_are_the_same_with_1_and_2_workers(cli: Cli) -> None:
    suite = cli.cwd / "threads.toml"
    suite.write_text(fault_suite("threads", METRICS, encoders=("oracle", "pca")))
    results = {}
    for workers in (1, 2):
        store = cli.cwd / f"store{workers}"
        proc = cli.run("run", "--suite", str(suite), "--store", str(store), "--out",
                       str(cli.cwd / f"lb{workers}"), "--workers", str(workers))
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
        results[workers] = _metrics(store)
    one, two = results[1], results[2]
    assert set(one) == set(two) and len(one) == 2 * len(METRICS)
    for key, value in one.items():
        if key[1] == "fault_threads":  # the settings the stage ran with, in both executors
            assert value["value"] == 1.0, value
            assert {n for _, n in value["extras"]["pools"]} == {1}, value
            assert value["extras"] == two[key]["extras"], (value, two[key])
        assert value["value"] == two[key]["value"], (key, value, two[key])
        assert value["ci_low"] == two[key]["ci_low"] and value["ci_high"] == two[key]["ci_high"]
    for a in Store(cli.cwd / "store1").list("latents"):
        b = Store(cli.cwd / "store2").get("latents", a.key)
        assert b is not None
        with np.load(a.file("latents.npz")) as za, np.load(b.file("latents.npz")) as zb:
            np.testing.assert_array_equal(za["z"], zb["z"])
    # run from a folder outside the checkout: the records still name repbench's commit
    commits = {json.loads(p.read_text())["git_commit"]
               for p in (cli.cwd / "store2").glob("*/*/record.json")}
    assert commits == {git_commit()} and git_commit() is not None
