"""The command line names every record it leaves out."""

from __future__ import annotations

import json

from repbench.runner import run_suite

from ..runner.tiny_toy_suite import tiny_toy_suite
from .conftest import Cli


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

