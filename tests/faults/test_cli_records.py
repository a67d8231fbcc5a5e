"""The command line names every record it leaves out, and refuses records of another suite."""

from __future__ import annotations

import json
from pathlib import Path

from repbench.pipeline.runner import run_suite

from ..runner.tiny_toy_suite import tiny_toy_suite
from .conftest import Cli

ROOT = Path(__file__).resolve().parents[2]


def test_leaderboard_prints_a_line_per_record_left_out(cli: Cli) -> None:
    suite = cli.cwd / "toycli.toml"
    suite.write_text(tiny_toy_suite("toycli", ["oracle"]))
    run_suite(suite, store=cli.cwd / "store", out=cli.cwd / "lb", workers=1, progress=False)
    folder = cli.cwd / "lb" / "records"
    tampered = next((folder / "metric").glob("*.ksg-*.json"))
    record = json.loads(tampered.read_text())
    record["values"]["value"] = record["values"]["ci_high"] + 1.0
    tampered.write_text(json.dumps(record, indent=1, sort_keys=True))
    truncated = next((folder / "rl").glob("*.json"))
    truncated.write_text(truncated.read_text()[:100])
    proc = cli.run("leaderboard", "--suite", str(suite), "--records", str(folder), "--out",
                   str(cli.cwd / "out"))
    assert proc.returncode == 0, proc.stderr
    assert sorted(line for line in proc.stderr.splitlines() if "left out" in line) == sorted([
        f"record {tampered} fails its checksum (edited or corrupt): left out; rerun the stage "
        "with `repbench run`",
        f"record {truncated} is not valid JSON (truncated or corrupt): left out; rerun the "
        "stage with `repbench run`"])
    assert "Traceback" not in proc.stderr


def test_records_of_another_suite_exit_2_with_one_line(cli: Cli) -> None:
    quick = ROOT / "leaderboards" / "quick" / "records"
    n = len(list(quick.rglob("*.json")))  # every shipped record is a stage of quick
    proc = cli.run("leaderboard", "--suite", "smoke", "--records", str(quick), "--out",
                   str(cli.cwd / "out"))
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.splitlines() == [
        f"repbench: error: the records in records folder {quick} belong to suite 'quick' ({n} "
        f"of their {n} stages), not to suite 'smoke' that was asked for; pass --suite quick, or "
        "the records of suite smoke"]
    assert not (cli.cwd / "out").exists()
    smoke = ROOT / "leaderboards" / "smoke" / "records"
    proc = cli.run("evaluate", "pca", "--suite", "quick", "--metrics-only", "--reference",
                   str(smoke), "--store", str(cli.cwd / "store"), "--out", str(cli.cwd / "ev"))
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.splitlines() == [
        f"repbench: error: the records in reference records folder {smoke} belong to suite "
        "'smoke' (125 of their 125 stages), not to suite 'quick' that was asked for; pass "
        "--suite smoke, or the records of suite quick"]
    assert not (cli.cwd / "store").exists()
