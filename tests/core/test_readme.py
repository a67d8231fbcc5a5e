"""README's promises: the encoder example runs, and CI runs README's test command."""

from __future__ import annotations

import re
from pathlib import Path

from repbench.registry import encoders

ROOT = Path(__file__).resolve().parents[2]


def test_readme_register_example_runs() -> None:
    text = (ROOT / "README.md").read_text()
    block = re.search(r"<!-- readme-example: start -->\s*```python\n(.*?)```", text, re.S)
    assert block is not None, "README lost its encoder example"
    try:
        exec(compile(block.group(1), "README.md", "exec"), {})
        assert "mean_colour" in encoders.names()
    finally:
        encoders.unregister("mean_colour")


def test_ci_runs_readmes_test_command() -> None:
    readme = (ROOT / "README.md").read_text()
    commands = re.findall(r"```bash\n(.*?)\n```", readme, re.S)
    test_cmd = next(c for c in commands if "pytest" in c)
    final = test_cmd.split("&&")[-1].strip()
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert final in [line.strip() for line in ci], f"CI must run {final!r}"


def test_readme_is_short_and_cites_no_issue_numbers() -> None:
    """A newcomer reads README in a minute; the research log with its issue numbers lives in
    ``docs/``."""
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 200, f"README has {len(lines)} lines; move detail to docs/"
    cited = [f"{n}: {line}" for n, line in enumerate(lines, 1)
             if re.search(r"[Ii]ssue \d+|#\d+", line)]
    assert not cited, "README cites issue numbers:\n" + "\n".join(cited)
