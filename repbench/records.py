"""Result records: one versioned, self-describing JSON file per finished stage.

Every stage that produces a result (dataset, full-state agent, true-state diagnostics, encoder
fit, metric, RL run) writes ``record.json`` next to its artifact. A record says, without the plan
or the code that made it:

* ``schema`` / ``schema_version`` — this format (:data:`SCHEMA`, :data:`SCHEMA_VERSION`);
* ``kind`` — ``dataset``, ``full_state_agent``, ``diagnostics``, ``encoder``, ``metric``, ``rl``;
* ``task``, ``encoder``, ``metric``, ``agent`` — each ``{"name", "version", "params"}`` (the
  plugin's declared ``version`` and its constructor parameters), where they apply;
* ``data`` — the datasets it was computed on (sizes, seeds, the full-state agent's budget) and
  ``data_checksums`` (SHA-256 of the arrays, when known);
* ``seed``, ``budget`` (RL steps and evaluation episodes);
* ``values`` — the result: a metric's value with its interval (``ci_low``, ``ci_high``); an RL
  run's evaluation return, success rate, per-episode returns and learning curve; an encoder's
  latent size and fit time;
* ``timings``, ``library_versions``, ``git_commit``, ``created``, ``stage`` (kind, key, inputs).

**Identity and versions (the rule).** A record's *identity* is everything above that says what
was computed — task, data, encoder, metric/agent with their parameters, seed, budget — *without*
the plugin versions: :func:`identity_key`. Stage keys in the store hash the identity *and* each
plugin's declared ``version`` (a class attribute, default 0), never its source code. So editing
a plugin's docstring or refactoring it changes nothing; a plugin author who changes what the
plugin computes bumps ``version``, and then ``repbench run`` recomputes its stages while
``repbench leaderboard`` shows the older records marked *stale* (never silently dropped) until
they are replaced.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from repbench.store import git_commit, library_versions

SCHEMA = "repbench.record"
SCHEMA_VERSION = 1
RECORD_FILE = "record.json"

#: The parts of a record that carry a plugin ``{"name", "version", "params"}``.
PLUGIN_PARTS = ("task", "encoder", "metric", "agent")
#: The parts that make up its identity (what was computed), besides the plugin parts.
IDENTITY_PARTS = ("kind", "data", "seed", "budget")


def plugin_version(obj: Any) -> int:
    """A plugin's declared ``version`` (class attribute; 0 when it declares none)."""
    version = getattr(obj, "version", 0)
    return int(version) if isinstance(version, (int, float)) else 0


def plugin_part(name: str, obj: Any, params: Mapping[str, Any]) -> dict[str, Any]:
    """``{"name", "version", "params"}`` of one plugin in a record."""
    return {"name": name, "version": plugin_version(obj), "params": jsonable(params)}


def identity(context: Mapping[str, Any]) -> dict[str, Any]:
    """What a record computed, without plugin versions (see the module docstring)."""
    out: dict[str, Any] = {k: context.get(k) for k in IDENTITY_PARTS if k in context}
    for part in PLUGIN_PARTS:
        if context.get(part):
            out[part] = {"name": context[part]["name"], "params": context[part].get("params", {})}
    return out


def identity_key(context: Mapping[str, Any]) -> str:
    """Short hash of :func:`identity`: equal for a stale record and its current replacement."""
    payload = json.dumps(jsonable(identity(context)), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(payload.encode()).hexdigest()[:24]


def versions_of(record: Mapping[str, Any]) -> dict[str, tuple[str, int]]:
    """part → (plugin name, declared version) for every plugin part of ``record``."""
    return {p: (record[p]["name"], int(record[p].get("version", 0))) for p in PLUGIN_PARTS
            if record.get(p)}


def make_record(context: Mapping[str, Any], values: Mapping[str, Any], *,
                stage: Mapping[str, Any], timings: Mapping[str, Any],
                data_checksums: Mapping[str, str] | None = None) -> dict[str, Any]:
    """A complete record (see the module docstring)."""
    import time

    record: dict[str, Any] = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION}
    record.update(jsonable(dict(context)))
    record.update({
        "identity": identity_key(context),
        "values": jsonable(dict(values)),
        "data_checksums": dict(data_checksums or {}),
        "timings": jsonable(dict(timings)),
        "library_versions": library_versions(),
        "git_commit": git_commit(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "stage": jsonable(dict(stage)),
    })
    return record


def read_record(path: str | Path) -> dict[str, Any] | None:
    """The record in ``path``, or None if it is not a readable repbench record."""
    try:
        with open(path) as f:
            record = json.load(f)
    except (OSError, json.JSONDecodeError):
        return None
    if not isinstance(record, dict) or record.get("schema") != SCHEMA:
        return None
    if int(record.get("schema_version", 0)) > SCHEMA_VERSION:
        return None  # written by a newer repbench; this one cannot interpret it
    record["_path"] = str(path)
    return record


def write_record(record: Mapping[str, Any], path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clean = {k: v for k, v in record.items() if not k.startswith("_")}
    path.write_text(json.dumps(clean, indent=1, sort_keys=True, allow_nan=False))
    return path


def jsonable(value: Any) -> Any:
    """Plain JSON values: tuples → lists, numpy scalars/arrays → Python, non-finite → None."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if hasattr(value, "tolist"):
        return jsonable(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Path):
        return str(value)
    return value
