"""Every reader of records checks them: an edited or truncated record is left out by name,
never published; the rest is."""

from __future__ import annotations

import json
import logging
import os
import shutil
from pathlib import Path

import pandas as pd
import pytest

from repbench.analysis.results import load_records
from repbench.errors import ConfigError
from repbench.pipeline.evaluate import reference_dirs
from repbench.pipeline.records import CHECKSUM, SCHEMA_VERSION, inspect_record, record_checksum
from repbench.pipeline.runner import (
    board_records_folders,
    rebuild_leaderboards,
    records_of_suite,
    run_suite,
)
from repbench.pipeline.suite import load_suite

from .tiny_toy_suite import tiny_toy_suite

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """(suite file, store, leaderboard folder) of one finished tiny run."""
    base = tmp_path_factory.mktemp("checked")
    suite = base / "toycheck.toml"
    suite.write_text(tiny_toy_suite("toycheck", ["oracle", "pca"]))
    result = run_suite(suite, store=base / "store", out=base / "lb", workers=1, progress=False)
    assert not result.report.failed
    return suite, base / "store", base / "lb"


def _find(folder: Path, kind: str, encoder: str, name: str = "") -> Path:
    for path in sorted(folder.rglob("*.json")):
        r = json.loads(path.read_text())
        if (r.get("kind") == kind and r["encoder"]["name"] == encoder
                and name in {"", (r.get("metric") or r.get("agent") or {}).get("name")}):
            return path
    raise AssertionError(f"no {kind} record of {encoder} {name} in {folder}")


def _damage(tampered: Path, truncated: Path) -> float:
    """Move a metric value outside its own interval; cut a record in half."""
    r = json.loads(tampered.read_text())
    r["values"]["value"] = r["values"]["ci_high"] + 10.0
    tampered.write_text(json.dumps(r, indent=1, sort_keys=True))
    text = truncated.read_text()
    truncated.write_text(text[: len(text) // 2])
    return float(r["values"]["value"])


def _left_out(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING
            and "left out" in r.getMessage()]


def test_records_carry_their_checksum(finished: tuple[Path, Path, Path]) -> None:
    _, store, lb = finished
    written = sorted(store.glob("*/*/record.json")) + sorted((lb / "records").rglob("*.json"))
    assert len(written) == 2 * 12  # dataset, diagnostics, 2 × (encoder, latents, 2 metrics, RL)
    for path in written:
        record, problem = inspect_record(path)
        assert problem is None and record is not None
        assert record["schema_version"] == SCHEMA_VERSION == 2
        assert record[CHECKSUM] == record_checksum(record)


def test_damaged_records_in_a_records_folder_are_left_out_by_name(
        finished: tuple[Path, Path, Path], tmp_path: Path,
        caplog: pytest.LogCaptureFixture) -> None:
    suite, _, lb = finished
    folder = tmp_path / "records"
    shutil.copytree(lb / "records", folder)
    tampered = _find(folder, "metric", "pca", "regression")
    truncated = _find(folder, "rl", "oracle")
    edited = _damage(tampered, truncated)
    with caplog.at_level(logging.WARNING):
        rebuild_leaderboards(suite, records=folder, out=tmp_path / "out")
    assert sorted(_left_out(caplog)) == sorted([
        f"record {truncated} is not valid JSON (truncated or corrupt): left out; rerun the "
        "stage with `repbench run`",
        f"record {tampered} fails its checksum (edited or corrupt): left out; rerun the stage "
        "with `repbench run`"])
    enc = pd.read_csv(tmp_path / "out" / "encoders.csv").set_index("encoder")
    before = pd.read_csv(lb / "encoders.csv").set_index("encoder")
    assert pd.isna(enc.loc["pca", "regression"]) and edited not in enc.to_numpy()
    assert pd.isna(enc.loc["oracle", "sac_return"])
    for kept in (("pca", "ksg"), ("oracle", "regression"), ("pca", "sac_return")):
        assert enc.loc[kept] == before.loc[kept]  # the rest is published unchanged
    assert len(list((tmp_path / "out" / "records").rglob("*.json"))) == 12 - 2
    page = (tmp_path / "out" / "index.html").read_text()
    assert "fails its checksum (edited or corrupt)" in page and tampered.name in page


def test_damaged_records_in_a_store_are_left_out_by_name(
        finished: tuple[Path, Path, Path], tmp_path: Path,
        caplog: pytest.LogCaptureFixture) -> None:
    suite, store, lb = finished
    copy = tmp_path / "store"
    shutil.copytree(store, copy)
    tampered = _find(copy, "metric", "oracle", "ksg").parent / "record.json"
    truncated = _find(copy, "encoder", "pca").parent / "record.json"
    # the tamperer also fixes the record's own checksum: the store's meta.json still knows
    r = json.loads(tampered.read_text())
    r["values"]["value"] = r["values"]["ci_high"] + 10.0
    r[CHECKSUM] = record_checksum(r)
    tampered.write_text(json.dumps(r, indent=1, sort_keys=True))
    text = truncated.read_text()
    truncated.write_text(text[: len(text) // 3])
    with caplog.at_level(logging.WARNING):
        rebuild_leaderboards(suite, store=copy, out=tmp_path / "out")
    messages = _left_out(caplog)
    assert len(messages) == 2
    assert any(str(tampered) in m and "fails its checksum" in m for m in messages)
    assert any(str(truncated) in m and "not valid JSON" in m for m in messages)
    enc = pd.read_csv(tmp_path / "out" / "encoders.csv").set_index("encoder")
    assert pd.isna(enc.loc["oracle", "ksg"])
    assert enc.loc["pca", "ksg"] == pd.read_csv(lb / "encoders.csv").set_index(
        "encoder").loc["pca", "ksg"]


@pytest.mark.parametrize("suite", ["smoke", "quick"])
def test_shipped_reference_records_pass_their_checks(suite: str, tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """Every record in the folders ``repbench evaluate`` reads (from the source checkout: the
    working directory has no leaderboards/) passes its checks, and together they hold every
    task of the suite, none of them twice (evaluate would read it twice)."""
    monkeypatch.chdir(tmp_path)
    folders = reference_dirs(suite)
    assert folders[0] == ROOT / "leaderboards" / suite / "records"
    tasks: set[str] = set()
    seen: set[str] = set()
    for folder in folders:
        paths = sorted(folder.rglob("*.json"))
        assert paths, folder
        for path in paths:
            record, problem = inspect_record(path)
            assert problem is None and record is not None, problem
            assert record[CHECKSUM] == record_checksum(record)
        ours = records_of_suite(load_records(folder), load_suite(suite), folder)
        tasks |= {r["task"]["name"] for r in ours}
        identities = {r["identity"] for r in ours}
        assert not identities & seen, f"{folder} repeats records of an earlier reference folder"
        seen |= identities
    assert sorted(tasks) == sorted(load_suite(suite).tasks)


def test_a_reference_manifest_lists_folders_and_a_bad_one_says_what_to_fix(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    suite = tmp_path / "leaderboards" / "s"
    for folder in ("records", "b/records"):
        (suite / folder).mkdir(parents=True)
    (suite / "records" / "r.json").write_text("{}")
    assert reference_dirs("s") == [Path("leaderboards/s/records")]  # no manifest: records/
    manifest = suite / "reference.toml"
    manifest.write_text('records = ["records", "b/records"]\n')
    assert reference_dirs("s") == [Path("leaderboards/s/records"), Path("leaderboards/s/b/records")]
    assert reference_dirs("s", [suite / "b" / "records"]) == [suite / "b" / "records"]
    manifest.write_text('records = ["records", "c/records"]\n')
    with pytest.raises(ConfigError, match=r"^leaderboards/s/reference.toml lists reference "
                       r"records folder leaderboards/s/c/records, which does not exist; fix "
                       r"the list or restore the folder$"):
        reference_dirs("s")
    for bad in ('records = "records"\n', "folders = []\n", "records = [\n"):
        manifest.write_text(bad)
        with pytest.raises(ConfigError, match=r"^leaderboards/s/reference.toml"):
            reference_dirs("s")
    with pytest.raises(ConfigError, match=r"^reference records folder nowhere does not exist$"):
        reference_dirs("s", ["nowhere"])


def test_records_of_another_suite_are_refused(finished: tuple[Path, Path, Path],
                                              tmp_path: Path) -> None:
    _, _, lb = finished
    other = tmp_path / "toyother.toml"
    other.write_text(tiny_toy_suite("toyother", ["oracle", "pca"]).replace(
        "random_episodes = 3", "random_episodes = 4"))
    with pytest.raises(ConfigError, match=r"^the records in records folder .* belong to suite "
                       r"'toycheck', not to suite 'toyother' that was asked for; pass --suite "
                       r"toycheck, or the records of suite toyother$"):
        rebuild_leaderboards(other, records=lb / "records", out=tmp_path / "out")
    quick = ROOT / "leaderboards" / "quick" / "records"
    n = len(list(quick.rglob("*.json")))  # every shipped record is a stage of quick
    with pytest.raises(ConfigError, match=rf"belong to suite 'quick' \({n} of their {n} "
                       r"stages\), not to suite 'smoke' that was asked for"):
        rebuild_leaderboards("smoke", records=quick, out=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_suite_whose_every_stage_is_in_a_bigger_suites_records_is_built_from_them(
        caplog: pytest.LogCaptureFixture) -> None:
    """quick holds every stage of its one-task suites: quick's records are enough to rebuild
    the Door-v0 board, so that task's records need not be stored twice."""
    quick = ROOT / "leaderboards" / "quick" / "records"
    records = load_records(quick)
    door = load_suite(ROOT / "leaderboards" / "quick" / "door" / "suite_20k.toml")
    with caplog.at_level(logging.WARNING):
        ours = records_of_suite(records, door, quick)
    assert {r["task"]["name"] for r in ours} == {"Door-v0"}
    # every Door-v0 record of the suite's encoders (quick's Door-v0 records less the zoo's,
    # which joined quick after the Door-v0 board was made)
    theirs = [r for r in records if r["task"]["name"] == "Door-v0"
              and (not r.get("encoder") or r["encoder"]["name"] in door.encoders)]
    assert len(ours) == len(theirs) > 300
    assert f"{len(records) - len(ours)} of the {len(records)} records" in caplog.text
    more_seeds = door.model_copy(update={"name": "quick_door_more",
                                    "seeds": [*door.seeds, max(door.seeds) + 1]})
    with pytest.raises(ConfigError, match=r"belong to suite 'quick'"):  # a stage is missing
        records_of_suite(records, more_seeds, quick)


def test_records_beyond_the_suite_are_left_out_by_count(finished: tuple[Path, Path, Path],
                                                        tmp_path: Path,
                                                        caplog: pytest.LogCaptureFixture) -> None:
    _, _, lb = finished
    fewer = tmp_path / "toyfewer.toml"
    fewer.write_text(tiny_toy_suite("toyfewer", ["oracle"]))
    with caplog.at_level(logging.WARNING):
        rebuild_leaderboards(fewer, records=lb / "records", out=tmp_path / "out")
    assert f"5 of the 12 records in records folder {lb / 'records'} are not stages of suite " \
           "'toyfewer': left out" in caplog.text
    enc = pd.read_csv(tmp_path / "out" / "encoders.csv")
    assert list(enc["encoder"]) == ["oracle"]


def test_a_board_can_leave_its_records_where_they_are(finished: tuple[Path, Path, Path],
                                                      tmp_path: Path) -> None:
    """--no-copy-records: the board is the same, nothing is copied into <out>/records, and
    provenance.json names the folder, which is where a later reader (--agent-run, --longer)
    finds the records."""
    suite, store, lb = finished
    out = rebuild_leaderboards(suite, records=lb / "records", out=tmp_path / "board",
                               copy_records=False)
    assert not (out / "records").exists()
    for table in ("encoders.csv", "metrics.csv", "claims.csv"):
        assert (out / table).read_text() == (lb / table).read_text()
    provenance = json.loads((out / "provenance.json").read_text())
    assert provenance["records_folders"] == [os.path.relpath(lb / "records", out)]
    assert board_records_folders(out) == [(lb / "records").resolve()]
    assert board_records_folders(lb) == [lb / "records"]
    with pytest.raises(ConfigError, match=r"needs --records"):
        rebuild_leaderboards(suite, store=store, out=tmp_path / "b2", copy_records=False)
    assert not (tmp_path / "b2").exists()


def test_two_writes_to_one_board_run_one_after_the_other(finished: tuple[Path, Path, Path],
                                                         tmp_path: Path) -> None:
    """A write waits for the board's lock (another write holding it) and then completes; two
    `repbench leaderboard` processes on one --out both succeed and leave one whole board."""
    import subprocess
    import sys
    import threading

    from repbench.report.leaderboard import BOARD_LOCK, board_lock

    suite, _, lb = finished
    out = tmp_path / "board"
    out.mkdir()
    done = threading.Event()

    def write() -> None:
        rebuild_leaderboards(suite, records=lb / "records", out=out)
        done.set()

    with board_lock(out):
        writer = threading.Thread(target=write)
        writer.start()
        assert not done.wait(3.0)  # blocked while the lock is held
        assert not (out / "index.html").exists()
    writer.join(120)
    assert done.is_set() and (out / "index.html").is_file() and (out / BOARD_LOCK).exists()

    both = tmp_path / "both"
    cmd = [sys.executable, "-m", "repbench.cli", "leaderboard", "--suite", str(suite),
           "--records", str(lb / "records"), "--out", str(both)]
    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    results = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [err for _, err in results]
    written = sorted(p.relative_to(both / "records") for p in (both / "records").rglob("*.json"))
    assert written == sorted(p.relative_to(lb / "records")
                             for p in (lb / "records").rglob("*.json"))
    assert not list(both.rglob("*.tmp"))
    assert (both / "encoders.csv").read_text() == (lb / "encoders.csv").read_text()
