"""Read what ``repbench score-metric --out`` wrote: the metrics it scored, as metric rows a
board can rank (``repbench leaderboard --scores``). Reading only: this module imports nothing
of the pipeline, so the runner can use it without importing ``score_metric``'s reference
machinery."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, NamedTuple

import pandas as pd

from repbench.errors import ConfigError, RepbenchError
from repbench.registry import metrics

__all__ = ["SCORES_FORMAT", "SCORES_MANIFEST", "SCORES_VERSION", "ScoredMetrics",
           "metric_slug", "read_scores"]

#: The manifest of a ``score-metric --out`` folder: which metrics it scored, from which
#: reference, their direction and group, and their files (:func:`read_scores`).
SCORES_MANIFEST = "scored.json"
SCORES_FORMAT = "repbench.scores"
SCORES_VERSION = 1


def metric_slug(name: str) -> str:
    """The file stem of metric ``name`` in a ``score-metric`` folder."""
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


class ScoredMetrics(NamedTuple):
    """What :func:`read_scores` read from a ``score-metric`` folder."""

    #: metric rows as :attr:`repbench.analysis.results.Results.metric_rows` holds them
    rows: list[dict[str, Any]]
    #: metric name → higher is better
    directions: dict[str, bool]
    #: metric name → ``observable`` or ``privileged``
    groups: dict[str, str]
    #: False for a folder written before :data:`SCORES_MANIFEST` existed: its metrics'
    #: bootstrap replicates were not kept, so a board's intervals leave their noise out
    manifest: bool = True


def read_scores(folder: str | Path) -> ScoredMetrics:
    """The metrics ``repbench score-metric --out folder`` scored: their rows (task, encoder,
    metric, value, ci_low, ci_high, higher_is_better, time_s, extras with the bootstrap
    replicates where the folder has them, and ``stage_cpu_s``, the metric's ``time_s``: one
    thread, no stage around it), directions and groups.

    Which metrics, their direction and group come from the folder's :data:`SCORES_MANIFEST`;
    a folder written before it existed names them by its ``<metric>_values.csv`` files whose
    ``<metric>.csv`` row file is there too (its ``metrics.csv`` also ranks the reference's own
    metrics, which were not scored), with the direction and group of the registered metric.
    Raises ConfigError (one line) for a folder without values files, a metric neither in the
    manifest nor registered here, or a file that is not what the manifest says.
    """
    path = Path(folder)
    if not path.is_dir():
        raise ConfigError(f"--scores {folder} does not exist; pass a folder that "
                          "`repbench score-metric --out` wrote")
    entries, manifest = _scored_entries(path)
    rows: list[dict[str, Any]] = []
    directions: dict[str, bool] = {}
    groups: dict[str, str] = {}
    for entry in entries:
        name = entry["name"]
        directions[name] = bool(entry["higher_is_better"])
        groups[name] = str(entry["group"])
        files = entry.get("files") or {}
        values_file = path / files.get("values", f"{metric_slug(name)}_values.csv")
        if not values_file.is_file():
            raise ConfigError(f"--scores {folder}: {SCORES_MANIFEST} lists metric {name} but "
                              f"{values_file.name} is not there; rescore it with "
                              f"`repbench score-metric {entry.get('reference', name)} --out "
                              f"{folder}`")
        table = pd.read_csv(values_file, float_precision="round_trip")  # every digit
        lacking = [c for c in ("task", "encoder", "value") if c not in table.columns]
        if lacking or table.empty:
            raise ConfigError(f"--scores {folder}: {values_file.name} has no "
                              f"{', '.join(lacking) or 'rows'}; rescore metric {name} with "
                              "`repbench score-metric`")
        replicates: dict[str, dict[str, list[float]]] = {}
        if files.get("replicates"):
            try:
                replicates = json.loads((path / files["replicates"]).read_text(
                    encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise ConfigError(f"--scores {folder}: cannot read {files['replicates']} "
                                  f"({exc}); rescore metric {name} with "
                                  "`repbench score-metric`") from None
        for r in table.to_dict("records"):
            task, enc = str(r["task"]), str(r["encoder"])
            time_s = _number(r.get("time_s"))
            reps = (replicates.get(task) or {}).get(enc)
            rows.append({"task": task, "encoder": enc, "metric": name,
                         "value": float(r["value"]), "higher_is_better": directions[name],
                         "ci_low": _number(r.get("ci_low")), "ci_high": _number(r.get("ci_high")),
                         "extras": {"bootstrap_replicates": reps} if reps else {},
                         "time_s": time_s, "stage_cpu_s": time_s})
    return ScoredMetrics(rows, directions, groups, manifest)


def _number(x: Any) -> float | None:
    """A CSV cell as a float; None for an empty cell."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return None
    return float(x)


def _scored_entries(path: Path) -> tuple[list[dict[str, Any]], bool]:
    """The metrics a ``score-metric`` folder scored: its manifest's entries, or (a folder
    written before the manifest) one per ``<metric>_values.csv`` beside its ``<metric>.csv``,
    direction and group from the registry; and whether the folder has the manifest."""
    manifest = path / SCORES_MANIFEST
    if manifest.is_file():
        try:
            data = json.loads(manifest.read_text(encoding="utf-8"))
        except ValueError as exc:
            raise ConfigError(f"--scores {path}: {SCORES_MANIFEST} is not JSON ({exc}); "
                              "rescore the metrics with `repbench score-metric`") from None
        if (not isinstance(data, dict) or data.get("format") != SCORES_FORMAT
                or not isinstance(data.get("version"), int)
                or data["version"] > SCORES_VERSION):
            what = (f"format {data.get('format')!r} version {data.get('version')!r}"
                    if isinstance(data, dict) else "not a manifest")
            raise ConfigError(f"--scores {path}: {SCORES_MANIFEST} is {what}; this repbench "
                              f"reads {SCORES_FORMAT} version {SCORES_VERSION}: upgrade "
                              "repbench or rescore with `repbench score-metric`")
        entries = list(data.get("metrics") or [])
        for entry in entries:
            if not isinstance(entry, dict) or not {"name", "higher_is_better",
                                                   "group"} <= set(entry):
                raise ConfigError(f"--scores {path}: {SCORES_MANIFEST} has a metric entry "
                                  f"without name, higher_is_better and group ({entry!r}); "
                                  "rescore with `repbench score-metric`")
        if not entries:
            raise ConfigError(f"--scores {path}: {SCORES_MANIFEST} lists no metric; score "
                              f"one into it with `repbench score-metric METRIC --out {path}`")
        return entries, True
    stems = sorted(f.name[:-len("_values.csv")] for f in path.glob("*_values.csv")
                   if (path / f"{f.name[:-len('_values.csv')]}.csv").is_file())
    if not stems:
        raise ConfigError(f"--scores {path}: no <metric>_values.csv there; score a metric "
                          f"into it with `repbench score-metric METRIC --out {path}`")
    entries = []
    for stem in stems:
        try:
            fn = metrics.get(stem)
        except RepbenchError:
            raise ConfigError(
                f"--scores {path}: metric {stem} is not registered here and the folder has no "
                f"{SCORES_MANIFEST} to give its direction and group; rescore it with "
                f"`repbench score-metric path/to/file.py:{stem} --out {path}`") from None
        entries.append({"name": stem, "reference": stem,
                        "higher_is_better": fn.higher_is_better, "group": fn.group,
                        "files": {"rows": f"{stem}.csv", "values": f"{stem}_values.csv"}})
    return entries, False
