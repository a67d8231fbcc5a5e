"""The command line: listing, help, and one-line errors with exit code 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest


def _repbench(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "repbench.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=300)


def test_list_encoders_with_descriptions() -> None:
    out = _repbench("list", "encoders")
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == "encoders:"
    vae = next(line for line in lines if line.split()[0] == "vae")
    assert len(vae.split()) > 1  # has a description
    assert "cannot load" not in out.stdout


def test_list_tasks_says_what_each_task_senses() -> None:
    """The three contact-rich tasks list their wrist camera and F/T sensor (from their configs'
    defaults); the toy task, which does not say, lists its description alone."""
    out = _repbench("list", "tasks")
    assert out.returncode == 0, out.stderr
    lines = {line.split()[0]: line for line in out.stdout.splitlines()[1:]}
    for task in ("PegInHole-v0", "SurfacePress-v0", "Door-v0"):
        assert lines[task].endswith(
            "Sensors: 64x64 wrist RGB, 6-axis wrist F/T (10 Hz low-pass), proprioception."), task
    assert "Sensors" not in lines["ToyReach-v0"] and "cannot load" not in out.stdout


def test_help_explains_every_command() -> None:
    out = _repbench("--help")
    assert out.returncode == 0
    for cmd in ("list", "doctor", "run", "leaderboard", "task"):
        assert cmd in out.stdout


@pytest.mark.parametrize("args, match", [
    (("list", "encodr"), "unknown plugin kind 'encodr'"),
    (("run", "--suite", "no_such_suite"), "neither a built-in suite"),
    (("leaderboard", "--suite", "smoke", "--store", "/dev/null/x"), "is not writable"),
])
def test_user_errors_are_one_line_exit_2(args: tuple[str, ...], match: str) -> None:
    out = _repbench(*args)
    assert out.returncode == 2
    assert match in out.stderr
    assert "Traceback" not in out.stderr and len(out.stderr.strip().splitlines()) == 1


def test_doctor_renders() -> None:
    out = _repbench("doctor")
    assert "64x64 offscreen render ok" in out.stdout, out.stdout + out.stderr
    assert out.returncode == 0


def test_task_preview_writes_a_contact_sheet(tmp_path: Path) -> None:
    out = _repbench("task", "preview", "PegInHole-v0", "--frames", "4", "--out",
                    str(tmp_path / "p.png"))
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "p.png").stat().st_size > 5_000
    assert "WARNING" not in out.stderr  # robosuite's harmless import warnings are filtered


def test_doctor_install_line_fits_root_and_sudo() -> None:
    from repbench.doctor import apt_install_line

    assert apt_install_line(["libegl1"], is_root=True) == (
        "apt-get update && apt-get install -y libegl1")
    assert apt_install_line(["libegl1", "chromium"], is_root=False, sudo="/usr/bin/sudo") == (
        "sudo apt-get update && sudo apt-get install -y libegl1 chromium")
