"""Process-level fault tests: a tiny ToyReach suite run by the real ``repbench`` command in a
subprocess, with test metrics (``faultplug.py``) installed through entry points."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from ..runner.tiny_toy_suite import tiny_toy_suite

HERE = Path(__file__).resolve().parent
ENTRY_POINTS = """[repbench.metrics]
fault_mlp = faultplug:fault_mlp
fault_threads = faultplug:fault_threads
"""


@pytest.fixture(scope="session")
def plugin_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder that, on PYTHONPATH, installs ``faultplug`` as a repbench metrics plugin."""
    path = tmp_path_factory.mktemp("faultplug")
    shutil.copy(HERE / "faultplug.py", path / "faultplug.py")
    info = path / "faultplug-0.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: faultplug\nVersion: 0.0\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)
    return path


def fault_suite(name: str, metrics: list[str], *, encoders: tuple[str, ...] = ("oracle",),
                epochs: int = 4000) -> str:
    """The tiny ToyReach suite with ``metrics`` (and ``fault_mlp`` training ``epochs``)."""
    text = tiny_toy_suite(name, list(encoders)).replace(
        'metrics = ["ksg", "regression"]', f"metrics = {json.dumps(metrics)}")
    if "fault_mlp" in metrics:
        text += f"[metric_params.fault_mlp]\nepochs = {epochs}\n"
    return text


def _default_sigint() -> None:
    """In the child before exec: SIGINT back to its default. A pytest started in the
    background of a non-interactive shell (``cmd &``) inherits SIGINT ignored, and an ignored
    SIGINT stays ignored across exec, so the Ctrl-C tests would send a signal nobody gets."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@dataclass
class Cli:
    """Runs ``repbench`` in a subprocess with the fault plugins installed."""

    env: dict[str, str]
    cwd: Path
    log: Path

    def cmd(self, *args: str) -> list[str]:
        return [sys.executable, "-m", "repbench.cli", *args]

    def start(self, *args: str, name: str = "run") -> subprocess.Popen[bytes]:
        """Start ``repbench ARGS``; stdout and stderr go to ``<cwd>/<name>.out|.err``."""
        out = open(self.cwd / f"{name}.out", "wb")  # noqa: SIM115 (closed by the process)
        err = open(self.cwd / f"{name}.err", "wb")  # noqa: SIM115
        try:
            return subprocess.Popen(self.cmd(*args), cwd=self.cwd, env=self.env, stdout=out,
                                    stderr=err, start_new_session=True,
                                    preexec_fn=_default_sigint)
        finally:
            out.close()
            err.close()

    def run(self, *args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
        return subprocess.run(self.cmd(*args), cwd=self.cwd, env=self.env, capture_output=True,
                              text=True, timeout=timeout)

    def output(self, name: str = "run") -> tuple[str, str]:
        return ((self.cwd / f"{name}.out").read_text(errors="replace"),
                (self.cwd / f"{name}.err").read_text(errors="replace"))

    def events(self) -> list[dict]:
        if not self.log.is_file():
            return []
        return [json.loads(line) for line in self.log.read_text().splitlines() if line.strip()]

    def wait_for(self, event: str, metric: str, proc: subprocess.Popen[bytes] | None = None,
                 timeout: float = 120) -> dict:
        """The first ``event`` line of ``metric`` in the log, waiting for it."""
        deadline = time.time() + timeout
        while time.time() < deadline:
            for e in self.events():
                if e["event"] == event and e["metric"] == metric:
                    return e
            if proc is not None and proc.poll() is not None:
                raise AssertionError(f"repbench exited ({proc.returncode}) before {metric} "
                                     f"{event}: {self.output()}")
            time.sleep(0.05)
        raise AssertionError(f"no {event} of {metric} within {timeout} s")


@pytest.fixture
def cli(plugin_path: Path, tmp_path: Path) -> Iterator[Cli]:
    """A :class:`Cli` whose working directory is ``tmp_path`` (not the repbench checkout)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(plugin_path), *filter(None, [env.get("PYTHONPATH")])])
    env["FAULTS_LOG"] = str(tmp_path / "events.jsonl")
    env["PYTHONUNBUFFERED"] = "1"
    env.pop("REPBENCH_STORE", None)
    yield Cli(env, tmp_path, tmp_path / "events.jsonl")


def children_of(pid: int) -> list[int]:
    """Process ids whose parent is ``pid`` (Linux /proc)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def alive(pid: int) -> bool:
    """True while ``pid`` exists and is not a zombie."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"
