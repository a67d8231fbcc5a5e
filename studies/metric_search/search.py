"""The pre-registered metric search (``studies/metric_search/preregistration.md``), as fixed there.

Three steps, in this order, each refusing to run out of it:

``check``
    Is the reference complete? Every learned encoder of PegInHole-v0 and Door-v0 has its latents
    shipped and 3 SAC seeds of the shipped weights (the pre-registration runs on nothing less).
``select``
    Refuses unless PegInHole-v0's reference is complete (the 2026-12-08 amendment: the selection
    reads PegInHole-v0 only, so it need not wait for Door-v0's). The 12 candidates scored on
    the shipped latents beside the 11 metrics on the board (one ranking, Holm over all 23),
    then the selection rule — the best single metric,
    the best model of at most two by nested leave-one-encoder-out CV, the best observable
    metric. Writes ``selection.json`` and ``selection.md`` to ``--out``; commit them before
    ``test``.
``test``
    Door-v0, scored once: refuses unless ``selection.json`` is committed and unchanged since,
    and unless both tasks' reference is complete.
    The selected single metric, the selected combination (fitted on PegInHole-v0's ranks) and
    the best observable metric against ``task_cmi`` on the same bootstrap resamples; the
    leave-one-encoder-out RMSE that decides ``evaluate --metrics-only``. Writes ``test.json``
    and ``test.md``.

Run::

    python studies/metric_search/search.py check
    python studies/metric_search/search.py select --out studies/metric_search/results
    git add studies/metric_search/results && git commit -m "metric search: the selection"
    python studies/metric_search/search.py test --out studies/metric_search/results
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from repbench.analysis.latent_sets import read_manifest
from repbench.analysis.metric_search import (
    compare_on,
    loo_rmse,
    nested_selection,
    reference_gaps,
    transfer_model,
)
from repbench.analysis.results import build_results, load_records
from repbench.pipeline.evaluate import reference_dirs
from repbench.pipeline.score_metric import latents_dir, score_metrics
from repbench.pipeline.suite import load_suite
from repbench.registry import metrics
from repbench.report.families import learned_encoders

#: The pre-registered candidates, in the pre-registration's order.
CANDIDATES = ("rankme", "alpha_req", "nesum", "forward_r2", "inverse_r2", "value_probe",
              "value_probe_gain", "reward_probe_gain", "task_sdl", "task_eps_samples",
              "task_vinfo_linear", "task_cmi_gc")
SELECT_TASK, TEST_TASK = "PegInHole-v0", "Door-v0"
AGENT, BASELINE, N_SEEDS = "sac", "task_cmi", 3
SELECTION, TEST = "selection.json", "test.json"


def gaps(suite: str, latents: str | None = None, reference: Sequence[str] | None = None,
         tasks: Sequence[str] = (SELECT_TASK, TEST_TASK), n_seeds: int = N_SEEDS) -> list[str]:
    """What keeps ``suite``'s reference from being complete on ``tasks`` (empty: complete)."""
    s = load_suite(suite)
    records = load_records(*reference_dirs(s.name, reference))
    res = build_results(records, suite=s)
    learned = {t: e for t, e in learned_encoders(res).items() if t in tasks}
    for task in tasks:
        if task not in learned:
            learned[task] = []
    missing = [f"{t}: no learned encoder has metric records" for t, e in learned.items() if not e]
    sets = read_manifest(latents_dir(s.name, latents)).get("sets", [])
    rl = [r for r in records if r.get("kind") == "rl"]
    return missing + reference_gaps(sets, rl, learned, agent=AGENT, n_seeds=n_seeds)


def _tables(score: Any, task: str) -> tuple[pd.DataFrame, dict[str, list[float]], list[str]]:
    """Direction-adjusted metric values (learned encoders × metrics; higher is better), each
    learned encoder's SAC returns per seed, and the learned encoders, on ``task``."""
    res = score.results
    learned = learned_encoders(res).get(task, [])
    directions = res.provenance.get("directions", {})
    rows = [r for r in res.metric_rows if r["task"] == task and r["encoder"] in learned]
    values = pd.DataFrame(rows).pivot_table(index="encoder", columns="metric", values="value",
                                            aggfunc="first")
    for m in values.columns:
        if not directions.get(m, metrics.get(m).higher_is_better):
            values[m] = -values[m]
    per_seed: dict[str, list[float]] = {}
    for r in res.rl_rows:
        if r["task"] == task and r["agent"] == AGENT and r["encoder"] in learned:
            per_seed.setdefault(r["encoder"], []).append(float(r["eval_return"]))
    return values.loc[sorted(values.index)], per_seed, learned


def _refuse_partial(args: argparse.Namespace, tasks: Sequence[str]) -> None:
    found = gaps(args.suite, args.latents, args.reference, tasks, args.n_seeds)
    if found:
        sys.exit(f"the reference is not complete on {', '.join(tasks)} ({len(found)} gaps, "
                 f"first: {found[0]}); the pre-registration runs each step on a complete "
                 "reference only — `search.py check` lists them")


def _ranking_rows(ranking: pd.DataFrame, task: str) -> list[dict[str, Any]]:
    cols = ["metric", "group", "n_learned", "spearman_learned", "spearman_learned_ci_low",
            "spearman_learned_ci_high", "spearman_learned_p", "spearman_learned_p_holm",
            "noise_ceiling", "of_ceiling"]
    t = ranking[(ranking["task"] == task) & (ranking["agent"] == AGENT)]
    return json.loads(t[cols].to_json(orient="records"))


def select(args: argparse.Namespace) -> dict[str, Any]:
    """Step 2: the selection on PegInHole-v0 (module docstring)."""
    _refuse_partial(args, (args.select_task,))
    out = Path(args.out)
    score = score_metrics(args.candidates, args.suite, latents=args.latents,
                          reference=args.reference, tasks=[args.select_task],
                          out=out / "scores", echo=print, progress=args.progress)
    values, per_seed, _ = _tables(score, args.select_task)
    returns = {e: float(np.mean(v)) for e, v in per_seed.items()}
    sel = nested_selection(values, returns)
    rows = _ranking_rows(score.ranking, args.select_task)
    observable = [r for r in rows if r["group"] == "observable"]
    best_obs = max(observable, key=lambda r: r["spearman_learned"])["metric"] if observable \
        else None
    y = np.array([returns[e] for e in values.index])
    model = list(sel.model)
    result = {
        "task": args.select_task, "agent": AGENT, "n_learned": len(values),
        "candidates": list(args.candidates), "metrics": list(values.columns),
        "single": sel.single, "single_rho": sel.single_rho,
        "model": model, "nested_rho": sel.nested_rho,
        "nested_predictions": sel.nested_predictions,
        "best_observable": best_obs,
        "model_train": {"encoders": list(values.index), "returns": y.tolist(),
                        "values": values[model].to_numpy(float).tolist()},
        "ranking": rows,
    }
    (out / SELECTION).write_text(json.dumps(result, indent=1) + "\n")
    (out / "selection.md").write_text(_selection_md(result))
    print(f"selected on {args.select_task}: single {sel.single} (ρ {sel.single_rho:.2f}); model "
          f"{' + '.join(model)} (nested ρ {sel.nested_rho:.2f}); best observable {best_obs}; "
          f"written to {out}")
    return result


def _committed_unchanged(path: Path) -> bool:
    """``path`` is in a commit and equals HEAD's copy."""
    def git(*a: str) -> subprocess.CompletedProcess:
        return subprocess.run(["git", *a], cwd=path.parent, capture_output=True, text=True)

    logged = git("log", "-1", "--format=%H", "--", path.name)
    return bool(logged.stdout.strip()) and git("diff", "--quiet", "HEAD", "--",
                                               path.name).returncode == 0


def held_out_test(args: argparse.Namespace) -> dict[str, Any]:
    """Step 3: the selection scored once on Door-v0 (module docstring)."""
    out = Path(args.out)
    path = out / SELECTION
    if not path.is_file():
        sys.exit(f"{path} does not exist; run `search.py select` and commit its output first")
    if not args.uncommitted_ok and not _committed_unchanged(path):
        sys.exit(f"{path} is not committed (or changed since); commit the selection before "
                 "scoring it on Door-v0")
    _refuse_partial(args, (args.select_task, args.test_task))
    sel = json.loads(path.read_text())
    score = score_metrics(sel["candidates"], args.suite, latents=args.latents,
                          reference=args.reference, tasks=[args.test_task],
                          out=out / "scores_test", echo=print, progress=args.progress)
    values, per_seed, _ = _tables(score, args.test_task)
    train = sel["model_train"]
    values["__model__"] = transfer_model(np.asarray(train["values"], float),
                                         np.asarray(train["returns"], float),
                                         values[sel["model"]].to_numpy(float))
    y = np.array([np.mean(per_seed[e]) for e in values.index])
    checks = {}
    for label, column in (("single", sel["single"]), ("model", "__model__"),
                          ("best_observable", sel["best_observable"])):
        if column is None:
            continue
        cmp = compare_on(values, per_seed, column, args.baseline)
        lo, hi = cmp["rho_selected_ci"]
        dlo = cmp["difference_ci"][0]
        verdict = (f"beats {args.baseline}" if dlo > 0 else "holds" if lo > 0
                   else "does not hold" if hi < 0 else "inconclusive")
        cols = sel["model"] if column == "__model__" else [column]
        checks[label] = {**cmp, "selected": " + ".join(cols), "verdict": verdict,
                         "loo_rmse": loo_rmse(values[cols].to_numpy(float), y),
                         "loo_rmse_task_cmi": loo_rmse(values[[args.baseline]].to_numpy(float),
                                                       y)}
    switch = min((c for k, c in checks.items() if k != "best_observable"),
                 key=lambda c: c["loo_rmse"], default=None)
    result = {"task": args.test_task, "agent": AGENT, "n_learned": len(values),
              "baseline": args.baseline, "checks": checks,
              "evaluate_switches_to": (switch["selected"] if switch is not None
                                       and switch["loo_rmse"] < switch["loo_rmse_task_cmi"]
                                       else None),
              "ranking": _ranking_rows(score.ranking, args.test_task)}
    (out / TEST).write_text(json.dumps(result, indent=1, default=float) + "\n")
    (out / "test.md").write_text(_test_md(result))
    for label, c in checks.items():
        print(f"{args.test_task} {label} {c['selected']}: ρ {c['rho_selected']:.2f} "
              f"[{c['rho_selected_ci'][0]:.2f}, {c['rho_selected_ci'][1]:.2f}] vs task_cmi "
              f"{c['rho_baseline']:.2f}; {c['verdict']}")
    return result


def _f(x: Any, spec: str) -> str:
    """``x`` formatted, or – where it is missing (a null of the JSON, NaN)."""
    return "–" if x is None or (isinstance(x, float) and np.isnan(x)) else format(x, spec)


def _fmt_rows(rows: list[dict[str, Any]]) -> list[str]:
    lines = ["| metric | group | ρ within learned [95 %] | Holm p | share of ceiling |",
             "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| `{r['metric']}` | {r['group']} | {_f(r['spearman_learned'], '.2f')} "
                     f"[{_f(r['spearman_learned_ci_low'], '.2f')}, "
                     f"{_f(r['spearman_learned_ci_high'], '.2f')}] | "
                     f"{_f(r['spearman_learned_p_holm'], '.3g')} | "
                     f"{_f(r['of_ceiling'], '.0%')} |")
    return lines


def _selection_md(r: dict[str, Any]) -> str:
    ceiling = r["ranking"][0]["noise_ceiling"] if r["ranking"] else None
    return "\n".join([
        f"# Metric search: the selection on {r['task']} (step 2 of the pre-registration)", "",
        f"{r['n_learned']} learned encoders, SAC, noise ceiling {_f(ceiling, '.2f')}.", "",
        f"- **Best single metric**: `{r['single']}`, ρ {r['single_rho']:.2f}.",
        f"- **Selected model** (nested leave-one-encoder-out): `{' + '.join(r['model'])}`; "
        f"its honest nested ρ {r['nested_rho']:.2f}.",
        f"- **Best observable metric**: `{r['best_observable']}`.", "",
        f"All {len(r['ranking'])} metrics (Holm over all of them):", "",
        *_fmt_rows(r["ranking"]), ""])


def _test_md(r: dict[str, Any]) -> str:
    lines = [f"# Metric search: the selection scored on {r['task']} (step 3)", "",
             f"{r['n_learned']} learned encoders, SAC; the same bootstrap resamples for the "
             f"selection and `{r['baseline']}`.", "",
             f"| check | metric(s) | ρ [95 %] | {r['baseline']} ρ | difference [95 %] | verdict | "
             f"LOO RMSE ({r['baseline']}'s) |", "|---|---|---|---|---|---|---|"]
    for label, c in r["checks"].items():
        lines.append(
            f"| {label} | `{c['selected']}` | {c['rho_selected']:.2f} "
            f"[{c['rho_selected_ci'][0]:.2f}, {c['rho_selected_ci'][1]:.2f}] | "
            f"{c['rho_baseline']:.2f} | {c['difference']:+.2f} [{c['difference_ci'][0]:+.2f}, "
            f"{c['difference_ci'][1]:+.2f}] | {c['verdict']} | {c['loo_rmse']:.0f} "
            f"({c['loo_rmse_task_cmi']:.0f}) |")
    switch = r["evaluate_switches_to"]
    lines += ["", "`repbench evaluate --metrics-only`: "
              + (f"switches to `{switch}` (`--predictor`)." if switch else
                 f"keeps `{r['baseline']}` (no selection has a lower leave-one-encoder-out RMSE "
                 "on the held-out task)."), "",
              f"All {len(r['ranking'])} metrics:", "", *_fmt_rows(r["ranking"]), ""]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="step", required=True)
    for step in ("check", "select", "test"):
        p = sub.add_parser(step)
        p.add_argument("--suite", default="quick")
        p.add_argument("--latents", default=None)
        p.add_argument("--reference", action="append", default=None)
        p.add_argument("--out", default=str(Path(__file__).parent / "results"))
        # the pre-registration's; other values are for testing the steps on a toy reference
        p.add_argument("--select-task", default=SELECT_TASK)
        p.add_argument("--test-task", default=TEST_TASK)
        p.add_argument("--candidates", nargs="+", default=list(CANDIDATES))
        p.add_argument("--n-seeds", type=int, default=N_SEEDS)
        p.add_argument("--baseline", default=BASELINE)
        p.add_argument("--no-progress", dest="progress", action="store_false")
        if step == "test":
            p.add_argument("--uncommitted-ok", action="store_true",
                           help="score a selection that is not committed (tests only)")
    args = ap.parse_args(argv)
    if args.step == "check":
        found = gaps(args.suite, args.latents, args.reference,
                     (args.select_task, args.test_task), args.n_seeds)
        for g in found:
            print(g)
        print(f"{len(found)} gaps" if found else "the reference is complete")
        return 1 if found else 0
    Path(args.out).mkdir(parents=True, exist_ok=True)
    (select if args.step == "select" else held_out_test)(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
