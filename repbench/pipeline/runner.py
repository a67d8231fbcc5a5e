"""``repbench run`` and ``repbench leaderboard``: plan a suite, run what is missing, write the
leaderboards."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from repbench.analysis.results import (
    Results,
    build_results,
    installed_versions,
    load_records,
    select,
)
from repbench.errors import ConfigError, RepbenchError
from repbench.pipeline.executors import RunReport, make_executor, run_stages
from repbench.pipeline.plan import Plan, build_plan
from repbench.pipeline.preflight import check_dataset_sizes, check_out_dir
from repbench.pipeline.records import identity_key
from repbench.pipeline.stages import RL
from repbench.pipeline.store import Store, leaves_no_store_on_refusal
from repbench.pipeline.suite import BUILTIN_SUITES, Suite, check_suite_name, load_suite
from repbench.report.leaderboard import write_leaderboards

log = logging.getLogger(__name__)


@dataclass
class RunResult:
    out_dir: Path
    report: RunReport
    results: Results
    seconds: float


def default_out_dir(suite_name: str, tasks: Sequence[str] | None = None) -> Path:
    """``leaderboards/<suite>``; on some of its tasks ``leaderboards/<suite>-<task>...``, so
    that a one-task run never overwrites the whole suite's board. Always one folder directly
    inside ``leaderboards/``: a task given by reference (``path/to/file.py:Task``) has the
    characters a folder name cannot hold replaced by ``_``; a bad suite name is a
    ConfigError."""
    try:
        check_suite_name(suite_name)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    safe = ["".join(c if c.isalnum() or c in "-_." else "_" for c in t).replace("..", "_")
            for t in tasks or []]
    return Path("leaderboards") / "-".join([suite_name, *safe])


def suite_on_tasks(suite: Suite, tasks: Sequence[str] | None) -> Suite:
    """``suite`` on ``tasks`` only (all of them when ``tasks`` is empty or None); a task that
    is not the suite's raises ConfigError naming the ones it has."""
    if not tasks:
        return suite
    unknown = [t for t in tasks if t not in suite.tasks]
    if unknown:
        raise ConfigError(f"--task {unknown[0]} is not a task of suite {suite.name} "
                          f"({', '.join(suite.tasks)}); pass one of those")
    return suite.only_tasks(list(dict.fromkeys(tasks)))


@leaves_no_store_on_refusal
def run_suite(suite: str | Path, *, store: str | Path | None = None, out: str | Path | None = None,
              executor: str = "local", workers: int | None = None,
              ray_address: str | None = None, progress: bool = True,
              no_rl: bool = False, tasks: Sequence[str] | None = None) -> RunResult:
    """Run every missing stage of ``suite`` and write its leaderboards.

    With ``no_rl`` every stage but the encoders' RL runs (datasets, the privileged agent that
    collects the on-policy data, encoders, latents, metrics): the metrics of a task can then be
    looked at, or a return predicted from them and committed, before any RL record exists; a
    later run without ``no_rl`` on the same store adds the RL. With ``tasks`` only those of the
    suite's tasks run (the same stages as in the whole suite, so a later whole run reuses
    them), and the default output folder is ``leaderboards/<suite>-<task>``.

    Raises :class:`repbench.errors.RepbenchError` for a bad suite/plugin/parameter before any
    work starts. Stages that fail are reported; the leaderboards show what finished.
    """
    start = time.time()
    check_workers(workers)
    s = suite_on_tasks(load_suite(suite), tasks)
    out_dir = check_out_dir(out if out is not None else default_out_dir(s.name, tasks))
    st = Store(store)
    plan = build_plan(s)
    check_dataset_sizes(plan, st)
    stages = [stage for stage in plan.stages() if not (no_rl and stage.kind == RL)]
    n_workers = cap_local_workers(workers, executor) or min(usable_cpus(), 8)
    ex = make_executor(executor, str(st.root), n_workers, ray_address)
    print(f"suite {s.name}: {len(stages)} stages ({len(s.tasks)} tasks × {len(s.encoders)} "
          f"encoders × {len(s.metrics)} metrics, "
          f"{'no RL' if no_rl else f'{len(s.agents)} agents × {len(s.seeds)} seeds'}); "
          f"store {st.root}; executor {executor} ({ex.capacity} workers)", flush=True)
    report = run_stages(stages, st, ex, progress=progress)
    print(f"stages: {report.summary()}", flush=True)
    results = collect_results(plan, st)
    write_leaderboards(results, out_dir)
    if report.failed:
        print("failed stages (the leaderboard leaves them out):", flush=True)
        for i, err in report.failed.items():
            print(f"  {report.labels[i]}: {err}", flush=True)
    return RunResult(out_dir, report, results, time.time() - start)


#: Stages whose absence the leaderboard lists as missing.
_SHOWN = ("encoder", "metric", "rl")


def collect_results(plan: Plan, store: Store, extra_records: list[dict] | None = None) -> Results:
    """The records of ``plan``'s stages in ``store`` (selected by identity, so records of an
    older plugin version are found and shown stale), plus ``extra_records``, as
    :class:`Results`. Stages with no record are listed in ``missing``."""
    problems: list[str] = []  # records left out (edited, truncated ...), shown on the page
    records = [*load_records(store, problems=problems), *(extra_records or [])]
    return results_of(plan, records, problems)


def results_of(plan: Plan, records: list[dict], problems: list[str] | None = None) -> Results:
    """:class:`Results` of ``plan`` from ``records`` (one per stage identity; stages with none
    listed in ``missing``); ``problems`` (records left out) become the page's warnings."""
    wanted = {identity_key(s.record): s for s in plan.stages() if s.record is not None}
    installed = installed_versions(records)
    chosen = select(records, wanted, installed)
    found = {r["identity"] for r in chosen}
    missing = [s.label for i, s in wanted.items() if i not in found and s.kind in _SHOWN]
    order = {i: n for n, i in enumerate(wanted)}
    chosen.sort(key=lambda r: order.get(r["identity"], len(order)))
    results = build_results(chosen, suite=plan.suite, missing=missing, installed=installed)
    results.warnings.extend(problems or [])
    return results


def plan_identities(suite: Suite) -> set[str]:
    """The record identities of every stage of ``suite``."""
    return {identity_key(s.record) for s in build_plan(suite).stages() if s.record is not None}


def records_of_suite(records: list[dict], suite: Suite, folder: str | Path,
                     what: str = "records folder") -> list[dict]:
    """The records among ``records`` (read from ``folder``) that are stages of ``suite``.

    Raises ConfigError (one line, naming the suite they belong to and the one asked for) when
    they are the records of another suite: another built-in suite (or the one their
    leaderboard's ``provenance.json`` names) has more of them among its stages, or ``suite``
    has none; unless they hold every stage of ``suite`` (one task of quick, say, rebuilt from
    quick's records). Records that are not stages of ``suite`` are otherwise left out with a
    warning.
    """
    wanted = plan_identities(suite)
    ours = [r for r in records if r.get("identity") in wanted]
    if len(ours) == len(records):
        return ours
    where = f"{what} {folder}"
    owner, n_owner = _owner_suite(records, exclude=suite.name)
    if owner is None:
        owner, n_owner = _provenance_suite(Path(folder)), 0
    every_stage = wanted <= {r.get("identity") for r in ours}
    if owner is not None and owner != suite.name and (n_owner > len(ours) or not ours) \
            and not every_stage:
        count = f" ({n_owner} of their {len(records)} stages)" if n_owner else ""
        raise ConfigError(
            f"the records in {where} belong to suite {owner!r}{count}, not to suite "
            f"{suite.name!r} that was asked for; pass --suite {owner}, or the records of suite "
            f"{suite.name}")
    if not ours:
        raise ConfigError(
            f"none of the {len(records)} records in {where} is a stage of suite {suite.name!r} "
            "as it is now (nor of another built-in suite): they were made with another suite "
            "or an older version of this one; pass --suite with the suite file they were made "
            "with")
    log.warning("%d of the %d records in %s are not stages of suite %r: left out",
                len(records) - len(ours), len(records), where, suite.name)
    return ours


def _owner_suite(records: list[dict], exclude: str) -> tuple[str | None, int]:
    """The built-in suite (other than ``exclude``) with the most of ``records`` among its
    stages, and how many; (None, 0) when none has any."""
    best: tuple[str | None, int] = (None, 0)
    identities = [r.get("identity") for r in records]
    for name in BUILTIN_SUITES:
        if name == exclude:
            continue
        try:
            theirs = plan_identities(load_suite(name))
        except RepbenchError:  # a built-in suite whose plugins are not installed
            continue
        n = sum(i in theirs for i in identities)
        if n > best[1]:
            best = (name, n)
    return best


def _provenance_suite(folder: Path) -> str | None:
    """The suite the ``provenance.json`` beside a leaderboard's records folder names, if any."""
    try:
        name = json.loads((folder.parent / "provenance.json").read_text()).get("suite")
    except (OSError, ValueError, AttributeError):
        return None
    return name if isinstance(name, str) and name else None


def check_workers(workers: int | None) -> None:
    """Raise ConfigError for a worker count below 1 (None means: size to the machine)."""
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}; leave it out to use "
                          "one worker per CPU core")


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity mask, else the machine's count)."""
    if hasattr(os, "sched_getaffinity"):
        with contextlib.suppress(OSError):
            return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def cap_local_workers(workers: int | None, executor: str = "local") -> int | None:
    """``workers`` for the local executor, at most :func:`usable_cpus` (more processes than
    CPUs only compete for them and multiply memory), with a one-line warning on stderr when
    it was more. Ray's workers run on the cluster's machines: not capped here."""
    if executor != "local" or workers is None:
        return workers
    cpus = usable_cpus()
    if workers > cpus:
        print(f"repbench: warning: --workers {workers} is more than the {cpus} CPUs this "
              f"process may use; using {cpus}", file=sys.stderr, flush=True)
        return cpus
    return workers


def _companion_results(folder: str | Path, option: str, example: str, what: str) -> Results:
    """The results of the leaderboard folder (or its ``records/``) given to ``option``;
    ConfigError (one line) when it is missing or holds no RL records."""
    folder = Path(folder)
    where = folder / "records" if (folder / "records").is_dir() else folder
    if not folder.is_dir():
        raise ConfigError(f"{option} {folder}: no such folder; pass the leaderboard folder of "
                          f"{what} (e.g. {example})")
    problems: list[str] = []
    records = [r for f in board_records_folders(folder)
               for r in load_records(f, problems=problems)]
    res = build_results(select(records, installed=installed_versions(records)))
    res.warnings.extend(problems)
    res.provenance["suite"] = _provenance_suite(where)
    if not res.rl_rows:
        raise ConfigError(f"{option} {folder}: no RL records there; pass the leaderboard folder "
                          f"of {what} (e.g. {example})")
    return res


def board_records_folders(folder: str | Path) -> list[Path]:
    """The folders holding the records of the leaderboard ``folder``: its ``records/`` and the
    folders its ``provenance.json`` names (a board written with ``copy_records=False``), or
    ``folder`` itself when it is a records folder."""
    folder = Path(folder)
    found = [folder / "records"] if (folder / "records").is_dir() else []
    try:
        named = json.loads((folder / "provenance.json").read_text()).get("records_folders", [])
    except (OSError, ValueError):
        named = []
    found += [(folder / f).resolve() for f in named if (folder / f).is_dir()]
    return found or [folder]


def _companion_provenance(folder: str | Path, res: Results) -> dict[str, Any]:
    return {"folder": str(folder), "suite": res.provenance.get("suite"),
            "agents": sorted({str(r["agent"]) for r in res.rl_rows}),
            "train_steps": sorted({int(r["train_steps"]) for r in res.rl_rows}),
            "encoders": sorted({str(r["encoder"]) for r in res.rl_rows})}


def agent_run_results(folder: str | Path, base: Results) -> Results:
    """The results in ``folder`` (a leaderboard folder, or its ``records/``) of another agent on
    ``base``'s tasks (e.g. DDPG beside SAC): the agent-agreement checks of ``robustness.csv``.
    Its budget may differ from ``base``'s (each agent at the budget where it learns: DDPG at
    50k beside quick's SAC at 10k); the rows then name both budgets.

    Raises ConfigError (one line) when the folder holds no RL records, or its runs are of an
    agent ``base`` already has, a task ``base`` has no RL results on, or several budgets.
    """
    other = _companion_results(folder, "--agent-run", "leaderboards/quick/ddpg",
                               "a run of another agent")
    for task, agent in sorted({(r["task"], r["agent"]) for r in other.rl_rows}):
        ours = {int(r["train_steps"]) for r in base.rl_rows if r["task"] == task}
        theirs = {int(r["train_steps"]) for r in other.rl_rows
                  if r["task"] == task and r["agent"] == agent}
        if any(r["task"] == task and r["agent"] == agent for r in base.rl_rows):
            raise ConfigError(f"--agent-run {folder}: its runs are {task} × {agent}, which this "
                              "suite already trains; pass a run of another agent")
        if not ours:
            raise ConfigError(f"--agent-run {folder}: its runs are on {task}, on which this "
                              "suite has no RL results; pass a run on this suite's tasks")
        if len(theirs) > 1:
            raise ConfigError(f"--agent-run {folder}: its {task} × {agent} runs are at several "
                              f"budgets {sorted(theirs)}; pass a run at one budget")
    return other


def longer_results(folder: str | Path, base: Results) -> Results:
    """The results in ``folder`` (a leaderboard folder, or its ``records/``) of the same task ×
    agent as ``base`` trained for more steps: the 10k-vs-longer checks of ``robustness.csv``.

    Raises ConfigError (one line) when the folder holds no RL records, or its runs are of a
    task × agent ``base`` has none of, or are not longer than ``base``'s.
    """
    longer = _companion_results(folder, "--longer", "leaderboards/quick/longer",
                                "a longer-budget run")
    for task, agent in sorted({(r["task"], r["agent"]) for r in longer.rl_rows}):
        ours = [int(r["train_steps"]) for r in base.rl_rows
                if r["task"] == task and r["agent"] == agent]
        theirs = [int(r["train_steps"]) for r in longer.rl_rows
                  if r["task"] == task and r["agent"] == agent]
        if not ours:
            raise ConfigError(f"--longer {folder}: its runs are {task} × {agent}, of which this "
                              "suite has no RL results; pass a longer run of this suite's "
                              "task × agent")
        if max(theirs) <= max(ours):
            raise ConfigError(f"--longer {folder}: its {task} × {agent} runs are "
                              f"{max(theirs)} steps, not longer than this suite's {max(ours)}; "
                              "pass the leaderboard of a longer-budget run")
    return longer


@leaves_no_store_on_refusal
def rebuild_leaderboards(suite: str | Path, *, store: str | Path | None = None,
                         out: str | Path | None = None,
                         records: str | Path | Sequence[str | Path] | None = None,
                         longer: str | Path | None = None,
                         agent_run: str | Path | None = None,
                         predictions: str | Path | Sequence[str | Path] | None = None,
                         copy_records: bool = True,
                         scores: str | Path | Sequence[str | Path] | None = None) -> Path:
    """Write the leaderboards of ``suite`` from what the store holds; computes nothing.

    With ``records`` (a folder of record files, e.g. ``leaderboards/smoke/records``, or
    several: e.g. one per task) they are computed from those records alone, without a store.
    With ``longer`` (the leaderboard folder of the same task × agent trained for longer, e.g.
    ``leaderboards/quick/longer``) ``robustness.csv`` gets the budget rows
    (:func:`longer_results`); with ``agent_run`` (another agent at this budget, e.g.
    ``leaderboards/quick/ddpg``) the agent-agreement rows (:func:`agent_run_results`); with
    ``predictions`` (a folder of pre-registered ``<task id>.csv``, e.g.
    ``leaderboards/quick/predictions``, or several) the prediction rows
    (:func:`load_predictions`). ``copy_records=False`` (only with ``records``) leaves the records
    in their folders, which ``provenance.json`` names, instead of copying them into
    ``<out>/records``: a board built from another board's records (one task of quick, say) then
    does not store them twice. With ``scores`` (a folder ``repbench score-metric --out`` wrote,
    or several) the metrics scored there are ranked with the records' own (:func:`add_scores`).
    """
    s = load_suite(suite)
    if not copy_records and records is None:
        raise ConfigError("not copying the records needs --records: a board built from the store "
                          "has no record files elsewhere to point to; drop --no-copy-records")
    out_dir = check_out_dir(out if out is not None else default_out_dir(s.name))
    score_folders = [scores] if isinstance(scores, (str, Path)) else list(scores or [])
    if score_folders:  # a bad folder is refused before the records are read
        from repbench.pipeline.scores import read_scores

        for folder in score_folders:
            read_scores(folder)
    if records is not None:
        folders = [records] if isinstance(records, str | Path) else list(records)
        where = f"records folder {', '.join(map(str, folders))}"
        problems: list[str] = []
        found = [r for f in folders
                 for r in records_of_suite(load_records(f, problems=problems), s, f)]
        results = results_of(build_plan(s), found, problems)
        if not copy_records:
            results.provenance["records_folders"] = [
                os.path.relpath(Path(f).resolve(), out_dir.resolve()) for f in folders]
    else:
        st = Store(store)
        results = collect_results(build_plan(s), st)
        where = f"store {st.root}"
    if not (results.encoder_rows or results.metric_rows or results.rl_rows):
        raise RepbenchError(f"no results of suite {s.name!r} in {where}; run "
                            f"`repbench run --suite {suite}` with the same --store first")
    if score_folders:
        add_scores(results, score_folders, out_dir)
    extra = other = None
    if longer is not None:
        extra = longer_results(longer, results)
        results.provenance["longer"] = _companion_provenance(longer, extra)
    if agent_run is not None:
        other = agent_run_results(agent_run, results)
        results.provenance["agent_run"] = _companion_provenance(agent_run, other)
    folders = [predictions] if isinstance(predictions, (str, Path)) else list(predictions or [])
    preds = [p for f in folders for p in load_predictions(f, results)]
    return write_leaderboards(results, out_dir, longer=extra, agent_run=other,
                              predictions=preds, copy_records=copy_records)


def add_scores(results: Results, folders: Sequence[str | Path], out_dir: Path) -> None:
    """Add the metrics ``repbench score-metric`` scored into ``folders``
    (:func:`repbench.pipeline.scores.read_scores`) to ``results``: their rows of the task
    × encoders ``results`` has join its ``metric_rows`` (so the board ranks them with its own
    metrics, one multiplicity correction over all of them), their directions and groups its
    provenance's ``"directions"`` and ``"groups"``, and ``"scores"`` names each folder
    (relative to ``out_dir``) with the metrics and rows it added.

    Raises ConfigError (one line) for a scored metric the records also have, one metric in two
    folders, or a folder with no rows of the board's task × encoders.
    """
    from repbench.pipeline.scores import SCORES_MANIFEST, read_scores

    board = {(r["task"], r["encoder"])
             for rows in (results.metric_rows, results.rl_rows, results.encoder_rows)
             for r in rows}
    own = {r["metric"] for r in results.metric_rows}
    seen: dict[str, str | Path] = {}
    added: list[dict[str, Any]] = []
    for folder in folders:
        scored = read_scores(folder)
        for name in scored.directions:
            if name in own:
                raise ConfigError(f"metric {name} is both in the records and in --scores "
                                  f"{folder}; the board ranks a metric once: drop that folder "
                                  "or score the metric under another name")
            if name in seen:
                raise ConfigError(f"metric {name} is in --scores {seen[name]} and in --scores "
                                  f"{folder}; pass a folder of each metric once")
            seen[name] = folder
        rows = [r for r in scored.rows if (r["task"], r["encoder"]) in board]
        if not rows:
            tasks = sorted({t for t, _ in board})
            raise ConfigError(f"--scores {folder} has no rows of this board's tasks × encoders "
                              f"({', '.join(tasks)}); score the metrics against this suite's "
                              "latents or drop that folder")
        if not scored.manifest:
            note = (f"--scores {folder} was written before {SCORES_MANIFEST} existed and kept "
                    "no bootstrap replicates: the intervals of its metrics "
                    f"({', '.join(scored.directions)}) leave out their own estimation noise; "
                    "rescore them with `repbench score-metric` to include it")
            log.warning("%s", note)
            results.warnings.append(note)
        results.metric_rows += rows
        results.provenance.setdefault("directions", {}).update(scored.directions)
        results.provenance.setdefault("groups", {}).update(scored.groups)
        added.append({
            "folder": os.path.relpath(Path(folder).resolve(), out_dir.resolve()),
            "metrics": list(scored.directions),
            "rows": len(rows), "rows_off_board": len(scored.rows) - len(rows),
            "bootstrap_replicates": any(r["extras"] for r in rows),
            "manifest": scored.manifest})
    results.provenance["scores"] = added


def load_predictions(folder: str | Path, results: Results) -> list[pd.DataFrame]:
    """The pre-registered predictions (``<task id>.csv``,
    :data:`repbench.analysis.transfer.COLUMNS`, each with its ``<task id>.note`` if there is
    one) in ``folder`` of the tasks ``results`` has; one-line errors for a folder without any or
    a file without the columns."""
    from repbench.analysis.transfer import COLUMNS, read_prediction

    path = Path(folder)
    files = sorted(path.glob("*.csv")) if path.is_dir() else []
    if not files:
        raise ConfigError(f"--predictions {folder}: no <task id>.csv files there (e.g. "
                          "leaderboards/quick/predictions)")
    tasks = {r["task"] for r in results.metric_rows}
    out = []
    for f in files:
        table = read_prediction(f)
        lacking = [c for c in COLUMNS if c not in table.columns]
        if lacking or table.empty:
            raise ConfigError(f"--predictions: {f} is not a prediction table (missing "
                              f"{', '.join(lacking) or 'rows'}); make it with "
                              "studies/predictions/predict.py")
        if table["task"].iloc[0] in tasks:
            out.append(table)
    return out
