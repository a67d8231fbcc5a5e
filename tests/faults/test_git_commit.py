"""Records carry the git commit of the repbench code that made them, not of the folder the
command runs in."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import repbench
from repbench.pipeline.store import source_commit

PACKAGE = Path(repbench.__file__).resolve().parent
_WRITE = """
import json, sys
from repbench.pipeline.records import make_record
from repbench.pipeline.store import Store, git_commit
store = Store(sys.argv[1])
with store.write("stage", "k", config={}) as w:
    w.write_json({"ok": True})
record = make_record({"kind": "metric"}, {}, stage={}, timings={})
print(json.dumps([git_commit(), store.get("stage", "k").meta["git_commit"],
                  record["git_commit"]]))
"""


def _git(cwd: Path, *args: str) -> str:
    return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@example.org", *args],
                          cwd=cwd, capture_output=True, text=True, check=True).stdout.strip()


def _user_project(path: Path) -> str:
    """A git repository of someone else's project, with one commit; returns its HEAD."""
    path.mkdir()
    _git(path, "init", "-q")
    (path / "notes.txt").write_text("my project")
    _git(path, "add", "notes.txt")
    _git(path, "commit", "-qm", "mine")
    return _git(path, "rev-parse", "HEAD")


def test_records_carry_repbench_commit_whatever_the_working_directory(tmp_path: Path) -> None:
    ours = _git(PACKAGE, "rev-parse", "HEAD")
    theirs = _user_project(tmp_path / "project")
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    for cwd in (tmp_path / "project", outside):
        proc = subprocess.run([sys.executable, "-c", _WRITE, str(tmp_path / f"st-{cwd.name}")],
                              cwd=cwd, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
        assert json.loads(proc.stdout) == [ours] * 3, (cwd, theirs)


def test_no_commit_outside_a_repbench_checkout(tmp_path: Path) -> None:
    wheel = tmp_path / "site-packages" / "repbench"  # installed from a wheel
    wheel.mkdir(parents=True)
    (wheel / "__init__.py").write_text("")
    assert source_commit(wheel) is None
    _user_project(tmp_path / "project")  # a virtual environment inside a user's project
    venv = tmp_path / "project" / ".venv" / "site-packages" / "repbench"
    venv.mkdir(parents=True)
    (venv / "__init__.py").write_text("")
    assert source_commit(venv) is None
    assert source_commit(PACKAGE) == _git(PACKAGE, "rev-parse", "HEAD")
