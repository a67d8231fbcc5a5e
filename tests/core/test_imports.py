"""The core's import graph has no circle: each module imports alone, and no chain of imports
(module-level or inside functions) leads from a module back to itself."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "repbench"

#: The core layer, bottom to top.
CORE = ["errors", "references", "dataset", "devices", "encoder", "task", "agent", "metric_types",
        "registry", "metric", "gym_envs", "provenance", "records", "pipeline.store",
        "pipeline.suite", "pipeline.stages", "pipeline.plan", "pipeline.executors",
        "analysis.correlation", "analysis.results", "report.leaderboard", "pipeline.runner", "cli"]


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _imports(path: Path, known: set[str]) -> set[str]:
    """repbench modules imported anywhere in ``path`` (top level and inside functions)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                found.add(sub if sub in known else node.module)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {m for m in found if m in known and m != "repbench"}


def _imported_names(path: Path) -> list[tuple[ast.stmt, list[str]]]:
    """Every import statement in ``path`` (top level and inside functions) with the modules it
    may import: for ``from X import a`` both ``X`` and ``X.a`` (``a`` may be a submodule),
    relative imports resolved, and an old path that ``repbench._moved`` redirects
    (``repbench.store``) named by the module it gives (``repbench.pipeline.store``)."""
    from repbench._moved import MOVED

    package = list(path.relative_to(PACKAGE.parent).with_suffix("").parts[:-1])
    out: list[tuple[ast.stmt, list[str]]] = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            module = ".".join([*base, *(node.module or "").split(".")]).strip(".")
            names = [module, *(f"{module}.{alias.name}" for alias in node.names)]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            continue
        for i, name in enumerate(names):
            head, _, rest = name.partition(".")
            old, _, tail = rest.partition(".")
            if head == "repbench" and old in MOVED:
                names[i] = ".".join(filter(None, ["repbench", MOVED[old], old, tail]))
        out.append((node, names))
    return out


def _imports_from(files: list[Path], banned: tuple[str, ...]) -> list[str]:
    """``<file>:<line>: <import statement>`` for every import in ``files`` of a module in (or
    under) one of the packages ``banned``."""
    return [f"{path.relative_to(PACKAGE.parent)}:{node.lineno}: {ast.unparse(node)}"
            for path in files for node, names in _imported_names(path)
            if any(n == b or n.startswith(f"{b}.") for n in names for b in banned)]


#: Modules below both the pipeline and the analysis: the record format and the reading of
#: records, and the provenance a record carries.
RECORD_CORE = ["records.py", "provenance.py"]


def test_analysis_never_imports_the_pipeline() -> None:
    """The flow is one way: the pipeline writes records and uses the analysis; the analysis
    reads records (:mod:`repbench.records`) and imports nothing of ``repbench.pipeline``, at
    top level or inside a function."""
    files = sorted((PACKAGE / "analysis").rglob("*.py"))
    assert files
    found = _imports_from(files, ("repbench.pipeline",))
    assert not found, "repbench/analysis imports the pipeline:\n" + "\n".join(found)


def test_record_core_imports_no_upper_layer() -> None:
    """:mod:`repbench.records` and :mod:`repbench.provenance` lie below the pipeline, the
    analysis and the report: they import none of them."""
    files = [PACKAGE / name for name in RECORD_CORE]
    found = _imports_from(files, ("repbench.pipeline", "repbench.analysis", "repbench.report"))
    assert not found, "the record core imports an upper layer:\n" + "\n".join(found)


def test_no_import_cycle_in_the_package() -> None:
    mods = _modules()
    known = set(mods)
    graph = {m: _imports(p, known) - {m} for m, p in mods.items() if m != "repbench"}
    state: dict[str, int] = {}  # 1 = on the current path, 2 = done

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for dep in sorted(graph.get(m, ())):
            if state.get(dep) == 1:
                cycle = [*path[path.index(dep):], dep] if dep in path else [m, dep]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if dep not in state:
                visit(dep, [*path, dep])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])


def test_registry_imports_the_plugin_bases_at_top_level() -> None:
    tree = ast.parse((PACKAGE / "registry.py").read_text())
    top = {n.module for n in tree.body if isinstance(n, ast.ImportFrom)}
    assert {"repbench.encoder", "repbench.task", "repbench.agent",
            "repbench.metric_types"} <= top
    nested = [n for f in ast.walk(tree) if isinstance(f, ast.FunctionDef)
              for n in ast.walk(f) if isinstance(n, (ast.Import, ast.ImportFrom))]
    assert not nested, "registry.py imports inside functions"


@pytest.mark.parametrize("module", CORE)
def test_each_core_module_imports_alone(module: str) -> None:
    out = subprocess.run([sys.executable, "-c", f"import repbench.{module}"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr


@pytest.mark.parametrize(("old", "new"), [("store", "pipeline.store"),
                                          ("results", "analysis.results"),
                                          ("leaderboard", "report.leaderboard")])
def test_moved_module_imports_from_its_old_path_with_a_warning(old: str, new: str) -> None:
    """``repbench.<module>`` moved into a subpackage: the old path gives the same module, and a
    DeprecationWarning names the new one."""
    code = (f"import warnings; warnings.simplefilter('error'); import repbench\n"
            f"try:\n    import repbench.{old}\nexcept DeprecationWarning as w:\n    print(w)\n"
            f"warnings.simplefilter('ignore')\nimport repbench.{old} as a, repbench.{new} as b\n"
            f"print(a is b)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == [f"repbench.{old} moved to repbench.{new}; import it from "
                                       "there", "True"]
