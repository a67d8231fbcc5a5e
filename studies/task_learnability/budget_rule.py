"""Issue 22's RL-budget rule for a new task, on the records of a budget pilot.

    python studies/task_learnability/budget_rule.py --records STORE_OR_DIR --task Door-v0 \\
        --steps 10000 --trained vae_lowkl vae_lowkl_ft_proprio

The rule (``leaderboards/quick/door/budget.toml``, fixed before the pilot ran): at a budget, each
trained encoder's final SAC returns over seeds against the untrained ``random``'s, a one-sided
Welch t (trained above random); the p-values are Holm-adjusted over the trained encoders named;
the budget separates them if any adjusted p < 0.05. Prints every pilot encoder's returns and
the verdict; exits 0 either way.
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path

import numpy as np
from scipy import stats
from statsmodels.stats.multitest import multipletests

from repbench.analysis.results import load_records

ALPHA = 0.05
UNTRAINED = "random"


def returns_by_encoder(records: list[dict], task: str, steps: int,
                       agent: str = "sac") -> dict[str, dict[int, float]]:
    """``{encoder: {seed: final eval return}}`` of the task's RL records at ``steps``."""
    out: dict[str, dict[int, float]] = defaultdict(dict)
    for r in records:
        if (r.get("kind") == "rl" and r["task"]["name"] == task
                and r["budget"]["train_steps"] == steps and r["agent"]["name"] == agent):
            out[r["encoder"]["name"]][int(r["seed"])] = float(r["values"]["eval_return"])
    return dict(out)


def budget_rule(returns: dict[str, dict[int, float]], trained: list[str]
                ) -> tuple[bool, list[tuple[str, float, float]]]:
    """(separates, [(encoder, one-sided Welch p, Holm-adjusted p)]) for ``trained`` vs random."""
    missing = [e for e in [UNTRAINED, *trained] if len(returns.get(e, {})) < 2]
    if missing:
        raise SystemExit(f"budget_rule: fewer than 2 seeds of {', '.join(missing)} in the "
                         "records; run the pilot first")
    base = np.array(list(returns[UNTRAINED].values()))
    raw = [float(stats.ttest_ind(np.array(list(returns[e].values())), base, equal_var=False,
                                 alternative="greater").pvalue) for e in trained]
    adjusted = multipletests(raw, alpha=ALPHA, method="holm")[1]
    rows = list(zip(trained, raw, (float(a) for a in adjusted), strict=True))
    return any(a < ALPHA for _, _, a in rows), rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--records", type=Path, required=True,
                    help="a store or a folder of records (the pilot's --store or --out)")
    ap.add_argument("--task", required=True)
    ap.add_argument("--steps", type=int, required=True, help="the pilot's SAC budget")
    ap.add_argument("--trained", nargs="+", required=True,
                    help="the trained encoders the rule tests against random")
    args = ap.parse_args()
    returns = returns_by_encoder(load_records(args.records, kinds=("rl",)), args.task,
                                 args.steps)
    print("| encoder | mean return | seeds |")
    print("|---|---|---|")
    for enc, by_seed in sorted(returns.items(), key=lambda kv: -np.mean(list(kv[1].values()))):
        seeds = ", ".join(f"{by_seed[s]:.0f}" for s in sorted(by_seed))
        print(f"| {enc} | {np.mean(list(by_seed.values())):.0f} | {seeds} |")
    separates, rows = budget_rule(returns, args.trained)
    for enc, p, adj in rows:
        print(f"{enc} above {UNTRAINED}: one-sided Welch p = {p:.3f}, Holm {adj:.3f}")
    print(f"{args.task} at {args.steps} steps: "
          f"{'separates (this is the budget)' if separates else 'does not separate'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
