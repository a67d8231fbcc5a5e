"""The same SurfacePress-v0 encoders trained twice, on two machines: how far do they and their
metrics move?

Encoder training is bit-reproducible on one machine but not across CPUs (torch picks AVX2 or
AVX-512 kernels). ``leaderboards/quick/surface_press/partial_10k/records`` were made on an
AVX-512 machine (Zen 4); a second store of the same suite, built from an empty store on
another machine, holds the same stage keys with other weights. This compares the two record
sets stage by stage:

    python studies/surface_press_retrain/compare.py --b /work/store_press

prints each encoder's held-out loss on both, each metric's values and how far they moved in
units of the metric's own bootstrap half-width, the Spearman correlation of each metric across
encoders between the two trainings, and the pre-registered prediction's ranking recomputed from
the second training's metrics with the same frozen peg-in-hole calibration (never written over
``leaderboards/quick/predictions/SurfacePress-v0.csv``). Writes ``metrics.csv`` and ``encoders.csv`` beside this
file; ``--write-prediction PATH`` also writes that recomputed prediction (the secondary test of
``leaderboards/quick/predictions/README.md``), after checking that the metric it predicts from has the values this
folder's committed ``metrics.csv`` holds for the second training.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import spearmanr

from repbench.analysis.results import load_records
from repbench.analysis.robustness import validated_method
from repbench.analysis.transfer import predict_task, privileged_return
from repbench.pipeline.plan import build_plan
from repbench.pipeline.runner import records_of_suite, results_of
from repbench.pipeline.store import Store
from repbench.pipeline.suite import load_suite
from repbench.report.families import encoder_families

HERE = Path(__file__).parent
BOARD = Path("leaderboards/quick/surface_press")
TASK, SOURCE_TASK, AGENT = "SurfacePress-v0", "PegInHole-v0", "sac"
LEARNED_OUT = {"oracle_task", "oracle", "random", "pca", "proprio_only"}


def _records(where: str) -> list[dict]:
    """The records of a store (artifact folders with ``meta.json``) or of a records folder."""
    path = Path(where)
    if any(path.glob("*/*/meta.json")):
        return load_records(Store(path))
    return load_records(path / "records" if (path / "records").is_dir() else path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    first = BOARD / "partial_10k" / "records"
    ap.add_argument("--a", default=str(first), help="first training's records")
    ap.add_argument("--b", required=True, help="second training: a store or a records folder")
    ap.add_argument("--suite", default=str(BOARD / "suite_20k.toml"))
    ap.add_argument("--write-prediction", type=Path, default=None,
                    help="write the prediction recomputed from the second training's metrics")
    args = ap.parse_args()
    committed_metrics = pd.read_csv(HERE / "metrics.csv")  # before this run rewrites it

    suite = load_suite(args.suite)
    plan = build_plan(suite)
    sides = {}
    for side in ("a", "b"):
        where = getattr(args, side)
        raw = _records(where)
        recs = records_of_suite(raw, suite, where)
        sides[side] = (recs, results_of(plan, recs))

    enc = {s: pd.DataFrame(r.encoder_rows).set_index("encoder") for s, (_, r) in sides.items()}
    encoders = enc["a"][["heldout_loss"]].join(enc["b"][["heldout_loss"]], lsuffix="_a",
                                               rsuffix="_b")
    encoders["relative_change"] = encoders.heldout_loss_b / encoders.heldout_loss_a - 1
    encoders.to_csv(HERE / "encoders.csv", float_format="%.6g")

    cols = ["encoder", "metric", "value", "ci_low", "ci_high"]
    m = {s: pd.DataFrame(r.metric_rows)[cols] for s, (_, r) in sides.items()}
    metrics = m["a"].merge(m["b"], on=["encoder", "metric"], suffixes=("_a", "_b"))
    half = (metrics.ci_high_a - metrics.ci_low_a) / 2
    metrics["delta"] = metrics.value_b - metrics.value_a
    metrics["delta_in_half_widths"] = metrics.delta / half.replace(0, np.nan)
    metrics["learned"] = ~metrics.encoder.isin(LEARNED_OUT)
    metrics.to_csv(HERE / "metrics.csv", index=False, float_format="%.6g")

    pd.set_option("display.width", 160)
    print(encoders.round(3).to_string())
    print()
    rows = []
    for name, g in metrics.groupby("metric"):
        learned = g[g.learned]
        rows.append({"metric": name,
                     "identical_baselines": int((g[~g.learned].delta == 0).sum()),
                     "spearman_all": spearmanr(g.value_a, g.value_b)[0],
                     "spearman_learned": spearmanr(learned.value_a, learned.value_b)[0],
                     "median_abs_delta_hw_learned":
                         learned.delta_in_half_widths.abs().median()})
    print(pd.DataFrame(rows).round(3).to_string(index=False))

    recs_b, res_b = sides["b"]
    quick = load_suite("quick")
    src_dir = Path("leaderboards/quick/records")
    src_recs = records_of_suite(load_records(src_dir), quick, src_dir)
    source = results_of(build_plan(quick), src_recs)
    families = {**encoder_families(source), **encoder_families(res_b)}
    again = predict_task(source.metric_rows, source.rl_rows, res_b.metric_rows,
                         source_task=SOURCE_TASK, target_task=TASK, agent=AGENT,
                         families=families,
                         ceiling_source=privileged_return(src_recs, SOURCE_TASK),
                         ceiling_target=privileged_return(recs_b, TASK),
                         choose=validated_method)
    committed = pd.read_csv(Path("leaderboards/quick/predictions") / f"{TASK}.csv")
    both = committed.merge(again, on="encoder", suffixes=("_committed", "_retrained"))
    learned = both[~both.encoder.isin(LEARNED_OUT)]
    rho = spearmanr(learned.predicted_unclipped_committed, learned.predicted_unclipped_retrained)[0]
    print(f"\nprivileged return: {committed.ceiling_target.iloc[0]:.1f} (committed) vs "
          f"{again.ceiling_target.iloc[0]:.1f} (retrained)")
    print(f"predicted ranking of the {len(learned)} learned encoders, committed vs recomputed "
          f"from the retrained metrics: Spearman {rho:.2f}")
    print(both[["encoder", "metric_value_committed", "metric_value_retrained",
                "predicted_unclipped_committed", "predicted_unclipped_retrained"]]
          .round(3).to_string(index=False))
    if args.write_prediction is not None:
        _check_against(again, committed_metrics)
        args.write_prediction.parent.mkdir(parents=True, exist_ok=True)
        again.to_csv(args.write_prediction, index=False, float_format="%.6g")
        print(f"wrote {args.write_prediction}")
    return 0


def _check_against(prediction: pd.DataFrame, committed: pd.DataFrame) -> None:
    """Stop unless every encoder's predicting metric value equals (to the CSV's 6 digits) the
    second training's value in the committed ``metrics.csv``."""
    (metric,) = prediction.metric.unique()
    values = committed[committed.metric == metric].set_index("encoder").value_b
    merged = prediction.set_index("encoder").metric_value.to_frame().join(values, how="left")
    if merged.value_b.isna().any() or not np.allclose(merged.metric_value, merged.value_b,
                                                      rtol=1e-5, atol=0):
        raise SystemExit(f"the store's {metric} values are not the committed metrics.csv's "
                         "value_b: this is not the training that file describes")


if __name__ == "__main__":
    raise SystemExit(main())
