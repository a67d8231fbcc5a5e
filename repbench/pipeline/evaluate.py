"""``repbench evaluate ENCODER``: place one new encoder on a suite's reference leaderboard.

Computes only that encoder's stages (the suite's datasets and privileged full-state agent are
reused from the store or regenerated deterministically from their seeds), merges its records
with the reference records shipped in ``leaderboards/<suite>/records/``, and writes a leaderboard
with the new encoder highlighted. ``metrics_only`` skips its RL runs and predicts its return
from the reference calibration (:mod:`repbench.analysis.calibration`) instead: minutes, not hours.

The new records are comparable with the reference only if they were computed on the same data:
the records' data identities and the dataset checksums are compared, and any difference is
printed and shown on the page.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from repbench.analysis.calibration import predict_from_rows
from repbench.analysis.results import (
    Results,
    build_results,
    installed_versions,
    load_records,
    select,
)
from repbench.errors import ConfigError
from repbench.pipeline.executors import RunReport, make_executor, run_stages
from repbench.pipeline.plan import build_plan
from repbench.pipeline.preflight import check_out_dir
from repbench.pipeline.records import identity_key
from repbench.pipeline.runner import records_of_suite
from repbench.pipeline.stages import RL
from repbench.pipeline.store import Store
from repbench.pipeline.suite import load_suite
from repbench.references import is_reference
from repbench.registry import encoders
from repbench.report.leaderboard import write_leaderboards


@dataclass
class EvaluateResult:
    out_dir: Path
    report: RunReport
    results: Results
    predictions: list[dict[str, Any]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0


def reference_dir(suite_name: str, reference: str | Path | None = None) -> Path:
    """Where the suite's reference records are: ``reference`` if given, else
    ``./leaderboards/<suite>/records``, else the one in repbench's source checkout."""
    if reference is not None:
        path = Path(reference)
        if not path.is_dir():
            raise ConfigError(f"reference records folder {path} does not exist")
        return path
    candidates = [Path("leaderboards") / suite_name / "records",
                  Path(__file__).resolve().parents[2] / "leaderboards" / suite_name / "records"]
    for path in candidates:
        if path.is_dir() and any(path.rglob("*.json")):
            return path
    raise ConfigError(f"no reference records for suite {suite_name!r} (looked in "
                      f"{', '.join(str(c) for c in candidates)}); pass --reference DIR, or run "
                      f"`repbench run --suite {suite_name}` to make them")


def _folder_name(encoder: str) -> str:
    """A folder name for ``encoder`` (``my_encoder.py:MyVAE`` → ``my_encoder-MyVAE``)."""
    if not is_reference(encoder):
        return encoder
    module, _, attr = encoder.rpartition(":")
    stem = Path(module).stem if module.endswith(".py") else module
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in f"{stem}-{attr}")


def evaluate_encoder(encoder: str, suite: str | Path = "smoke", *, metrics_only: bool = False,
                     store: str | Path | None = None, out: str | Path | None = None,
                     reference: str | Path | None = None, executor: str = "local",
                     workers: int | None = None, progress: bool = True,
                     tasks: Sequence[str] | None = None) -> EvaluateResult:
    """Compute ``encoder``'s stages of ``suite`` and write the merged leaderboard; with
    ``tasks``, on those of the suite's tasks only (and against their reference records)."""
    start = time.time()
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    if is_reference(encoder):
        encoders.get(encoder)  # a file or module reference: a bad one fails here, in one line
    elif encoder not in encoders:
        raise ConfigError(encoders._unknown_message(encoder))
    base = load_suite(suite)
    out_dir = check_out_dir(out if out is not None
                            else Path("leaderboards") / f"{base.name}-{_folder_name(encoder)}")
    ref_dir = reference_dir(base.name, reference)
    dropped: list[str] = []  # reference or new records left out (edited, truncated ...)
    reference_records = load_records(ref_dir, problems=dropped)
    if not reference_records:
        raise ConfigError(f"no readable records in {ref_dir}")
    reference_records = records_of_suite(reference_records, base, ref_dir,
                                         what="reference records folder")
    if tasks:
        unknown = [t for t in tasks if t not in base.tasks]
        if unknown:
            raise ConfigError(f"--task {unknown[0]} is not a task of suite {base.name} "
                              f"({', '.join(base.tasks)}); pass one of those")
        reference_records = [r for r in reference_records if r["task"]["name"] in tasks]
    one = (base.only_tasks(tasks) if tasks else base).model_copy(update={
        "encoders": [encoder], "encoder_params": {encoder: base.encoder_params.get(encoder, {})}})
    plan = build_plan(one)
    stages = [s for s in plan.stages() if not (metrics_only and s.kind == RL)]
    st = Store(store)
    ex = make_executor(executor, str(st.root), workers)
    print(f"evaluate {encoder} on suite {base.name}: {len(stages)} stages"
          f"{' (metrics only, no RL)' if metrics_only else ''}; reference records {ref_dir}; "
          f"store {st.root}", flush=True)
    report = run_stages(stages, st, ex, progress=progress)
    print(f"stages: {report.summary()}", flush=True)

    wanted = {identity_key(s.record): s for s in stages if s.record is not None}
    new_records = select(load_records(st, problems=dropped), wanted)
    ours = [r for r in new_records if (r.get("encoder") or {}).get("name") == encoder]
    shared = [r for r in new_records if not r.get("encoder")]  # datasets, diagnostics, agent
    warnings = _compare_data(ours + shared, reference_records)
    others = [r for r in reference_records if (r.get("encoder") or {}).get("name") != encoder]
    records = others + ours
    installed = installed_versions(records)
    res = build_results(select(records, None, installed), suite=base, installed=installed,
                        missing=[s.label for i, s in wanted.items()
                                 if s.kind in ("encoder", "metric", "rl")
                                 and i not in {r["identity"] for r in ours}])
    res.highlight = [encoder]
    res.warnings = [*dropped, *warnings]
    res.provenance["evaluated"] = {"encoder": encoder, "metrics_only": metrics_only,
                                   "reference_records": str(ref_dir),
                                   "n_reference_records": len(reference_records)}
    if metrics_only:
        from repbench.analysis.robustness import validated_method
        from repbench.report.families import encoder_families

        res.predictions = predict_from_rows(res.metric_rows, res.rl_rows, encoder,
                                            families=encoder_families(res),
                                            choose=validated_method)
        res.provenance["evaluated"]["predictions"] = res.predictions
    write_leaderboards(res, out_dir)
    for w in warnings:
        print(f"warning: {w}", flush=True)
    for p in res.predictions:
        print(f"predicted {p['agent']} return of {encoder} on {p['task']}: "
              f"{p['predicted_return']:.4g} [{p['ci_low']:.4g}, {p['ci_high']:.4g}] from "
              f"{p['predictor']} ({p['n_reference']} reference encoders)", flush=True)
        if p.get("measured_coverage") is not None:
            lo, hi = p["coverage_ci"]
            print(f"  interval: {p['method']}; measured out of sample (one family of reference "
                  f"encoders held out at a time): coverage {p['measured_coverage']:.0%} "
                  f"[{lo:.0%}, {hi:.0%}], median half-width ±{p['median_half_width']:.0f}",
                  flush=True)
        if p.get("method_warning"):
            print(f"warning: {p['method_warning']}", flush=True)
    if report.failed:
        for i, err in report.failed.items():
            print(f"  FAILED {report.labels[i]}: {err}", flush=True)
    return EvaluateResult(out_dir, report, res, res.predictions, warnings, time.time() - start)


def _compare_data(new: list[dict[str, Any]], reference: list[dict[str, Any]]) -> list[str]:
    """Differences between the data the new records used and the reference data."""
    out = []
    ref_data = {(r["task"]["name"], _freeze(r.get("data"))) for r in reference
                if r["kind"] == "metric"}
    for r in new:
        if r["kind"] == "metric" and ref_data and (
                (r["task"]["name"], _freeze(r.get("data"))) not in ref_data):
            out.append(f"the suite's data settings for {r['task']['name']} differ from those of "
                       "the reference records (the suite changed since they were made); the new "
                       "encoder's metrics are not comparable with the reference")
            break
    ref_sums: dict[tuple[str, str], set[str]] = {}
    for r in reference:
        for name, digest in (r.get("data_checksums") or {}).items():
            if digest:
                ref_sums.setdefault((r["task"]["name"], name), set()).add(digest)
    for r in new:
        for name, digest in (r.get("data_checksums") or {}).items():
            known = ref_sums.get((r["task"]["name"], name))
            if digest and known and digest not in known:
                msg = (f"the regenerated {name} dataset of {r['task']['name']} differs from the "
                       "reference data (checksum); simulator or library versions differ, so "
                       "compare with care")
                if msg not in out:
                    out.append(msg)
    return out


def _freeze(value: Any) -> str:
    import json

    return json.dumps(value, sort_keys=True)
