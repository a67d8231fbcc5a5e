"""``repbench evaluate ENCODER``: place one new encoder on a suite's reference leaderboard.

Computes only that encoder's stages (the suite's datasets and privileged full-state agent are
reused from the store or regenerated deterministically from their seeds), merges its records
with the reference records shipped in ``leaderboards/<suite>/`` (the folders its
``reference.toml`` lists, else ``records/``), and writes a leaderboard with the new
encoder highlighted. ``metrics_only`` skips its RL runs and predicts its return
from the reference calibration (:mod:`repbench.analysis.calibration`) instead: minutes, not hours.

The new records are comparable with the reference only if they were computed on the same data:
the records' data identities and the dataset checksums are compared, and any difference is
printed and shown on the page.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from repbench import _toml as toml
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
from repbench.pipeline.preflight import check_dataset_sizes, check_out_dir
from repbench.pipeline.records import identity_key
from repbench.pipeline.runner import cap_local_workers, records_of_suite, suite_on_tasks
from repbench.pipeline.stages import RL
from repbench.pipeline.store import Store, leaves_no_store_on_refusal
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


#: The manifest in ``leaderboards/<suite>/`` that lists a suite's reference records folders
#: (``records = ["records", "b/records"]``, relative to the manifest).
REFERENCE_MANIFEST = "reference.toml"


def reference_dirs(suite_name: str,
                   reference: str | Path | Sequence[str | Path] | None = None) -> list[Path]:
    """Where the suite's reference records are: the ``reference`` folder(s) if given, else the
    folders that ``leaderboards/<suite>/reference.toml`` lists, else
    ``leaderboards/<suite>/records``; looked for in ``./`` first, then in repbench's source
    checkout."""
    if reference is not None and not isinstance(reference, (str, Path)) and not reference:
        reference = None
    if reference is not None:
        paths = [Path(reference)] if isinstance(reference, (str, Path)) else \
            [Path(r) for r in reference]
        for path in paths:
            if not path.is_dir():
                raise ConfigError(f"reference records folder {path} does not exist")
        return paths
    roots = [Path("leaderboards") / suite_name,
             Path(__file__).resolve().parents[2] / "leaderboards" / suite_name]
    for root in roots:
        if (root / REFERENCE_MANIFEST).is_file():
            return _manifest_dirs(root / REFERENCE_MANIFEST)
        if (root / "records").is_dir() and any((root / "records").rglob("*.json")):
            return [root / "records"]
    raise ConfigError(f"no reference records for suite {suite_name!r} (looked in "
                      f"{', '.join(str(r / 'records') for r in roots)}); pass --reference DIR, "
                      f"or run `repbench run --suite {suite_name}` to make them")


def _manifest_dirs(manifest: Path) -> list[Path]:
    """The records folders a reference manifest lists, each checked to exist."""
    try:
        folders = toml.loads(manifest.read_text())["records"]
    except (toml.TOMLDecodeError, KeyError) as exc:
        raise ConfigError(f"{manifest} must hold records = [\"folder\", ...] (the reference "
                          f"records folders, relative to it): {exc}") from exc
    if not isinstance(folders, list) or not folders \
            or not all(isinstance(f, str) for f in folders):
        raise ConfigError(f"{manifest}: records must be a non-empty list of folder names, "
                          f"got {folders!r}")
    paths = [manifest.parent / f for f in folders]
    for path in paths:
        if not path.is_dir():
            raise ConfigError(f"{manifest} lists reference records folder {path}, which does "
                              "not exist; fix the list or restore the folder")
    return paths


def check_not_reference_board(out_dir: Path, ref_dirs: Sequence[Path], suite_name: str,
                              encoder: str) -> None:
    """Raise ConfigError when the leaderboard folder ``out_dir`` would overwrite the reference
    board: it is one of the reference records folders ``ref_dirs`` or lies inside one, it holds
    one (``leaderboards/quick`` for ``leaderboards/quick/records``; an ancestor of it), or it lies
    inside the board that holds one (``leaderboards/quick/door``). Writing there would replace
    the reference board's pages and add ``encoder``'s records to the reference records."""
    out = out_dir.expanduser().resolve()
    for ref in ref_dirs:
        ref = ref.expanduser().resolve()
        board = ref.parent if ref.name == "records" else ref  # a board keeps records/ inside
        if out.is_relative_to(board) or ref.is_relative_to(out):
            raise ConfigError(
                f"--out {out_dir} would write over the reference board of suite {suite_name} "
                f"(its records are in {ref}) and add {encoder} to its reference records; choose "
                f"another --out, e.g. leaderboards/{suite_name}-{_folder_name(encoder)}")


def _folder_name(encoder: str) -> str:
    """A folder name for ``encoder`` (``my_encoder.py:MyVAE`` → ``my_encoder-MyVAE``)."""
    if not is_reference(encoder):
        return encoder
    module, _, attr = encoder.rpartition(":")
    stem = Path(module).stem if module.endswith(".py") else module
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in f"{stem}-{attr}")


@leaves_no_store_on_refusal
def evaluate_encoder(encoder: str, suite: str | Path = "smoke", *, metrics_only: bool = False,
                     store: str | Path | None = None, out: str | Path | None = None,
                     reference: str | Path | Sequence[str | Path] | None = None,
                     executor: str = "local",
                     workers: int | None = None, progress: bool = True,
                     tasks: Sequence[str] | None = None,
                     predictors: Sequence[str] | None = None) -> EvaluateResult:
    """Compute ``encoder``'s stages of ``suite`` and write the merged leaderboard; with
    ``tasks``, on those of the suite's tasks only (and against their reference records).

    With ``metrics_only`` the return is predicted from the metrics; ``predictors`` restricts
    the metrics the prediction may use (default: every metric of the suite, the calibration
    picking among them), its held-out coverage measured under the same restriction."""
    start = time.time()
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    if is_reference(encoder):
        encoders.get(encoder)  # a file or module reference: a bad one fails here, in one line
    elif encoder not in encoders:
        raise ConfigError(encoders._unknown_message(encoder))
    base = load_suite(suite)
    unknown = sorted(set(predictors or ()) - set(base.metrics))
    if unknown:
        raise ConfigError(f"--predictor {', '.join(unknown)} is not a metric of suite "
                          f"{base.name!r}; choose among {', '.join(base.metrics)}")
    if predictors and not metrics_only:
        raise ConfigError("--predictor applies to --metrics-only (a prediction of the return); "
                          "add --metrics-only or drop --predictor")
    on_tasks = suite_on_tasks(base, tasks)
    out_dir = check_out_dir(out if out is not None
                            else Path("leaderboards") / f"{base.name}-{_folder_name(encoder)}")
    ref_dirs = reference_dirs(base.name, reference)
    check_not_reference_board(out_dir, ref_dirs, base.name, encoder)
    dropped: list[str] = []  # reference or new records left out (edited, truncated ...)
    reference_records = []
    for ref_dir in ref_dirs:
        found = load_records(ref_dir, problems=dropped)
        if not found:
            raise ConfigError(f"no readable records in {ref_dir}")
        reference_records += records_of_suite(found, base, ref_dir,
                                              what="reference records folder")
    reference_records = [r for r in reference_records if r["task"]["name"] in on_tasks.tasks]
    one = on_tasks.model_copy(update={
        "encoders": [encoder], "encoder_params": {encoder: base.encoder_params.get(encoder, {})}})
    plan = build_plan(one)
    stages = [s for s in plan.stages() if not (metrics_only and s.kind == RL)]
    st = Store(store)
    check_dataset_sizes(plan, st)
    ex = make_executor(executor, str(st.root), cap_local_workers(workers, executor))
    print(f"evaluate {encoder} on suite {base.name}: {len(stages)} stages"
          f"{' (metrics only, no RL)' if metrics_only else ''}; reference records "
          f"{', '.join(map(str, ref_dirs))}; "
          f"store {st.root}", flush=True)
    report = run_stages(stages, st, ex, progress=progress)
    print(f"stages: {report.summary()}", flush=True)

    wanted = {identity_key(s.record): s for s in stages if s.record is not None}
    new_records = select(load_records(st, problems=dropped), wanted)
    ours = [r for r in new_records if (r.get("encoder") or {}).get("name") == encoder]
    shared = [r for r in new_records if not r.get("encoder")]  # datasets, diagnostics, agent
    warnings = _compare_data(ours + shared, reference_records) + conformance_warnings(
        plan, st, encoder)
    others = [r for r in reference_records if (r.get("encoder") or {}).get("name") != encoder]
    records = others + ours
    installed = installed_versions(records)
    res = build_results(select(records, None, installed), suite=base, installed=installed,
                        missing=[s.label for i, s in wanted.items()
                                 if s.kind in ("encoder", "metric", "rl")
                                 and i not in {r["identity"] for r in ours}])
    res.highlight = [encoder]
    res.warnings = [*dropped, *warnings, *res.warnings]  # and those build_results found
    res.provenance["evaluated"] = {"encoder": encoder, "metrics_only": metrics_only,
                                   "predictors": list(predictors or ()),
                                   "reference_records": ", ".join(map(str, ref_dirs)),
                                   "n_reference_records": len({r["identity"]
                                                               for r in reference_records})}
    if metrics_only:
        from repbench.analysis.robustness import validated_method
        from repbench.report.families import encoder_families

        rows = [r for r in res.metric_rows if not predictors or r["metric"] in predictors]
        res.predictions = predict_from_rows(rows, res.rl_rows, encoder,
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


#: Rows of the task's data :func:`conformance_warnings` encodes twice.
CONFORMANCE_ROWS = 16


def conformance_warnings(plan: Any, store: Store, encoder: str) -> list[str]:
    """What ``check_encoder`` would flag in the trained ``encoder`` that a board must not publish
    without a word: ``encode`` not deterministic (two calls on the same rows differ) or
    modifying its input. Checked on :data:`CONFORMANCE_ROWS` rows of each task's metric data,
    with the encoder the stages trained; one warning per problem and task."""
    import copy

    import numpy as np

    from repbench.dataset import Dataset
    from repbench.encoder import Encoder
    from repbench.pipeline.stages import DATASET, ENCODER

    out = []
    for tp in plan.tasks:
        spec = tp.encoders.get(encoder)
        data_spec = tp.heldout_dataset or tp.random_dataset
        art = store.get(ENCODER, spec.key) if spec is not None else None
        data = store.get(DATASET, data_spec.key) if data_spec is not None else None
        if art is None or data is None:
            continue
        enc = Encoder.load(art.file("encoder.pt"))
        obs = Dataset.load(data.file("dataset.npz")).obs(slice(0, CONFORMANCE_ROWS))
        before = copy.deepcopy(obs)
        first = np.asarray(enc.encode(obs))
        changed = sorted(k for k in before if not np.array_equal(before[k], obs[k]))
        if changed:
            out.append(f"encoder {encoder!r} on {tp.task}: encode modified its input "
                       f"{', '.join(changed)}; its latents may not be what it computes on fresh "
                       f"data — repbench.testing.check_encoder({encoder!r}) says more")
        second = np.asarray(enc.encode(before))
        if first.shape != second.shape or not np.array_equal(first, second):
            gap = float(np.abs(first - second).max()) if first.shape == second.shape else \
                float("nan")
            out.append(f"encoder {encoder!r} on {tp.task}: encode is not deterministic (two "
                       f"calls on the same {CONFORMANCE_ROWS} rows differ by up to {gap:.3g}); "
                       "its metrics and RL are not reproducible — "
                       f"repbench.testing.check_encoder({encoder!r}) says more")
    return out


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
    ref_made: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for r in reference:
        for name, digest in (r.get("data_checksums") or {}).items():
            if digest:
                ref_sums.setdefault((r["task"]["name"], name), set()).add(digest)
                ref_made.setdefault((r["task"]["name"], name), []).append(r)
    for r in new:
        for name, digest in (r.get("data_checksums") or {}).items():
            where = (r["task"]["name"], name)
            known = ref_sums.get(where)
            if digest and known and digest not in known:
                msg = (f"the regenerated {name} dataset of {r['task']['name']} differs from the "
                       f"reference data (checksum); {_why_data_differs(r, ref_made[where])}, so "
                       "compare with care")
                if msg not in out:
                    out.append(msg)
    return out


def _why_data_differs(new: Mapping[str, Any], reference: list[Mapping[str, Any]]) -> str:
    """What differs between the machine that made ``new`` and those that made ``reference``:
    library versions (named), the CPU model (named), or neither."""
    mine = new.get("library_versions") or {}
    theirs: dict[str, set[str]] = {}
    for r in reference:
        for lib, version in (r.get("library_versions") or {}).items():
            theirs.setdefault(lib, set()).add(str(version))
    changed = [f"{lib} {mine[lib]} here vs {' / '.join(sorted(theirs[lib]))} in the reference"
               for lib in sorted(mine) if lib in theirs and str(mine[lib]) not in theirs[lib]]
    cpu = new.get("cpu")
    ref_cpus = sorted({str(r["cpu"]) for r in reference if r.get("cpu")})
    if not cpu or not ref_cpus:
        cpu_part = "CPU not recorded on both sides"
    elif cpu not in ref_cpus:
        cpu_part = f"CPU differs: {cpu} here vs {' / '.join(ref_cpus)} in the reference"
    else:
        cpu_part = ""
    if changed:
        why = f"simulator or library versions differ ({', '.join(changed)})"
        return f"{why}; {cpu_part}" if cpu_part else f"{why}; same CPU"
    if cpu_part.startswith("CPU differs"):
        return f"same versions; {cpu_part} — float results can differ across CPUs"
    if cpu_part:
        return f"same versions; {cpu_part}"
    return ("same versions and CPU (so not the machine: the task's data collection changed or "
            "is not deterministic)")


def _freeze(value: Any) -> str:
    import json

    return json.dumps(value, sort_keys=True)
