"""Issue 20's paired same-answer check, the statistics fixed in PREREGISTRATION.md.

Usage: ``python analyse.py STORE_OR_RECORDS [MORE ...] [--out paired.csv]``. It reads the RL and
privileged-agent records of both paths (told apart by the agent's ``backend`` and
``hidden_sizes``), prints the table and the verdict of each pre-registered criterion, and writes
one row per encoder to ``--out``. Written before the first RL record of either path existed.
"""

from __future__ import annotations

import argparse
import csv
import statistics
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy import stats
from statsmodels.stats.multitest import multipletests

from repbench.analysis.results import load_records

ENCODERS = ["supervised_task", "vae_lowkl", "vae", "oracle_task", "success", "pca", "random",
            "proprio_only"]
SEEDS = (0, 1, 2)
PATHS = {"old": ("sb3", [256, 256]), "new": ("sbx", [128, 128])}
RHO_MIN, ALPHA, PRIVILEGED_MIN = 0.9, 0.05, 0.9


def path_of(record: dict) -> str | None:
    """'old' / 'new' by the agent's parameters (the suite files set both explicitly)."""
    params = record["agent"]["params"]
    key = (params.get("backend", "sb3"), list(params.get("hidden_sizes", [])))
    return next((name for name, p in PATHS.items() if (p[0], p[1]) == key), None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sources", type=Path, nargs="+")
    parser.add_argument("--out", type=Path, default=Path(__file__).with_name("paired.csv"))
    args = parser.parse_args()

    records = load_records(*args.sources, kinds=["rl", "full_state_agent"])
    returns: dict[tuple[str, str], dict[int, float]] = defaultdict(dict)
    cpu: dict[str, list[float]] = defaultdict(list)
    privileged = []
    for r in records:
        if r["kind"] == "full_state_agent":
            privileged.append(r["values"]["eval_success_rate"])
            continue
        path = path_of(r)
        if path is None or r["encoder"]["name"] not in ENCODERS:
            continue
        returns[(r["encoder"]["name"], path)][int(r["seed"])] = r["values"]["eval_return"]
        cpu[path].append(r["timings"]["cpu_time_s"])

    complete = [e for e in ENCODERS
                if all(len(returns[(e, p)]) == len(SEEDS) for p in PATHS)]
    missing = [e for e in ENCODERS if e not in complete]
    if missing:
        print(f"incomplete (not judged): {', '.join(missing)}")
    rows = []
    for enc in complete:
        old = np.array([returns[(enc, "old")][s] for s in SEEDS])
        new = np.array([returns[(enc, "new")][s] for s in SEEDS])
        test = stats.ttest_ind(new, old, equal_var=False)
        ci = test.confidence_interval(0.95)
        rows.append({"encoder": enc, "old_mean": old.mean(), "new_mean": new.mean(),
                     "difference": new.mean() - old.mean(), "ci_low": ci.low, "ci_high": ci.high,
                     "welch_p": test.pvalue, "old_seeds": old.tolist(),
                     "new_seeds": new.tolist()})
    if len(rows) < 2:
        print("fewer than 2 complete encoders: nothing to judge yet")
        return
    holm = multipletests([r["welch_p"] for r in rows], alpha=ALPHA, method="holm")[1]
    for r, p in zip(rows, holm, strict=True):
        r["holm_p"] = p
    rho = stats.spearmanr([r["old_mean"] for r in rows], [r["new_mean"] for r in rows])[0]

    print("| encoder | old mean | new mean | new − old [Welch 95 %] | Holm p |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['encoder']} | {r['old_mean']:.1f} | {r['new_mean']:.1f} | "
              f"{r['difference']:+.1f} [{r['ci_low']:+.1f}, {r['ci_high']:+.1f}] | "
              f"{r['holm_p']:.3f} |")
    ok1 = rho >= RHO_MIN
    ok2 = all(r["holm_p"] >= ALPHA for r in rows)
    ok3 = bool(privileged) and min(privileged) >= PRIVILEGED_MIN
    print(f"\n1. Spearman of per-encoder means: {rho:.3f} (threshold {RHO_MIN}): "
          f"{'holds' if ok1 else 'fails'}")
    print(f"2. no Holm-adjusted Welch p < {ALPHA}: {'holds' if ok2 else 'fails'}")
    print(f"3. privileged agent success {privileged} (≥ {PRIVILEGED_MIN}): "
          f"{'holds' if ok3 else 'fails'}")
    for path in PATHS:
        if {"oracle_task", "random", "proprio_only"} <= set(complete):
            top = min(returns[("oracle_task", path)].values())
            low = max(v for e in ("random", "proprio_only") for v in returns[(e, path)].values())
            print(f"4. ({path}) every oracle_task seed above every random/proprio_only seed: "
                  f"{top:.1f} > {low:.1f}: {'yes' if top > low else 'no'}")
    for path in PATHS:
        if cpu[path]:
            print(f"CPU per RL run ({path}): median {statistics.median(cpu[path]):.0f} s, "
                  f"sum {sum(cpu[path]) / 60:.1f} min over {len(cpu[path])} runs")
    if cpu["old"] and cpu["new"]:
        print(f"ratio of medians old/new: "
              f"{statistics.median(cpu['old']) / statistics.median(cpu['new']):.2f}")
    verdict = ok1 and ok2 and ok3 and not missing
    print(f"\nverdict: {'same answer' if verdict else 'NOT the same answer (or incomplete)'}")

    with args.out.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main()
