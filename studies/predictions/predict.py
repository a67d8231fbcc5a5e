"""The pre-registered cross-task prediction: a new task's per-encoder SAC returns,
predicted from its metrics alone with the peg-in-hole's calibration (no refitting).

    python studies/predictions/predict.py \\
        --suite leaderboards/quick/surface_press/suite.toml --store /work/store_press

reads the peg-in-hole's committed quick records (``--source``, default
``leaderboards/quick/records``) and the new task's metric and privileged-agent records from
the store of ``repbench run --suite ... --no-rl``; writes ``<task id>.csv`` into
``leaderboards/quick/predictions/`` (``--out``)
(:data:`repbench.analysis.transfer.COLUMNS`). The test it is scored by is fixed in
:mod:`repbench.analysis.transfer` and in this folder's README, both committed with the CSV
before any RL record of the task exists. ``--score`` (after the RL) prints that test.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy import stats

from repbench.analysis.results import load_records
from repbench.analysis.robustness import validated_method
from repbench.analysis.transfer import (
    predict_task,
    privileged_return,
    read_prediction,
    score_predictions,
)
from repbench.pipeline.plan import build_plan
from repbench.pipeline.runner import collect_results, records_of_suite, results_of
from repbench.pipeline.store import Store
from repbench.pipeline.suite import load_suite
from repbench.report.families import encoder_families

PREDICTIONS = Path("leaderboards/quick/predictions")
SOURCE_TASK, AGENT = "PegInHole-v0", "sac"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--suite", required=True, help="the new task's suite file")
    ap.add_argument("--store", required=True, help="its store (after `repbench run --no-rl`)")
    ap.add_argument("--source", type=Path, default=Path("leaderboards/quick/records"))
    ap.add_argument("--score", action="store_true",
                    help="score the committed predictions against the store's RL records")
    ap.add_argument("--prediction", type=Path, default=None,
                    help="with --score: the prediction table to score (default <task id>.csv "
                         "in --out)")
    ap.add_argument("--out", type=Path, default=PREDICTIONS,
                    help="folder of the prediction tables (default %(default)s)")
    ap.add_argument("--task", default=None,
                    help="the task to predict, for a suite of several (e.g. the zoo's)")
    ap.add_argument("--source-task", default=SOURCE_TASK,
                    help="the task whose calibration predicts (default %(default)s; the task "
                         "itself for the zoo's within-task test)")
    args = ap.parse_args()

    quick = load_suite("quick")
    source_records = records_of_suite(load_records(args.source), quick, args.source)
    source = results_of(build_plan(quick), source_records)
    suite = load_suite(args.suite)
    if args.task is not None:
        suite = suite.only_tasks([args.task])
    target = collect_results(build_plan(suite), Store(args.store))
    (task,) = suite.tasks
    out = args.out / f"{task}.csv"
    if args.score:
        check, table = score_predictions(read_prediction(args.prediction or out), target.rl_rows)
        print(table[["encoder", "family", "metric_value", "predicted_unclipped",
                     "predicted_return", "ci_low", "ci_high", "actual_return", "n_seeds",
                     "inside"]].to_string(index=False))
        print(f"{check.check}: {check.statistic} {check.value:.2f} "
              f"[{check.ci_low:.2f}, {check.ci_high:.2f}] -> {check.verdict}; {check.detail}")
        scored = table[table["n_seeds"] > 0]
        n_in, n = int(scored["inside"].sum()), len(scored)
        ci = stats.binomtest(n_in, n).proportion_ci(method="exact")
        rmse = float(np.sqrt(np.mean((scored["predicted_return"]
                                      - scored["actual_return"]) ** 2)))
        _, reference, _, _ = validated_method(
            source.metric_rows, source.rl_rows,
            {**encoder_families(source), **encoder_families(target)}, args.source_task, AGENT)
        print(f"coverage: {n_in}/{n} inside the stated intervals (nominal "
              f"{scored['coverage'].iloc[0]:.0%}), Clopper-Pearson 95 % "
              f"[{ci.low:.2f}, {ci.high:.2f}]; RMSE of predicted_return {rmse:.0f}")
        if reference is not None:
            print(f"the reference's own held-out figures: {reference.detail}")
        return 0
    if target.rl_rows:
        raise SystemExit(f"{args.store} already holds RL records of {task}: a prediction made "
                         "now is not made before them")
    if out.exists():
        raise SystemExit(f"{out} exists: a pre-registered prediction is not remade; move it "
                         "away first if it was never committed")
    families = {**encoder_families(source), **encoder_families(target)}
    pred = predict_task(source.metric_rows, source.rl_rows, target.metric_rows,
                        source_task=args.source_task, target_task=task, agent=AGENT,
                        families=families,
                        ceiling_source=privileged_return(source_records, args.source_task),
                        ceiling_target=privileged_return(load_records(Store(args.store)), task),
                        choose=validated_method)
    out.parent.mkdir(parents=True, exist_ok=True)
    pred.to_csv(out, index=False, float_format="%.6g")
    print(pred[["encoder", "family", "metric", "metric_value", "predicted_return", "ci_low",
                "ci_high", "predicted_unclipped"]].to_string(index=False))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
