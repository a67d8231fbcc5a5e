"""The documentation site builds strictly, and its code examples run."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from repbench.registry import encoders, metrics

ROOT = Path(__file__).resolve().parents[2]
_TOOLS = ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers.python")


def _missing_tools() -> list[str]:
    missing = []
    for name in _TOOLS:
        try:
            found = importlib.util.find_spec(name) is not None
        except ModuleNotFoundError:  # a parent package is absent
            found = False
        if not found:
            missing.append(name)
    return missing


def test_docs_build_strictly(tmp_path: Path) -> None:
    """``mkdocs build --strict``: a broken link, a page left out of the nav or a docstring
    griffe cannot parse fails the build (a few seconds)."""
    missing = _missing_tools()
    if missing:
        pytest.skip(f"docs tools not installed ({', '.join(missing)}): pip install -e '.[test]'")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    out = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
         "-d", str(tmp_path / "site")],
        capture_output=True, text=True, cwd=ROOT, env=env, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    api = (tmp_path / "site" / "api" / "index.html").read_text()
    assert 'id="repbench.encoder.Encoder"' in api and 'id="repbench.registry.Registry"' in api


def test_extending_examples_run() -> None:
    """The encoder and metric examples of docs/extending.md pass the conformance kit."""
    text = (ROOT / "docs" / "extending.md").read_text()
    blocks = [b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "check_" in b]
    assert len(blocks) == 2, "docs/extending.md lost its encoder or metric example"
    try:
        for block in blocks:
            exec(compile(block, "docs/extending.md", "exec"), {})
        assert "mean_colour" in encoders.names() and "linear_r2" in metrics.names()
    finally:
        encoders.unregister("mean_colour")
        metrics.unregister("linear_r2")
