"""Score a metric against a reference without training or RL: ``repbench score-metric``.

The reference ships every encoder's latents (:mod:`repbench.analysis.latent_sets`) beside its
records. A metric — registered, or a plain function in a file with the signature the built-in
metrics have (:mod:`repbench.metric`) — is computed on every shipped latent set exactly as the
metric stage of a run computes it (:func:`repbench.latent_metrics.compute_on_latents`: the same
rows, arrays, parameters and seed, one thread), then ranked with the reference's own metrics
against the reference's RL returns (:func:`repbench.report.leaderboard.metric_ranking`: within-
learned and all-encoder Spearman ρ with encoder × seed bootstrap intervals, Holm and BH p over
every metric of the task, and the noise ceiling). This is an analysis over shipped files beside
``repbench leaderboard``; it runs no stage and writes no store.

Its ``--out`` folder (``scored.json``, :data:`SCORES_MANIFEST`, says which metrics it scored,
with their direction and group) is read back by :func:`read_scores`: ``repbench leaderboard
--scores DIR`` ranks the scored metrics on the board beside the records' own.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import json
import os
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from repbench.analysis.latent_sets import LatentSet, read_latent_sets
from repbench.analysis.results import Results, build_results, load_records
from repbench.errors import ConfigError, PluginError
from repbench.latent_metrics import compute_on_latents
from repbench.metric_types import Metric, MetricResult
from repbench.pipeline.evaluate import reference_dirs
from repbench.pipeline.scores import (
    SCORES_FORMAT,
    SCORES_MANIFEST,
    SCORES_VERSION,
    ScoredMetrics,
    metric_slug,
    read_scores,
)
from repbench.pipeline.suite import load_suite
from repbench.references import import_reference, is_reference
from repbench.registry import metrics

__all__ = ["SCORES_FORMAT", "SCORES_MANIFEST", "SCORES_VERSION", "MetricScore", "ScoredMetrics",
           "latents_dir", "read_scores", "resolve_metric", "score_metric", "score_metrics"]

#: A metric slower than this per latent set (seconds, measured on the first) is computed on
#: the rest in worker processes.
PARALLEL_ABOVE_S = 0.5
#: The folder of shipped latents beside a suite's reference records.
LATENTS_FOLDER = "latents"


@dataclass
class MetricScore:
    """What :func:`score_metric` found.

    Attributes:
        metric: the scored metric's name (as on the board).
        row: its rows of ``metrics.csv`` (one per task × agent), with ``rank`` among the
            metrics of that task × agent (1 = best within-learned ρ) and ``n_metrics``.
        ranking: every metric's rows on the same encoders, the scored one included.
        values: the metric per task × encoder (``metric``, ``value``, ``ci_low``, ``ci_high``,
            ``time_s``).
        out_dir: where the tables and the figure were written (None when not written).
        seconds: wall time of the whole scoring.
        results: the reference's results on the shipped encoders, the scored metrics' rows in
            place of any records of the same name.
    """

    metric: str
    row: pd.DataFrame
    ranking: pd.DataFrame
    values: pd.DataFrame
    out_dir: Path | None
    seconds: float
    results: Results | None = None


def latents_dir(suite_name: str, latents: str | Path | None = None) -> Path:
    """The shipped latents of ``suite_name``: ``latents`` if given, else
    ``leaderboards/<suite>/latents`` in ``./`` or in repbench's source checkout."""
    if latents is not None:
        if not Path(latents).is_dir():
            raise ConfigError(f"latents folder {latents} does not exist")
        return Path(latents)
    roots = [Path("leaderboards") / suite_name,
             Path(__file__).resolve().parents[2] / "leaderboards" / suite_name]
    for root in roots:
        if (root / LATENTS_FOLDER / "manifest.json").is_file():
            return root / LATENTS_FOLDER
    raise ConfigError(f"suite {suite_name!r} ships no latents (looked in "
                      f"{', '.join(str(r / LATENTS_FOLDER) for r in roots)}); pass --latents DIR "
                      "or score against a suite that ships them (quick)")


def resolve_metric(reference: str, higher_is_better: bool | None = None,
                   observable: bool = False) -> Metric:
    """The metric named ``reference``: a registered name, or ``file.py:name`` /
    ``module:name`` of a :class:`~repbench.metric.Metric` (``@repbench.metric(...,
    register=False)``) or of a plain function ``fn(z, z_true, episode, rng, **kw)`` returning a
    :class:`~repbench.metric.MetricResult` or a number. A plain function's direction is
    ``higher_is_better`` (default True), its group ``observable`` or (default) ``privileged``
    (:data:`repbench.metric.GROUPS`)."""
    if not is_reference(reference):
        return metrics.get(reference)
    obj = import_reference(reference)
    if isinstance(obj, Metric):
        return obj
    if not callable(obj):
        raise PluginError(f"{reference!r} is not a function; a metric is "
                          "fn(z, z_true, episode, rng, **params) -> MetricResult")
    direction = True if higher_is_better is None else bool(higher_is_better)
    name = reference.rpartition(":")[2]

    @functools.wraps(obj)
    def as_result(z: Any, z_true: Any, episode: Any, rng: Any, **kw: Any) -> MetricResult:
        out = obj(z, z_true, episode, rng, **kw)
        if isinstance(out, MetricResult):
            if out.higher_is_better != direction:
                raise ConfigError(
                    f"metric {reference!r} says higher_is_better={out.higher_is_better}; "
                    f"pass {'--higher-is-better' if out.higher_is_better else '--lower-is-better'}"
                    " to score it")
            return out
        if isinstance(out, (int, float, np.number)) and not isinstance(out, bool):
            return MetricResult(float(out), direction)
        raise PluginError(f"metric {reference!r} returned {type(out).__name__}; return a "
                          "MetricResult or a number")

    return Metric(as_result, name, direction,
                  group="observable" if observable else "privileged")


def _params(fn: Metric, suite: Any, name: str) -> dict[str, Any]:
    """The parameters a run of ``suite`` gives metric ``name``: its ``n_bootstrap`` (when the
    metric takes it) and its ``metric_params``."""
    sig = inspect.signature(fn.fn).parameters
    takes_any = any(p.kind == p.VAR_KEYWORD for p in sig.values())
    params: dict[str, Any] = {}
    if "n_bootstrap" in sig or takes_any:
        params["n_bootstrap"] = suite.metric_settings.bootstrap
    params.update(suite.metric_params.get(name, {}))
    return params


def _compute(reference: str, higher_is_better: bool | None, latent_set: LatentSet,
             seed: int, params: Mapping[str, Any], name: str,
             observable: bool = False) -> dict[str, Any]:
    """One latent set's metric values (in a worker process too: the metric is resolved from
    its reference there), with one thread as a run's metric stage has."""
    from repbench.devices import torch_threads

    fn = resolve_metric(reference, higher_is_better, observable)
    with torch_threads(1, blas=True):
        return compute_on_latents(fn, latent_set.arrays(), seed=seed, params=params,
                                  who=f"metric {name!r} on {latent_set.task} "
                                      f"{latent_set.encoder}")


def _compute_all(reference: str, higher_is_better: bool | None, sets: Sequence[LatentSet],
                 seed: int, params: Mapping[str, Any], name: str, workers: int,
                 echo: Callable[[str], None] | None, progress: bool,
                 observable: bool = False) -> list[dict[str, Any]]:
    from tqdm.auto import tqdm

    bar = tqdm(total=len(sets), desc=f"score {name}", unit="set", disable=not progress,
               leave=False)
    out = [_compute(reference, higher_is_better, sets[0], seed, params, name, observable)]
    bar.update()
    first = float(out[0]["time_s"])  # the metric's own time, not the files' first read
    rest = list(sets[1:])
    if rest and workers > 1 and first > PARALLEL_ABOVE_S:
        if echo is not None:
            echo(f"{name}: {first:.1f} s per latent set; {len(rest)} more on {workers} workers")
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = [pool.submit(_compute, reference, higher_is_better, s, seed,
                                   dict(params), name, observable) for s in rest]
            for f in futures:
                out.append(f.result())
                bar.update()
    else:
        for s in rest:
            out.append(_compute(reference, higher_is_better, s, seed, params, name, observable))
            bar.update()
    bar.close()
    return out


def _on_shipped_encoders(res: Results, shipped: set[tuple[str, str]]) -> None:
    """Keep ``res``'s metric and RL rows of the task × encoders whose latents are shipped, so
    every metric is ranked on the same encoders."""
    res.metric_rows = [r for r in res.metric_rows if (r["task"], r["encoder"]) in shipped]
    res.rl_rows = [r for r in res.rl_rows if (r["task"], r["encoder"]) in shipped]


def score_metric(metric: str, suite: str = "quick", *,
                 reference: str | Path | Sequence[str | Path] | None = None,
                 latents: str | Path | None = None, tasks: Sequence[str] | None = None,
                 workers: int | None = None, out: str | Path | None = None,
                 higher_is_better: bool | None = None, observable: bool = False,
                 n_bootstrap: int = 1000, echo: Callable[[str], None] | None = None,
                 progress: bool = True) -> MetricScore:
    """Score ``metric`` against ``suite``'s reference (module docstring).

    Args:
        metric: a registered metric name, or ``path/to/file.py:fn`` / ``module:fn``.
        reference: reference records folder(s) (default: the suite's, as ``evaluate``).
        latents: shipped latents folder (default ``leaderboards/<suite>/latents``).
        tasks: only these tasks (default: every task with shipped latents).
        workers: processes for a slow metric (default: the CPU count).
        out: folder for ``metrics.csv`` (every metric on the shipped encoders),
            ``<metric>.csv`` (its rows), ``<metric>_values.csv`` (and
            ``<metric>_replicates.json``, its bootstrap replicates where it has them),
            ``figures/<metric>_vs_return.png`` and :data:`SCORES_MANIFEST`, which
            ``repbench leaderboard --scores`` reads (:func:`read_scores`); None writes nothing.
        higher_is_better: a plain function's direction (default True).
        observable: a plain function reads only what a real robot logs (its ``group``).
        n_bootstrap: bootstrap resamples for the correlation intervals.
    """
    return score_metrics([metric], suite, reference=reference, latents=latents, tasks=tasks,
                         workers=workers, out=out, higher_is_better=higher_is_better,
                         observable=observable, n_bootstrap=n_bootstrap, echo=echo,
                         progress=progress)


def score_metrics(metric_refs: Sequence[str], suite: str = "quick", *,
                  reference: str | Path | Sequence[str | Path] | None = None,
                  latents: str | Path | None = None, tasks: Sequence[str] | None = None,
                  workers: int | None = None, out: str | Path | None = None,
                  higher_is_better: bool | None = None, observable: bool = False,
                  n_bootstrap: int = 1000, echo: Callable[[str], None] | None = None,
                  progress: bool = True) -> MetricScore:
    """Score several metrics at once, ranked together with the reference's own metrics in one
    ranking (so the multiplicity correction covers all of them): as :func:`score_metric`, with
    ``metric`` the comma-joined names and ``row`` / ``values`` holding every scored metric's
    rows (column ``metric``)."""
    start = time.time()
    if not metric_refs:
        raise ConfigError("no metric to score; name at least one")
    s = load_suite(suite)
    fns = [resolve_metric(m, higher_is_better, observable) for m in metric_refs]
    names = [fn.name for fn in fns]
    if len(set(names)) < len(names):
        raise ConfigError(f"metrics {', '.join(names)} name one metric twice; name each once")
    folder = latents_dir(s.name, latents)
    sets = read_latent_sets(folder, tasks)
    if not sets:
        raise ConfigError(f"no shipped latents of task(s) {', '.join(tasks or [])} in {folder}; "
                          "tasks there: " + ", ".join(sorted(
                              {x.task for x in read_latent_sets(folder)})))
    records = load_records(*reference_dirs(s.name, reference))
    res = build_results(records, suite=s)
    shipped = {(x.task, x.encoder) for x in sets}
    _on_shipped_encoders(res, shipped)
    if not res.rl_rows:
        raise ConfigError(f"the reference of suite {s.name!r} has no RL records of the encoders "
                          f"whose latents are in {folder}; nothing to score against")
    res.metric_rows = [r for r in res.metric_rows if r["metric"] not in names]
    value_rows: list[dict[str, Any]] = []
    for ref, fn, name in zip(metric_refs, fns, names, strict=True):
        values = _compute_all(ref, higher_is_better, sets, s.metric_settings.seed,
                              _params(fn, s, name), name, workers or os.cpu_count() or 1, echo,
                              progress, observable)
        res.metric_rows += [
            {"task": x.task, "encoder": x.encoder, "metric": name, **v, "stage_cpu_s": None}
            for x, v in zip(sets, values, strict=True)]
        res.provenance.setdefault("directions", {})[name] = fn.higher_is_better
        res.provenance.setdefault("groups", {})[name] = fn.group
        value_rows += [
            {"task": x.task, "encoder": x.encoder, "metric": name,
             **{k: v.get(k) for k in ("value", "ci_low", "ci_high", "time_s")}}
            for x, v in zip(sets, values, strict=True)]
    from repbench.report.leaderboard import metric_ranking

    ranking, _ = metric_ranking(res, n_bootstrap=n_bootstrap)
    ranking = _ranked(ranking)  # the scored metrics' groups: res.provenance["groups"]
    row = ranking[ranking["metric"].isin(names)].reset_index(drop=True)
    table = pd.DataFrame(value_rows)  # one frame: no concat of an all-empty CI column
    out_dir = None
    if out is not None:
        scored = [{"name": name, "reference": str(ref), "higher_is_better": fn.higher_is_better,
                   "group": fn.group} for ref, fn, name in zip(metric_refs, fns, names,
                                                               strict=True)]
        out_dir = _write(Path(out), scored, row, ranking, table, res)
    return MetricScore(",".join(names), row, ranking, table, out_dir, time.time() - start,
                       res)


def _ranked(ranking: pd.DataFrame) -> pd.DataFrame:
    """Add ``rank`` (1 = the largest within-learned ρ of its task × agent) and ``n_metrics``."""
    if ranking.empty:
        return ranking
    ranking = ranking.copy()
    group = ranking.groupby(["task", "agent"])["spearman_learned"]
    ranking["rank"] = group.rank(ascending=False, method="min").astype("Int64")
    ranking["n_metrics"] = group.transform("size")
    return ranking


def _write(out: Path, scored: Sequence[dict[str, Any]], row: pd.DataFrame,
           ranking: pd.DataFrame, values: pd.DataFrame, res: Results) -> Path:
    """Write the tables, figures and :data:`SCORES_MANIFEST` of the ``scored`` metrics (name,
    reference, higher_is_better, group) to ``out``. ``<metric>_values.csv`` keeps every digit
    and ``<metric>_replicates.json`` (task → encoder → the metric's bootstrap replicates, where
    it has them) what the ranking's intervals resampled, so that :func:`read_scores` gives a
    board the very rows ranked here."""
    from repbench.report.figures import metric_vs_return
    from repbench.report.leaderboard import metric_table

    out.mkdir(parents=True, exist_ok=True)
    ranking.to_csv(out / "metrics.csv", index=False, float_format="%.6g")
    (out / "figures").mkdir(exist_ok=True)
    entries = []
    for entry in scored:
        name = entry["name"]
        slug = metric_slug(name)
        mine = row[row["metric"] == name]
        mine.to_csv(out / f"{slug}.csv", index=False, float_format="%.6g")
        values[values["metric"] == name].drop(columns="metric").to_csv(
            out / f"{slug}_values.csv", index=False)  # every digit: the board reads them back
        only = dataclasses.replace(res, metric_rows=[r for r in res.metric_rows
                                                     if r["metric"] == name])
        replicates: dict[str, dict[str, list[float]]] = {}
        for r in only.metric_rows:
            reps = (r.get("extras") or {}).get("bootstrap_replicates")
            if reps:
                replicates.setdefault(r["task"], {})[r["encoder"]] = [float(v) for v in reps]
        files = {"rows": f"{slug}.csv", "values": f"{slug}_values.csv"}
        if replicates:
            files["replicates"] = f"{slug}_replicates.json"
            (out / files["replicates"]).write_text(json.dumps(replicates), encoding="utf-8")
        else:
            (out / f"{slug}_replicates.json").unlink(missing_ok=True)
        entries.append({**entry, "files": files})
        titles = mine.merge(metric_table(only), on=["task", "agent", "metric"], how="left")
        metric_vs_return(only, out / "figures" / f"{slug}_vs_return.png", titles)
    manifest = {"format": SCORES_FORMAT, "version": SCORES_VERSION, "metrics": entries}
    (out / SCORES_MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n", encoding="utf-8")
    return out
