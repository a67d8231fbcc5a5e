"""Results are the source of truth: read result records and turn them into leaderboard rows.

Records (:mod:`repbench.records`) come from a stage store or from a folder of JSON files
(the reference records shipped in ``leaderboards/<suite>/records/``). This module knows nothing of
suites' plans: :func:`select` keeps the records whose identities a caller asks for, and
:func:`build_results` is a pure function of the records it is given (plus the installed plugin
versions, to mark older records *stale*). The leaderboard tables and pages are computed from the
:class:`Results` it returns.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path
from typing import Any

from repbench.errors import RepbenchError
from repbench.records import (
    CHECKSUM,
    PLUGIN_PARTS,
    RECORD_STAGES,
    inspect_record,
    is_store_root,
    mixed_encoder_weights,
    plugin_version,
    store_record_files,
    store_record_problem,
    value_problem,
    versions_of,
    write_record,
)
from repbench.registry import REGISTRIES

log = logging.getLogger(__name__)

#: Stage kinds whose records the leaderboard reads.
RECORD_KINDS = RECORD_STAGES
_LABELS = {"dataset": "{task} {name} data", "full_state_agent": "{task} privileged SAC"}


@dataclass
class Results:
    """Everything a leaderboard shows, gathered from records."""

    suite: Any
    metric_rows: list[dict[str, Any]] = field(default_factory=list)
    rl_rows: list[dict[str, Any]] = field(default_factory=list)
    encoder_rows: list[dict[str, Any]] = field(default_factory=list)
    diagnostics: dict[str, Any] = field(default_factory=dict)  # task → diagnostics
    provenance: dict[str, Any] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)
    figures_from_store: dict[str, Path] = field(default_factory=dict)  # name → png path
    #: (task, encoder) → why its results are stale ("encoder vae v0, installed v1")
    stale: dict[tuple[str, str], list[str]] = field(default_factory=dict)
    #: encoders to highlight (``repbench evaluate``)
    highlight: list[str] = field(default_factory=list)
    #: predicted returns (``repbench evaluate --metrics-only``): dicts with task, encoder,
    #: agent, predicted_return, ci_low, ci_high, predictor, n_reference, method
    predictions: list[dict[str, Any]] = field(default_factory=list)
    #: the records the results were built from (written to ``<leaderboard>/records/``)
    records: list[dict[str, Any]] = field(default_factory=list)
    #: notes shown above the tables (e.g. data that differ from the reference data)
    warnings: list[str] = field(default_factory=list)
    #: (task, agent, metric) → encoder → leave-one-encoder-out predicted return (metric
    #: leaderboard, :func:`repbench.report.leaderboard.metric_ranking`)
    loo_predictions: dict[tuple[str, str, str], dict[str, float]] = field(default_factory=dict)
    #: the "Does the answer hold?" checks (:mod:`repbench.analysis.robustness`): ``checks``, the
    #: rows of ``robustness.csv``; ``heldout``, every encoder predicted leave-one-family-out
    #: per task × agent × calibration method
    robustness: dict[str, Any] = field(default_factory=dict)


# -- reading --------------------------------------------------------------------------------------

def load_records(*sources: Any, kinds: Iterable[str] = RECORD_KINDS,
                 problems: list[str] | None = None) -> list[dict[str, Any]]:
    """Every sound record in ``sources``: a :class:`repbench.pipeline.store.Store` (or any
    object with the store's folder as its ``root``), a store root, or a folder of record JSON
    files (searched recursively).

    Each record is checked (:func:`repbench.records.inspect_record`: valid JSON, its own
    checksum; in a store also the checksum the artifact's ``meta.json`` holds for it,
    :func:`repbench.records.store_record_problem`). A record that fails is left out with a
    one-line warning naming the file and why (logged, and appended to ``problems`` when given),
    never published.
    """
    out: list[dict[str, Any]] = []
    kinds = tuple(kinds)
    for source in sources:
        # a Store is read by its folder (no import of the pipeline: the flow is one way); a
        # path is no store object, though a Path has a ``root`` ("/") too
        is_store_object = not isinstance(source, (str, PathLike)) and hasattr(source, "root")
        root = Path(source.root) if is_store_object else Path(source)
        in_store = is_store_object or is_store_root(root)
        if in_store:  # a stage store
            paths: Iterable[Path] = store_record_files(root, kinds)
        else:
            paths = sorted(root.rglob("*.json")) if root.is_dir() else []
        unchecked = 0
        for path in paths:
            record, problem = inspect_record(path)
            if problem is None and record is not None and in_store:
                problem = store_record_problem(path)
            if problem is not None:
                log.warning("%s", problem)
                if problems is not None:
                    problems.append(problem)
                continue
            if record is not None and record.get("kind") in kinds:
                out.append(record)
                unchecked += CHECKSUM not in record and not in_store
        if unchecked:
            log.warning("%d records in %s carry no checksum (record schema 1, written before "
                        "records had one): read unchecked", unchecked, root)
    return out


def installed_versions(records: Iterable[Mapping[str, Any]]) -> dict[tuple[str, str], int]:
    """(part, name) → the declared version of the installed plugin, for every plugin the
    records name that is installed (uninstalled ones are left out: they cannot be compared)."""
    out: dict[tuple[str, str], int] = {}
    for record in records:
        for part, (name, _) in versions_of(record).items():
            if (part, name) in out:
                continue
            registry = REGISTRIES[f"{part}s"]
            try:
                out[(part, name)] = plugin_version(registry.get(name))
            except RepbenchError:
                continue
    return out


def stale_reasons(record: Mapping[str, Any], installed: Mapping[tuple[str, str], int]
                  ) -> list[str]:
    """Why ``record`` is stale: each plugin whose recorded version differs from the
    installed one (empty: current, or its plugins are not installed)."""
    reasons = []
    for part, (name, version) in versions_of(record).items():
        now = installed.get((part, name))
        if now is not None and now != version:
            reasons.append(f"{part} {name} v{version}, installed v{now}")
    return reasons


def select(records: Iterable[dict[str, Any]], identities: Iterable[str] | None = None,
           installed: Mapping[tuple[str, str], int] | None = None) -> list[dict[str, Any]]:
    """One record per identity (those in ``identities``, or all): the current one when there
    is one, else the newest stale one (which :func:`build_results` marks stale)."""
    wanted = None if identities is None else set(identities)
    installed = installed or {}
    best: dict[str, dict[str, Any]] = {}
    for record in records:
        ident = record.get("identity")
        if ident is None or (wanted is not None and ident not in wanted):
            continue
        old = best.get(ident)
        if old is None or _rank(record, installed) > _rank(old, installed):
            best[ident] = record
    return list(best.values())


def _rank(record: Mapping[str, Any], installed: Mapping[tuple[str, str], int]
          ) -> tuple[int, str]:
    return (0 if stale_reasons(record, installed) else 1, str(record.get("created", "")))


# -- building the leaderboard's inputs ------------------------------------------------------------

def build_results(records: Iterable[Mapping[str, Any]], *, suite: Any = None,
                  missing: Iterable[str] = (),
                  installed: Mapping[tuple[str, str], int] | None = None) -> Results:
    """The leaderboard's rows from ``records`` (a pure function of its arguments).

    A metric record whose value cannot be published (not a finite number, or outside its own
    interval: :func:`repbench.records.value_problem`) is left out with a warning
    naming its file, in the log and on the page, like a record that fails its checksum.

    ``suite`` (optional) adds the suite's description and settings to the provenance;
    ``installed`` (:func:`installed_versions`) marks records of older plugin versions stale.
    """
    res = Results(suite)
    res.missing = list(missing)
    installed = installed or {}
    records = sorted(records, key=_order_by(suite))
    for problem in filter(None, map(value_problem, records)):
        log.warning("%s", problem)
        res.warnings.append(problem)
    records = [r for r in records if value_problem(r) is None]
    res.records = list(records)
    for warning in mixed_encoder_weights(records):
        log.warning("%s", warning)
        res.warnings.append(warning)
    multi_task = len({r["task"]["name"] for r in records}) > 1
    directions: dict[str, bool] = {}
    for r in records:
        task = r["task"]["name"]
        values = dict(r.get("values") or {})
        kind = r["kind"]
        enc = (r.get("encoder") or {}).get("name")
        reasons = stale_reasons(r, installed)
        if reasons and enc is not None:
            bucket = res.stale.setdefault((task, enc), [])
            bucket.extend(x for x in reasons if x not in bucket)
        if kind == "encoder":
            res.encoder_rows.append({"task": task, "encoder": enc,
                                     "latent_dim": values.get("latent_dim"),
                                     "fit_time_s": values.get("fit_time_s"),
                                     "fit_cpu_s": _stage_cpu_s(r),
                                     "family": values.get("family"),
                                     "best_epoch": values.get("best_epoch"),
                                     "epochs_run": values.get("epochs_run"),
                                     "heldout_loss": values.get("heldout_loss")})
            label = f"{enc} {task}" if multi_task else enc  # one figure per task × encoder
            for stem, png in (values.get("files") or {}).items():
                path = _encoder_figure(r, stem, label, enc, png)
                if path is not None:
                    res.figures_from_store[f"{stem} {label}"] = path
        elif kind == "metric":
            name = r["metric"]["name"]
            directions[name] = bool(values.get("higher_is_better", True))
            res.metric_rows.append({"task": task, "encoder": enc, "metric": name, **values,
                                    "stage_cpu_s": _stage_cpu_s(r)})
        elif kind == "rl":
            res.rl_rows.append({"task": task, "encoder": enc, "agent": r["agent"]["name"],
                                "seed": r.get("seed"),
                                "encoder_weights": r.get("encoder_weights"), **values})
        elif kind == "diagnostics":
            res.diagnostics[task] = values
        elif kind in _LABELS:
            label = _LABELS[kind].format(task=task, name=(r.get("data") or {}).get("name", ""))
            label = label.replace("on_policy data", "on-policy data")
            res.provenance.setdefault("datasets", {})[label] = {
                k: v for k, v in values.items() if k != "metadata"}
    res.provenance.update(_provenance(suite, records))
    res.provenance["directions"] = directions
    if res.stale:
        res.provenance["stale"] = {f"{t} {e}": why for (t, e), why in sorted(res.stale.items())}
    return res


def _stage_cpu_s(record: Mapping[str, Any]) -> float | None:
    """CPU seconds of the stage that made ``record`` (its ``timings``; ``None`` if absent).

    Unlike wall time this does not grow while the run waits: paused, or sharing its cores
    with other work."""
    seconds = (record.get("timings") or {}).get("cpu_time_s")
    return float(seconds) if isinstance(seconds, (int, float)) else None


def _order_by(suite: Any) -> Any:
    """Sort key: the suite's order of tasks, encoders, metrics and agents (so tables keep the
    suite's column order); names the suite does not list come after, alphabetically."""
    lists = {part: list(getattr(suite, f"{part}s", []) or []) for part in PLUGIN_PARTS}

    def pos(part: str, r: Mapping[str, Any]) -> tuple[int, str]:
        name = (r.get(part) or {}).get("name") or ""
        order = lists[part]
        return (order.index(name) if name in order else len(order), name)

    def key(r: Mapping[str, Any]) -> tuple[Any, ...]:
        seed = r.get("seed")
        return (pos("task", r), pos("encoder", r), str(r.get("kind")), pos("metric", r),
                pos("agent", r), seed if isinstance(seed, int) else -1)

    return key


def _provenance(suite: Any, records: list[Mapping[str, Any]]) -> dict[str, Any]:
    commits = sorted({r.get("git_commit") or "unknown" for r in records})
    versions = records[-1].get("library_versions", {}) if records else {}
    by_stage: dict[str, float] = {}
    for r in records:
        secs = float((r.get("timings") or {}).get("wall_time_s") or 0.0)
        by_stage[r["kind"]] = by_stage.get(r["kind"], 0.0) + secs
    created = sorted(str(r.get("created", "")) for r in records)
    out: dict[str, Any] = {}
    if suite is not None:
        out.update({
            "suite": suite.name, "suite_source": suite.source, "description": suite.description,
            "rl_seeds": list(suite.seeds), "dataset": suite.dataset.model_dump(),
            "encoder_training": suite.encoder_training.model_dump(),
            "rl": suite.rl.model_dump()})
        for key, table in (("task_dataset", suite.task_dataset), ("task_rl", suite.task_rl)):
            if table:  # per-task overrides of [dataset] / [rl]
                out[key] = {t: o.model_dump(exclude_unset=True) for t, o in table.items()}
    out.update({
        "git_commits": commits, "versions": versions,
        "compute_seconds_by_stage": {k: round(v, 1) for k, v in sorted(by_stage.items())},
        "first_result": created[0] if created else None,
        "last_result": created[-1] if created else None,
        "n_records": len(records),
    })
    return out


def _encoder_figure(record: Mapping[str, Any], stem: str, label: str, encoder: str | None,
                    png: str) -> Path | None:
    """The encoder's figure ``png`` beside its record in the store or, for a record shipped in
    a leaderboard's ``records/encoder/``, the copy in that leaderboard's ``figures/`` (a
    rebuild from records keeps the training curves and reconstructions it cannot redraw):
    named by ``label`` (``"<encoder> <task>"`` on a board of several tasks), or by the encoder
    alone when the records folder holds one task's encoders (a figure so named belongs to the one
    task such a board had, so a folder of several tasks never falls back to it). A board of one
    task built from a folder of several finds the figure under its ``<encoder>_<task>`` name."""
    if not record.get("_path"):
        return None
    here = Path(record["_path"]).parent
    figures = here.parent.parent / "figures"
    task = (record.get("task") or {}).get("name")
    one_task_name = figures / f"{stem}_{encoder}.png"
    candidates = [here / png, figures / f"{stem}_{encoder}_{task}.png",
                  figures / f"{stem}_{label.replace(' ', '_')}.png"]
    if len({p.name.split(".", 1)[0] for p in here.glob("*.json")}) <= 1:  # <task>.<encoder>-...
        candidates.append(one_task_name)
    else:  # a label of the encoder alone is the one-task name, another task's figure here
        candidates = [path for path in candidates if path != one_task_name]
    return next((path for path in candidates if path.is_file()), None)


def write_records(records: Iterable[Mapping[str, Any]], folder: Path) -> list[Path]:
    """Write ``records`` as ``folder/<kind>/<task>.<encoder>.<metric|agent>.s<seed>-<id>.json``
    (replacing the folder's earlier records): the shippable form of a leaderboard's results.

    Only sound repbench records (:func:`~repbench.records.inspect_record`) are replaced:
    any other file in ``folder`` (a user's notes, an analysis, an edited or damaged record) is
    not repbench's to delete and stays where it is."""
    folder = Path(folder)
    if folder.is_dir():
        for old in folder.rglob("*.json"):
            if inspect_record(old)[0] is not None:
                old.unlink(missing_ok=True)
    return [write_record(r, folder / r["kind"] / f"{record_stem(r)}.json") for r in records]


def record_stem(r: Mapping[str, Any]) -> str:
    """The file name (without ``.json``) a record is shipped under:
    ``<task>.<encoder>.<metric|agent>[.s<seed>]-<identity8>``."""
    parts = [r["task"]["name"], *((r.get(p) or {}).get("name") for p in PLUGIN_PARTS[1:])]
    if r["kind"] == "dataset":
        parts.append((r.get("data") or {}).get("name"))
    if isinstance(r.get("seed"), int) and r["kind"] == "rl":
        parts.append(f"s{r['seed']}")
    return ".".join(_slug(p) for p in parts if p) + f"-{r['identity'][:8]}"


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in str(text))
