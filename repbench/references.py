"""Lazy plugin references: ``"package.module:Name"`` strings imported on first use.

The lowest layer of the plugin machinery: the registry and :meth:`repbench.Encoder.load` both
resolve references here, so neither has to import the other.
"""

from __future__ import annotations

import importlib
from typing import Any

from repbench.errors import PluginError


def import_reference(reference: str) -> Any:
    """Import ``"package.module:Attribute"`` (the attribute may be dotted) and return it."""
    module_name, sep, attr_path = reference.partition(":")
    if not sep or not module_name or not attr_path:
        raise PluginError(
            f"bad plugin reference {reference!r}: write it as 'package.module:Name'"
        )
    try:
        obj: Any = importlib.import_module(module_name)
    except ImportError as exc:
        raise PluginError(
            f"cannot import module {module_name!r} for plugin reference {reference!r}: {exc}; "
            "is the package installed?"
        ) from exc
    for part in attr_path.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise PluginError(
                f"module {module_name!r} has no attribute {attr_path!r} "
                f"(plugin reference {reference!r})"
            ) from None
    return obj
