"""One generic plugin registry serving the four kinds: tasks, encoders, metrics and agents.

Plugins arrive three ways, all ending in the same table:

* a decorator, ``@encoders.register("my_vae")``, on a class or function;
* a lazy reference, ``encoders.register("my_vae", "my_pkg.models:MyVAE")``, imported on first use;
* an entry point in the group ``repbench.<kind>`` of any installed distribution (repbench's own
  built-in plugins are found this way too), discovered on first lookup;
* a reference used as the name, ``encoders.get("my_encoder.py:MyVAE")`` (or
  ``"my_pkg.models:MyVAE"``): registered under that name on first lookup, in every process that
  looks it up, so a plugin in a plain file works in suites, worker processes and records.

Unknown names get close matches and the list of known names; duplicates are rejected; every
loaded plugin is checked against its kind's base (``Registry("encoder", base=Encoder)``).

The bases are imported at the top: :mod:`repbench.encoder`, :mod:`repbench.task`,
:mod:`repbench.agent` and :mod:`repbench.metric_types` never import this module, so the import
graph has no circle (``tests/core/test_imports.py``). The ``@repbench.metric`` decorator, which
registers, lives above it in :mod:`repbench.metric`.
"""

from __future__ import annotations

import difflib
import inspect
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any, Generic, TypeVar

from repbench.agent import Agent
from repbench.encoder import Encoder
from repbench.errors import PluginError
from repbench.metric_types import Metric
from repbench.references import import_reference, is_reference
from repbench.task import Task

T = TypeVar("T")

ENTRY_POINT_GROUPS = {
    "task": "repbench.tasks",
    "encoder": "repbench.encoders",
    "metric": "repbench.metrics",
    "agent": "repbench.agents",
}


@dataclass
class _Entry:
    name: str
    target: Any = None  # the loaded object, once loaded
    reference: str | None = None  # "pkg.mod:Name" while not yet loaded
    source: str = "decorator"  # "decorator", "reference" or "entry point <dist>"
    metadata: dict[str, Any] = field(default_factory=dict)


class Registry(Generic[T]):
    """A name → plugin table for one kind of plugin.

    Args:
        kind: singular noun used in messages ("encoder").
        entry_point_group: the ``importlib.metadata`` group discovered on first lookup.
        check: optional validator called on every loaded plugin; raise ``TypeError`` with a
            message to reject it.
        base: the class every plugin must be (a subclass of, for classes; an instance of,
            for objects such as :class:`~repbench.metric_types.Metric`).
        hint: what to do when a plugin is not a ``base`` (appended to the rejection).
    """

    def __init__(
        self,
        kind: str,
        entry_point_group: str | None = None,
        check: Callable[[str, Any], None] | None = None,
        *,
        base: type | None = None,
        hint: str = "",
    ) -> None:
        self.kind = kind
        self.entry_point_group = entry_point_group
        self.base = base
        self._hint = hint
        self._check = check
        self._entries: dict[str, _Entry] = {}
        self._discovered = False

    # -- registration -------------------------------------------------------------------------
    def register(
        self, name: str, target: Any = None, *, replace: bool = False, **metadata: Any
    ) -> Any:
        """Register ``target`` under ``name``; without ``target``, return a decorator.

        ``target`` may be the object itself or a lazy ``"package.module:Name"`` string.
        Extra keyword arguments are stored as metadata (e.g. ``description=``).
        """
        if target is None:

            def decorator(obj: Any) -> Any:
                self.register(name, obj, replace=replace, **metadata)
                return obj

            return decorator
        if not isinstance(name, str) or not name:
            raise PluginError(f"{self.kind} name must be a non-empty string, got {name!r}")
        if isinstance(target, str):
            entry = _Entry(name, reference=target, source="reference", metadata=metadata)
        else:
            self._validate(name, target)
            entry = _Entry(name, target=target, metadata=metadata)
        self._add(entry, replace=replace)
        return target

    def unregister(self, name: str) -> None:
        """Remove ``name`` (mainly for tests and interactive sessions)."""
        self._entries.pop(name, None)

    def _add(self, entry: _Entry, *, replace: bool) -> None:
        existing = self._entries.get(entry.name)
        if existing is not None and not replace:
            if _same_plugin(existing, entry):
                return  # the same plugin seen twice (e.g. editable + entry point): harmless
            raise PluginError(
                f"duplicate {self.kind} name {entry.name!r}: already registered from "
                f"{existing.source} ({_describe_target(existing)}); pick another name or pass "
                "replace=True"
            )
        self._entries[entry.name] = entry

    def _validate(self, name: str, obj: Any) -> None:
        try:
            if self.base is not None and not _is_a(obj, self.base):
                raise TypeError(f"expected {_kind_of(self.base)} repbench.{self.base.__name__}"
                                f"{self._hint}, got {obj!r}")
            if self._check is not None:
                self._check(name, obj)
        except TypeError as exc:
            raise PluginError(f"{self.kind} {name!r} rejected: {exc}") from None

    # -- discovery ----------------------------------------------------------------------------
    def discover(self, *, force: bool = False) -> None:
        """Read the entry-point group (once, or again with ``force``)."""
        if (self._discovered and not force) or self.entry_point_group is None:
            return
        self._discovered = True
        for ep in entry_points(group=self.entry_point_group):
            dist = getattr(ep, "dist", None)
            dist_name = dist.metadata["Name"] if dist is not None else "?"
            entry = _Entry(ep.name, reference=ep.value, source=f"entry point of {dist_name}")
            self._add(entry, replace=False)

    # -- lookup ---------------------------------------------------------------------------------
    def get(self, name: str) -> T:
        """Return the plugin registered as ``name``, importing it if needed."""
        self.discover()
        entry = self._entries.get(name)
        if entry is None and isinstance(name, str) and is_reference(name):
            entry = _Entry(name, reference=name, source="reference given as the name")
            self._entries[name] = entry
        if entry is None:
            raise PluginError(self._unknown_message(name))
        if entry.target is None:
            assert entry.reference is not None
            try:
                obj = import_reference(entry.reference)
                self._validate(name, obj)
            except PluginError:
                if entry.source == "reference given as the name":
                    del self._entries[name]  # a typo is not left registered
                raise
            entry.target = obj
        return entry.target  # type: ignore[no-any-return]

    def metadata(self, name: str) -> dict[str, Any]:
        """Metadata given at registration (``description`` etc.)."""
        self.get(name)
        return dict(self._entries[name].metadata)

    def describe(self, name: str) -> str:
        """One-line description: the ``description`` metadata or the docstring's first line."""
        entry_meta = self.metadata(name)
        if entry_meta.get("description"):
            return str(entry_meta["description"])
        obj = self.get(name)
        if isinstance(getattr(obj, "description", None), str) and obj.description:
            return str(obj.description)
        doc = inspect.getdoc(obj) or ""
        return doc.strip().splitlines()[0] if doc.strip() else ""

    def names(self) -> list[str]:
        """All registered names, sorted."""
        self.discover()
        return sorted(self._entries)

    def __contains__(self, name: object) -> bool:
        self.discover()
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def __len__(self) -> int:
        return len(self.names())

    def _unknown_message(self, name: str) -> str:
        known = self.names()
        close = difflib.get_close_matches(name, known, n=3, cutoff=0.5)
        hint = f"did you mean {' or '.join(repr(c) for c in close)}? " if close else ""
        listing = ", ".join(known) if known else "(none registered)"
        return f"unknown {self.kind} {name!r}; {hint}known: {listing}"


def _describe_target(entry: _Entry) -> str:
    if entry.reference is not None and entry.target is None:
        return entry.reference
    target = entry.target
    return f"{getattr(target, '__module__', '?')}:{getattr(target, '__qualname__', target)!s}"


def _same_plugin(a: _Entry, b: _Entry) -> bool:
    return _describe_target(a) == _describe_target(b)


def _is_a(obj: Any, base: type) -> bool:
    if base is Metric:  # metrics are registered as Metric objects, not classes
        return isinstance(obj, base)
    return inspect.isclass(obj) and issubclass(obj, base)


def _kind_of(base: type) -> str:
    return "a" if base is Metric else "a subclass of"


tasks: Registry[type[Task]] = Registry("task", ENTRY_POINT_GROUPS["task"], base=Task)
encoders: Registry[type[Encoder]] = Registry("encoder", ENTRY_POINT_GROUPS["encoder"],
                                             base=Encoder)
metrics: Registry[Metric] = Registry(
    "metric", ENTRY_POINT_GROUPS["metric"], base=Metric,
    hint=" (decorate the function with @repbench.metric(...))")
agents: Registry[type[Agent]] = Registry("agent", ENTRY_POINT_GROUPS["agent"], base=Agent)

__all__ = ["ENTRY_POINT_GROUPS", "REGISTRIES", "Registry", "agents", "encoders",
           "import_reference", "metrics", "tasks"]

REGISTRIES: dict[str, Registry[Any]] = {
    "tasks": tasks,
    "encoders": encoders,
    "metrics": metrics,
    "agents": agents,
}
