"""Provenance of a result: the library versions, the CPU and the git commit of the code that
made it. Stage artifacts (``meta.json``, :mod:`repbench.pipeline.store`) and result records
(:mod:`repbench.records`) both carry them."""

from __future__ import annotations

import contextlib
import functools
import os
import platform
import subprocess
from pathlib import Path


@functools.lru_cache(maxsize=1)
def library_versions() -> dict[str, str]:
    """Versions of the libraries that shape results."""
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version()}
    for dist in ("repbench", "numpy", "torch", "scipy", "scikit-learn", "pandas", "mujoco",
                 "robosuite", "gymnasium", "stable-baselines3"):
        with contextlib.suppress(PackageNotFoundError):
            out[dist] = version(dist)
    return out


@functools.lru_cache(maxsize=1)
def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``'s ``model name``, else
    :func:`platform.processor`, else the machine type). Float results of one code and one set of
    library versions can differ across CPUs (torch and numpy pick kernels by instruction set),
    so every record says which CPU made it; it is no library version and is kept apart."""
    with contextlib.suppress(OSError), open("/proc/cpuinfo") as f:
        for line in f:
            name, sep, value = line.partition(":")
            if sep and value.strip() and name.strip() in ("model name", "Model", "Processor",
                                                          "cpu model"):
                return " ".join(value.split())
    return platform.processor() or platform.machine() or "unknown"


@functools.lru_cache(maxsize=1)
def git_commit() -> str | None:
    """The git commit of the repbench code that runs: HEAD of the checkout the installed
    ``repbench`` package lives in (a source tree or an editable install); None when it lives in
    none (installed from a wheel). Never the commit of the folder the command runs in."""
    return source_commit(Path(__file__).resolve().parent)


def source_commit(package_dir: Path) -> str | None:
    """HEAD of the git checkout that tracks ``package_dir/__init__.py``; None when no checkout
    does (not a checkout, or an untracked folder inside someone else's, like a virtual
    environment's site-packages inside a user's project)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("GIT_")}

    def git(*args: str) -> str | None:
        try:
            out = subprocess.run(["git", "-C", str(package_dir), *args], capture_output=True,
                                 text=True, timeout=5, check=False, env=env)
        except (OSError, subprocess.SubprocessError):
            return None
        return out.stdout.strip() or None if out.returncode == 0 else None

    if git("ls-files", "--error-unmatch", "--", "__init__.py") is None:
        return None
    return git("rev-parse", "HEAD")
