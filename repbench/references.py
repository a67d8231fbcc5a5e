"""Lazy plugin references: ``"package.module:Name"`` or ``"path/to/file.py:Name"`` strings,
imported on first use.

The lowest layer of the plugin machinery: the registry and :meth:`repbench.Encoder.load` both
resolve references here, so neither has to import the other. A reference is self-describing, so
any process (a pool worker, a Ray worker with the same files) resolves it the same way: that is
what lets ``repbench run`` and ``repbench evaluate`` take an encoder written in one plain ``.py``
file, without packaging it.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

from repbench.errors import PluginError

#: attribute set on a module loaded from a file: its absolute path
FILE_ATTRIBUTE = "__repbench_file__"


def is_reference(text: str) -> bool:
    """Whether ``text`` is a reference (``module:Name`` or ``file.py:Name``) rather than a
    registered name."""
    module, sep, attr = text.rpartition(":")
    return bool(sep and module and attr)


def _is_file(module_part: str) -> bool:
    return module_part.endswith(".py") or "/" in module_part or os.sep in module_part


def import_reference(reference: str) -> Any:
    """Import ``"package.module:Attribute"`` or ``"path/to/file.py:Attribute"`` (the attribute
    may be dotted; a relative path is relative to the working directory) and return it."""
    module_name, sep, attr_path = reference.rpartition(":")
    if not sep or not module_name or not attr_path:
        raise PluginError(f"bad plugin reference {reference!r}: write it as 'package.module:Name' "
                          "or 'path/to/file.py:Name'")
    obj: Any = (load_file_module(module_name, reference) if _is_file(module_name)
                else _import_module(module_name, reference))
    for part in attr_path.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise PluginError(f"{module_name!r} has no attribute {attr_path!r} (plugin reference "
                              f"{reference!r})") from None
    return obj


def _import_module(module_name: str, reference: str) -> ModuleType:
    """Import ``module_name``; a module beside the working directory is found too (the working
    directory is put at the end of ``sys.path`` when the first try does not find it)."""
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        cwd = os.getcwd()
        top = module_name.split(".")[0]
        if exc.name != top or cwd in sys.path or not (
                Path(cwd, top).is_dir() or Path(cwd, f"{top}.py").is_file()):
            raise _cannot_import(module_name, reference, exc) from exc
        sys.path.append(cwd)
        try:
            return importlib.import_module(module_name)
        except ImportError as exc2:
            raise _cannot_import(module_name, reference, exc2) from exc2
    except ImportError as exc:
        raise _cannot_import(module_name, reference, exc) from exc


def _cannot_import(module_name: str, reference: str, exc: Exception) -> PluginError:
    return PluginError(f"cannot import module {module_name!r} for plugin reference "
                       f"{reference!r}: {exc}; is the package installed?")


def load_file_module(path: str | os.PathLike[str], reference: str | None = None) -> ModuleType:
    """The module of the Python file ``path``, executed once per process (cached in
    ``sys.modules`` under a name derived from its absolute path)."""
    shown = reference or str(path)
    file = Path(path).expanduser()
    if not file.is_absolute():
        file = Path.cwd() / file
    file = file.resolve()
    if not file.is_file():
        raise PluginError(f"plugin file {str(path)!r} of {shown!r} does not exist (looked for "
                          f"{file}); give the path to the .py file, relative to the working "
                          "directory or absolute")
    stem = "".join(c if c.isalnum() else "_" for c in file.stem)
    name = f"repbench_file_{stem}_{hashlib.sha1(str(file).encode()).hexdigest()[:10]}"
    cached = sys.modules.get(name)
    if cached is not None:
        return cached
    spec = importlib.util.spec_from_file_location(name, file)
    if spec is None or spec.loader is None:
        raise PluginError(f"{file} of {shown!r} cannot be imported as a Python file")
    module = importlib.util.module_from_spec(spec)
    setattr(module, FILE_ATTRIBUTE, str(file))
    sys.modules[name] = module  # before executing: dataclasses and pickle look it up
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        del sys.modules[name]
        raise PluginError(f"importing {file} (plugin reference {shown!r}) failed: "
                          f"{type(exc).__name__}: {exc}") from exc
    return module


def reference_of(obj: Any) -> str:
    """The reference that imports ``obj`` (a class or function) again in a fresh process: its
    file's absolute path when it was loaded from a file, else its module."""
    module = sys.modules.get(obj.__module__)
    file = getattr(module, FILE_ATTRIBUTE, None)
    return f"{file or obj.__module__}:{obj.__qualname__}"


def source_digest(obj: Any) -> str | None:
    """SHA-256 of the file ``obj`` was loaded from by a file reference (None otherwise): stage
    keys carry it, so editing the file recomputes what depends on it."""
    module = sys.modules.get(getattr(obj, "__module__", ""))
    file = getattr(module, FILE_ATTRIBUTE, None)
    return hashlib.sha256(Path(file).read_bytes()).hexdigest() if file else None
