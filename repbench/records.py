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
* ``encoder_weights`` — SHA-256 of the trained encoder file the result was computed from (its
  own for an encoder record, its encoder's for a metric or RL record; null without an encoder).
  Encoder training is not bit-reproducible across CPUs (torch picks AVX2 or AVX-512 kernels),
  so one encoder's stage key can stand for different weights on two machines: a board whose
  records of one encoder carry different weights mixes two trainings
  (:func:`mixed_encoder_weights` says so on the page);
* ``seed``, ``budget`` (RL steps and evaluation episodes);
* ``values`` — the result: a metric's value with its interval (``ci_low``, ``ci_high``); an RL
  run's evaluation return, success rate, per-episode returns and learning curve; an encoder's
  latent size and fit time;
* ``timings``, ``library_versions``, ``cpu`` (the CPU's model name: float results of the same
  versions can differ across CPUs), ``git_commit``, ``created``, ``stage`` (kind, key, inputs);
* ``checksum`` — SHA-256 of the record's canonical JSON without this field
  (:func:`record_checksum`; schema version 2 on). Every reader checks it
  (:func:`inspect_record`): an edited or damaged record is left out with a one-line warning,
  never published. Records of schema version 1 have none; inside a stage store the store's own
  file checksums cover them.

**Identity and versions (the rule).** A record's *identity* is everything above that says what
was computed — task, data, encoder, metric/agent with their parameters, seed, budget — *without*
the plugin versions: :func:`identity_key`. Stage keys in the store hash the identity *and* each
plugin's declared ``version`` (a class attribute, default 0), never its source code. So editing
a plugin's docstring or refactoring it changes nothing; a plugin author who changes what the
plugin computes bumps ``version``, and then ``repbench run`` recomputes its stages while
``repbench leaderboard`` shows the older records marked *stale* (never silently dropped) until
they are replaced.

**Where records are read from.** A stage store (:class:`repbench.pipeline.store.Store`) keeps a
record as ``<root>/<stage>/<key>/record.json`` beside its artifact's ``meta.json``, which holds
the SHA-256 of every file of the artifact (:func:`store_record_files`,
:func:`store_record_problem`); a folder of exported records (a leaderboard's ``records/``) holds
``<kind>/<name>.json`` files (:func:`holds_exported_records`). This module reads both without
the store's code, so the analysis (:mod:`repbench.analysis.results`) reads records without
depending on the pipeline that writes them: it imports nothing from ``repbench.pipeline``,
``repbench.analysis`` or ``repbench.report``.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from repbench.provenance import cpu_model, git_commit, library_versions

SCHEMA = "repbench.record"
#: 2: records carry their own ``checksum``; 1 (still read): without it
SCHEMA_VERSION = 2
RECORD_FILE = "record.json"
CHECKSUM = "checksum"
#: What to do about a record a reader leaves out (appended to its warning).
RERUN = "rerun the stage with `repbench run`"

#: the stages whose artifacts hold a result record (a records folder has one subfolder each)
RECORD_STAGES = ("dataset", "full_state_agent", "diagnostics", "encoder", "latents", "metric",
                 "rl")
#: an artifact's metadata file in a stage store (its ``files`` maps each file to its SHA-256)
META = "meta.json"

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
                data_checksums: Mapping[str, str] | None = None,
                encoder_weights: str | None = None) -> dict[str, Any]:
    """A complete record (see the module docstring)."""
    import time

    record: dict[str, Any] = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION}
    record.update(jsonable(dict(context)))
    record.update({
        "identity": identity_key(context),
        "values": jsonable(dict(values)),
        "data_checksums": dict(data_checksums or {}),
        "encoder_weights": encoder_weights,
        "timings": jsonable(dict(timings)),
        "library_versions": library_versions(),
        "cpu": cpu_model(),
        "git_commit": git_commit(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "stage": jsonable(dict(stage)),
    })
    record[CHECKSUM] = record_checksum(record)
    return record


def record_checksum(record: Mapping[str, Any]) -> str:
    """SHA-256 of ``record``'s canonical JSON (sorted keys, no whitespace), leaving out the
    ``checksum`` field itself and in-memory fields (names starting with ``_``)."""
    clean = {k: v for k, v in record.items() if k != CHECKSUM and not k.startswith("_")}
    payload = json.dumps(clean, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(payload.encode()).hexdigest()


def inspect_record(path: str | Path) -> tuple[dict[str, Any] | None, str | None]:
    """Read the record in ``path``: ``(record, None)`` when it is sound; ``(None, why)`` when
    it is damaged, edited or unreadable (``why`` is the one-line warning, naming the file and
    what to do); ``(None, None)`` for a JSON file that is no repbench record."""
    try:
        with open(path) as f:
            text = f.read()
    except OSError as exc:
        return None, f"record {path} cannot be read ({exc.strerror or exc}): left out; {RERUN}"
    try:
        record = json.loads(text)
    except json.JSONDecodeError:
        return None, (f"record {path} is not valid JSON (truncated or corrupt): left out; "
                      f"{RERUN}")
    if not isinstance(record, dict) or record.get("schema") != SCHEMA:
        return None, None
    try:
        version = int(record.get("schema_version", 0))
    except (TypeError, ValueError):
        version = -1
    if version > SCHEMA_VERSION:
        return None, (f"record {path} has record schema {version}, this repbench reads up to "
                      f"{SCHEMA_VERSION}: left out; upgrade repbench to read it")
    if version >= 2 and not _checksum_matches(record):
        return None, (f"record {path} fails its checksum (edited or corrupt): left out; "
                      f"{RERUN}")
    if version < 1:
        return None, f"record {path} has no valid schema_version: left out; {RERUN}"
    record["_path"] = str(path)
    return record, None


def _checksum_matches(record: Mapping[str, Any]) -> bool:
    try:
        return record.get(CHECKSUM) == record_checksum(record)
    except (TypeError, ValueError):  # NaN or another value no record holds
        return False


def value_problem(record: Mapping[str, Any]) -> str | None:
    """Why a metric record's value cannot be published, as a one-line warning naming its file
    (None: it can, or the record is no metric's): a value that is not a finite number (an older
    repbench stored a metric's NaN as null) or one outside the record's own interval
    (``ci_low``..``ci_high``: an edited record, or a metric whose interval is not of its value).
    The readers of records into a board leave such a record out
    (:func:`repbench.analysis.results.build_results`)."""
    if record.get("kind") != "metric":
        return None
    values = record.get("values") or {}
    where = record.get("_path") or f"of metric {(record.get('metric') or {}).get('name')}"
    what = (f"({(record.get('metric') or {}).get('name')} of "
            f"{(record.get('encoder') or {}).get('name')} on "
            f"{(record.get('task') or {}).get('name')})")
    value, low, high = values.get("value"), values.get("ci_low"), values.get("ci_high")
    if not _finite(value):
        return f"record {where} {what} has no finite value ({value!r}): left out; {RERUN}"
    if _finite(low) and _finite(high):
        tol = 1e-9 * max(1.0, abs(float(low)), abs(float(high)))
        if not float(low) - tol <= float(value) <= float(high) + tol:
            return (f"record {where} {what} has the value {float(value):.6g} outside its own "
                    f"interval [{float(low):.6g}, {float(high):.6g}] (edited, or the metric's "
                    f"interval is wrong): left out; {RERUN}")
    return None


def _finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def read_record(path: str | Path) -> dict[str, Any] | None:
    """The record in ``path``, or None if it is not a sound repbench record
    (:func:`inspect_record` says why)."""
    return inspect_record(path)[0]


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


def mixed_encoder_weights(records: Iterable[Mapping[str, Any]]) -> list[str]:
    """One warning line per (task, encoder) whose records were computed from different trained
    weights (``encoder_weights``), e.g. metrics from a training on one machine and RL returns
    from a training on another. Records without the field (made before it existed) are not
    judged."""
    seen: dict[tuple[str, str], dict[str, set[str]]] = {}
    for r in records:
        digest, enc = r.get("encoder_weights"), r.get("encoder")
        if not digest or not enc:
            continue
        task = (r.get("task") or {}).get("name", "?")
        seen.setdefault((task, enc["name"]), {}).setdefault(digest, set()).add(r.get("kind", "?"))
    out = []
    for (task, name), digests in sorted(seen.items()):
        if len(digests) > 1:
            kinds = "; ".join(f"{d[:12]}: {', '.join(sorted(k))}" for d, k in digests.items())
            out.append(f"encoder {name} on {task}: its records come from {len(digests)} "
                       f"different trainings of its weights ({kinds}), e.g. made on different "
                       "machines; its metrics and returns do not describe one encoder; rerun its "
                       "stages in one store")
    return out


# -- the store's layout, as readers of records see it ----------------------------------------------

def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def holds_exported_records(root: Path) -> bool:
    """Whether ``root`` is a folder of exported records (``<stage>/<name>.json``, as a
    leaderboard's ``records/``) rather than a stage store (``<stage>/<key>/`` folders)."""
    return root.is_dir() and any(p.is_file() for stage in RECORD_STAGES
                                 for p in (root / stage).glob("*.json"))


def is_store_root(root: Path) -> bool:
    """Whether the folder ``root`` is a stage store (it has the store's ``.tmp/`` and is no
    folder of exported records)."""
    return (root / ".tmp").is_dir() and not holds_exported_records(root)


def store_record_files(root: Path, kinds: Iterable[str] = RECORD_STAGES) -> list[Path]:
    """The record file of every finished artifact of the stages ``kinds`` in the stage store
    ``root`` (``<root>/<kind>/<key>/record.json``), stage by stage in ``kinds``' order, each
    stage's sorted. Unverified: :func:`store_record_problem` checks one against its artifact."""
    return [p for k in kinds for p in sorted((root / k).glob(f"*/{RECORD_FILE}"))]


def store_record_problem(path: Path) -> str | None:
    """Why the record file ``path`` of a stored artifact fails the checksum its artifact's
    ``meta.json`` holds for it (None: it passes)."""
    meta_path = path.parent / META
    try:
        digest = json.loads(meta_path.read_text()).get("files", {}).get(path.name)
    except (OSError, ValueError, AttributeError):
        return (f"record {path} belongs to an artifact without a readable {META}: left out; "
                f"{RERUN}")
    if digest != file_sha256(path):
        return f"record {path} fails its checksum (edited or corrupt): left out; {RERUN}"
    return None
