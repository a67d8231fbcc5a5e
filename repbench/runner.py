"""``repbench run`` and ``repbench leaderboard``: plan a suite, run what is missing, write the
leaderboards."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

from repbench.errors import ConfigError, RepbenchError
from repbench.executors import RunReport, make_executor, run_stages
from repbench.leaderboard import write_leaderboards
from repbench.plan import Plan, build_plan
from repbench.preflight import check_out_dir
from repbench.records import identity_key
from repbench.results import Results, build_results, installed_versions, load_records, select
from repbench.store import Store
from repbench.suite import load_suite


@dataclass
class RunResult:
    out_dir: Path
    report: RunReport
    results: Results
    seconds: float


def default_out_dir(suite_name: str) -> Path:
    return Path("leaderboards") / suite_name


def run_suite(suite: str | Path, *, store: str | Path | None = None, out: str | Path | None = None,
              executor: str = "local", workers: int | None = None,
              ray_address: str | None = None, progress: bool = True) -> RunResult:
    """Run every missing stage of ``suite`` and write its leaderboards.

    Raises :class:`repbench.errors.RepbenchError` for a bad suite/plugin/parameter before any
    work starts. Stages that fail are reported; the leaderboards show what finished.
    """
    start = time.time()
    check_workers(workers)
    s = load_suite(suite)
    out_dir = check_out_dir(out if out is not None else default_out_dir(s.name))
    st = Store(store)
    plan = build_plan(s)
    stages = plan.stages()
    n_workers = workers or min(os.cpu_count() or 1, 8)
    ex = make_executor(executor, str(st.root), n_workers, ray_address)
    print(f"suite {s.name}: {len(stages)} stages ({len(s.tasks)} tasks × {len(s.encoders)} "
          f"encoders × {len(s.metrics)} metrics, {len(s.agents)} agents × {len(s.seeds)} seeds); "
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
    wanted = {identity_key(s.record): s for s in plan.stages() if s.record is not None}
    records = [*load_records(store), *(extra_records or [])]
    installed = installed_versions(records)
    chosen = select(records, wanted, installed)
    found = {r["identity"] for r in chosen}
    missing = [s.label for i, s in wanted.items() if i not in found and s.kind in _SHOWN]
    order = {i: n for n, i in enumerate(wanted)}
    chosen.sort(key=lambda r: order.get(r["identity"], len(order)))
    return build_results(chosen, suite=plan.suite, missing=missing, installed=installed)


def check_workers(workers: int | None) -> None:
    """Raise ConfigError for a worker count below 1 (None means: size to the machine)."""
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}; leave it out to use "
                          "one worker per CPU core")


def rebuild_leaderboards(suite: str | Path, *, store: str | Path | None = None,
                         out: str | Path | None = None,
                         records: str | Path | None = None) -> Path:
    """Write the leaderboards of ``suite`` from what the store holds; computes nothing.

    With ``records`` (a folder of record files, e.g. ``leaderboards/smoke/records``) they are
    computed from those records alone, without a store or a plan.
    """
    s = load_suite(suite)
    out_dir = check_out_dir(out if out is not None else default_out_dir(s.name))
    if records is not None:
        found = load_records(records)
        installed = installed_versions(found)
        results = build_results(select(found, None, installed), suite=s, installed=installed)
        where = f"records folder {records}"
    else:
        st = Store(store)
        results = collect_results(build_plan(s), st)
        where = f"store {st.root}"
    if not (results.encoder_rows or results.metric_rows or results.rl_rows):
        raise RepbenchError(f"no results of suite {s.name!r} in {where}; run "
                            f"`repbench run --suite {suite}` with the same --store first")
    return write_leaderboards(results, out_dir)
