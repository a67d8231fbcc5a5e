"""The stage store: content keys, atomic writes, checksums, corruption, kill -9 safety."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from repbench.errors import StoreError
from repbench.pipeline.store import Store, stage_key


def _put(store: Store, key: str, payload: bytes = b"x" * 1000) -> None:
    with store.write("stage", key, config={"a": 1}) as w:
        w.file("data.bin").write_bytes(payload)
        w.write_json({"ok": True})


def test_key_depends_on_config_and_inputs_only() -> None:
    k = stage_key("s", {"a": 1, "b": [1, 2]}, ["in1"])
    assert k == stage_key("s", {"b": [1, 2], "a": 1}, ["in1"])  # key order irrelevant
    assert k != stage_key("s", {"a": 2, "b": [1, 2]}, ["in1"])
    assert k != stage_key("s", {"a": 1, "b": [1, 2]}, ["in2"])
    assert k != stage_key("t", {"a": 1, "b": [1, 2]}, ["in1"])


def test_roundtrip_with_metadata(tmp_path: Path) -> None:
    store = Store(tmp_path)
    _put(store, "k1")
    art = store.get("stage", "k1")
    assert art is not None
    assert art.read_json() == {"ok": True}
    assert art.file("data.bin").read_bytes() == b"x" * 1000
    meta = art.meta
    assert meta["config"] == {"a": 1}
    assert set(meta["files"]) == {"data.bin", "result.json"}
    assert "numpy" in meta["versions"] and "wall_time_s" in meta and "created" in meta
    assert store.list("stage")[0].key == "k1"


def test_failed_stage_leaves_nothing(tmp_path: Path) -> None:
    store = Store(tmp_path)
    with pytest.raises(RuntimeError), store.write("stage", "k2", config={}) as w:
        w.file("half.bin").write_bytes(b"partial")
        raise RuntimeError("stage crashed")
    assert store.get("stage", "k2") is None
    assert list((tmp_path / ".tmp").iterdir()) == []


@pytest.mark.parametrize("damage", ["truncate", "delete", "meta"])
def test_corrupt_artifact_detected_and_quarantined(tmp_path: Path, damage: str,
                                                   caplog: pytest.LogCaptureFixture) -> None:
    store = Store(tmp_path)
    _put(store, "k3")
    path = store.artifact_dir("stage", "k3")
    if damage == "truncate":
        data = (path / "data.bin").read_bytes()
        (path / "data.bin").write_bytes(data[:10])
    elif damage == "delete":
        (path / "data.bin").unlink()
    else:
        (path / "meta.json").write_text("{not json")
    assert store.get("stage", "k3") is None
    assert "will be recomputed" in caplog.text
    assert not path.exists() and any((tmp_path / ".corrupt").iterdir())
    _put(store, "k3")  # recomputation succeeds
    assert store.get("stage", "k3") is not None



@pytest.mark.parametrize("where", ["artifact", "stage folder"])
def test_artifact_folder_replaced_by_a_file_is_quarantined(tmp_path: Path, where: str,
                                                           caplog: pytest.LogCaptureFixture
                                                           ) -> None:
    """Before: the stage was recomputed, then its commit failed with a raw NotADirectoryError
    (rename onto the file), and every later run failed the same way. Now the file is moved
    aside to .corrupt/ like any corrupt artifact, and the stage is recomputed."""
    store = Store(tmp_path)
    _put(store, "k5")
    _put(store, "other")
    path = store.artifact_dir("stage", "k5")
    target = path if where == "artifact" else path.parent
    shutil.rmtree(target)
    target.write_text("not a folder")
    assert store.get("stage", "k5") is None
    assert [a.key for a in store.list("stage")] == (["other"] if where == "artifact" else [])
    what = "the artifact folder of stage/k5" if where == "artifact" else "a stage folder"
    assert f"{target} is a file, not {what}" in caplog.text
    assert "will be recomputed" in caplog.text
    assert target.is_dir() or not target.exists()
    kept = [p for p in (tmp_path / ".corrupt").iterdir() if p.is_file()]
    assert [p.read_text() for p in kept] == ["not a folder"]  # moved aside, not deleted
    _put(store, "k5")  # recomputation succeeds
    assert store.get("stage", "k5") is not None


def test_unwritable_root_is_a_clear_error(tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    with pytest.raises(StoreError, match=r"is not writable.*--store DIR"):
        Store(blocker / "store")


def test_root_from_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("REPBENCH_STORE", str(tmp_path / "envstore"))
    assert Store().root == tmp_path / "envstore"


_SLOW_WRITER = textwrap.dedent("""
    import sys, time
    from repbench.pipeline.store import Store
    store = Store(sys.argv[1])
    with store.write("stage", "big", config={}) as w:
        with open(w.file("data.bin"), "wb") as f:
            for _ in range(10_000):
                f.write(b"y" * 100_000)
                f.flush()
                time.sleep(0.01)
""")


def test_kill_9_during_write_never_exposes_a_partial_artifact(tmp_path: Path) -> None:
    proc = subprocess.Popen([sys.executable, "-c", _SLOW_WRITER, str(tmp_path)])
    try:
        deadline = time.time() + 60
        partial = None
        while time.time() < deadline:
            partial = next((tmp_path / ".tmp").glob("stage-big-*/data.bin"), None)
            if partial is not None and partial.stat().st_size > 1_000_000:
                break
            time.sleep(0.05)
        assert partial is not None, "writer never started"
        store = Store(tmp_path)
        assert store.get("stage", "big") is None  # in flight: invisible
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    store = Store(tmp_path)
    assert store.get("stage", "big") is None  # killed: still invisible
    assert not store.artifact_dir("stage", "big").exists()
    assert store.clean_tmp(older_than_s=0) == 1
    _put(store, "big")
    assert store.get("stage", "big") is not None


def test_a_records_folder_is_refused_as_a_store_and_still_read(tmp_path: Path) -> None:
    """A store opened on a leaderboard's ``records/`` folder would create ``.tmp/`` there, and
    readers would then take the folder for a store and find no records in it."""
    from repbench.analysis.results import load_records

    shipped = next((Path(__file__).parents[2] / "leaderboards/quick/records/rl").glob("*.json"))
    records = tmp_path / "records"
    (records / "rl").mkdir(parents=True)
    (records / "rl" / shipped.name).write_bytes(shipped.read_bytes())
    with pytest.raises(StoreError, match=r"folder of exported records.*another --store"):
        Store(records)
    assert not (records / ".tmp").exists()  # nothing written
    (records / ".tmp").mkdir()  # left by an older version
    assert [r["kind"] for r in load_records(records)] == ["rl"]


@pytest.mark.parametrize("source", ["store", "path", "str", "duck"])
def test_records_are_read_alike_from_a_store_or_its_folder(tmp_path: Path, source: str) -> None:
    """The analysis reads a store's records without the pipeline's code: a :class:`Store`, any
    object with the store's folder as ``root``, or the folder itself (a ``Path``, whose own
    ``root`` is "/", or a string) give the same records, each checked against its artifact's
    ``meta.json`` (a record rewritten in other whitespace keeps its own checksum but not the
    store's)."""
    import json
    from types import SimpleNamespace

    from repbench.analysis.results import load_records
    from repbench.records import RECORD_FILE, make_record, write_record

    store = Store(tmp_path / "st")
    for key in ("sound", "rewritten"):
        with store.write("metric", key, config={}) as w:
            record = make_record({"kind": "metric", "task": {"name": "T", "version": 0,
                                                             "params": {}}},
                                 {"value": 0.5}, stage={"key": key}, timings={})
            write_record(record, w.file(RECORD_FILE))
    rewritten = store.root / "metric" / "rewritten" / RECORD_FILE
    rewritten.write_text(json.dumps(json.loads(rewritten.read_text()), indent=3))
    given = {"store": store, "path": store.root, "str": str(store.root),
             "duck": SimpleNamespace(root=str(store.root))}[source]
    problems: list[str] = []
    records = load_records(given, problems=problems)
    assert [r["stage"]["key"] for r in records] == ["sound"]
    assert problems == [f"record {rewritten} fails its checksum (edited or corrupt): left out; "
                        "rerun the stage with `repbench run`"]
