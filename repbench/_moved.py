"""Import paths of modules that moved into ``repbench.pipeline``, ``repbench.analysis`` and
``repbench.report`` keep working: ``import repbench.store`` gives ``repbench.pipeline.store``
(the same module object) with a :class:`DeprecationWarning` naming the new path.

``repbench.records`` is no such path any more: the record format moved back down to it (the
real module :mod:`repbench.records`; ``repbench.pipeline.records`` re-exports it)."""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType

#: old module name (under ``repbench.``) → its subpackage
MOVED: dict[str, str] = {
    **dict.fromkeys(["suite", "plan", "stages", "store", "executors", "runner", "preflight",
                     "diskfull", "evaluate"], "pipeline"),
    **dict.fromkeys(["results", "correlation", "claims", "calibration"], "analysis"),
    **dict.fromkeys(["leaderboard", "figures", "report_html"], "report"),
}


class _MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Resolves ``repbench.<old>`` to ``repbench.<subpackage>.<old>``."""

    def find_spec(self, fullname: str, path: object = None,
                  target: object = None) -> importlib.machinery.ModuleSpec | None:
        prefix, _, name = fullname.partition(".")
        if prefix != "repbench" or name not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        name = spec.name.partition(".")[2]
        new = f"repbench.{MOVED[name]}.{name}"
        warnings.warn(f"{spec.name} moved to {new}; import it from there", DeprecationWarning,
                      stacklevel=2)
        module = importlib.import_module(new)
        sys.modules[spec.name] = module
        return module

    def exec_module(self, module: ModuleType) -> None:
        """The module is the already-executed new one."""


def install() -> None:
    """Put the finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _MovedModuleFinder) for f in sys.meta_path):
        sys.meta_path.append(_MovedModuleFinder())
