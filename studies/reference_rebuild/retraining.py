"""How much does retraining an encoder move its RL return? Training-to-training reliability.

The rebuild (issue 54) retrained quick's original encoders under the same config on regenerated
data (the same task, seeds and sizes; the data differ in their checksums because they were
generated on another CPU) and ran their SAC seeds again. So each rebuilt encoder has two
trainings, each with 3 SAC seeds: the records before the rebuild (``--before``, a commit) and
the records now. This compares them, over the learned encoders rebuilt so far:

- **training-to-training ρ**: the Spearman ρ between the two trainings' 3-seed mean returns,
  with a bootstrap interval over encoders (and, inside each, seeds of both trainings);
- beside it, **seed-to-seed** r₁ of the same encoders within the new training (the noise
  ceiling's input, :func:`repbench.analysis.noise_ceiling.noise_ceiling`) and the 3-seed
  mean's Spearman–Brown reliability: what the two trainings' ρ would be if retraining changed
  nothing but the SAC seeds;
- the same two-trainings ρ for ``task_cmi``'s value.

The statistic was fixed (this file, first commit) when 3 of the 17 encoders left to rebuild on
PegInHole-v0 had been seen one by one (vae_lowkl 779 → 363, success 479 → 665, success_lowkl
660 → 625), before any was read as a group; it reads committed records only.

Run::

    python studies/reference_rebuild/retraining.py --before 328b051~1 --task PegInHole-v0
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy import stats

from repbench.analysis.noise_ceiling import noise_ceiling, spearman_brown
from repbench.analysis.results import load_records
from repbench.registry import encoders

RECORDS = Path("leaderboards/quick/records")
ROOT = Path(__file__).resolve().parents[2]


def _records_at(commit: str, kind: str, task: str) -> list[dict]:
    """The committed records of ``kind`` on ``task`` at ``commit`` (read with ``git show``)."""
    names = subprocess.run(["git", "ls-tree", "--name-only", f"{commit}:{RECORDS / kind}"],
                           cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    out = []
    for name in names:
        if name.startswith(f"{task}."):
            text = subprocess.run(["git", "show", f"{commit}:{RECORDS / kind / name}"],
                                  cwd=ROOT, capture_output=True, text=True, check=True).stdout
            out.append(json.loads(text))
    return out


def _sac(records: list[dict]) -> dict[str, dict[int, float]]:
    out: dict[str, dict[int, float]] = {}
    for r in records:
        if r["agent"]["name"] == "sac":
            out.setdefault(r["encoder"]["name"], {})[r["seed"]] = float(
                r["values"]["eval_return"])
    return out


def _metric(records: list[dict], name: str) -> dict[str, float]:
    return {r["encoder"]["name"]: float(r["values"]["value"]) for r in records
            if r["metric"]["name"] == name}


def compare(before: str, task: str, n_bootstrap: int = 2000, seed: int = 0) -> dict:
    """The comparison of the module docstring; rebuilt = learned encoders whose SAC records
    changed between ``before`` and now."""
    old_rl = _sac(_records_at(before, "rl", task))
    new_rl = _sac([r for r in load_records(ROOT / RECORDS, kinds=("rl",))
                   if r["task"]["name"] == task])
    old_cmi = _metric(_records_at(before, "metric", task), "task_cmi")
    new_cmi = _metric([r for r in load_records(ROOT / RECORDS, kinds=("metric",))
                       if r["task"]["name"] == task], "task_cmi")
    rebuilt = sorted(e for e in new_rl if e in old_rl and new_rl[e] != old_rl[e]
                     and getattr(encoders.get(e), "family", "") != "baseline"
                     and len(new_rl[e]) == len(old_rl[e]) == 3)
    a = np.array([[old_rl[e][s] for s in sorted(old_rl[e])] for e in rebuilt])
    b = np.array([[new_rl[e][s] for s in sorted(new_rl[e])] for e in rebuilt])
    rng = np.random.default_rng(seed)
    boot = []
    for _ in range(n_bootstrap):
        idx = rng.integers(0, len(rebuilt), len(rebuilt))
        ma = np.array([rng.choice(a[i], 3).mean() for i in idx])
        mb = np.array([rng.choice(b[i], 3).mean() for i in idx])
        boot.append(stats.spearmanr(ma, mb).statistic)
    lo, hi = np.nanquantile(boot, [0.025, 0.975])
    within = noise_ceiling({e: new_rl[e] for e in rebuilt}, n_bootstrap=n_bootstrap, seed=seed)
    cmi = [e for e in rebuilt if e in old_cmi and e in new_cmi]
    return {
        "task": task, "before": before, "n_rebuilt": len(rebuilt), "encoders": rebuilt,
        "training_to_training_rho": float(stats.spearmanr(a.mean(1), b.mean(1)).statistic),
        "training_to_training_ci": [float(lo), float(hi)],
        "seed_to_seed_r1_new": within["r1"], "r1_ci": [within["r1_ci_low"], within["r1_ci_high"]],
        "expected_if_only_seeds": spearman_brown(within["r1"], 3),
        "task_cmi_training_to_training_rho": float(stats.spearmanr(
            [old_cmi[e] for e in cmi], [new_cmi[e] for e in cmi]).statistic),
        "mean_abs_change": float(np.abs(b.mean(1) - a.mean(1)).mean()),
        "per_encoder": {e: {"before": a[i].mean(), "after": b[i].mean(),
                            "task_cmi_before": old_cmi.get(e), "task_cmi_after": new_cmi.get(e)}
                        for i, e in enumerate(rebuilt)},
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", default="328b051~1", help="the commit before the rebuild")
    ap.add_argument("--task", default="PegInHole-v0")
    ap.add_argument("--out", default=None, help="write the result as JSON here")
    args = ap.parse_args(argv)
    out = compare(args.before, args.task)
    print(f"{out['task']}: {out['n_rebuilt']} learned encoders retrained; training-to-training "
          f"Spearman of 3-seed mean SAC return {out['training_to_training_rho']:.2f} "
          f"[{out['training_to_training_ci'][0]:.2f}, {out['training_to_training_ci'][1]:.2f}]; "
          f"if retraining changed nothing but the seeds: {out['expected_if_only_seeds']:.2f} "
          f"(seed-to-seed r1 {out['seed_to_seed_r1_new']:.2f}); task_cmi across trainings "
          f"{out['task_cmi_training_to_training_rho']:.2f}; mean |change| of the mean return "
          f"{out['mean_abs_change']:.0f}")
    for e, v in out["per_encoder"].items():
        print(f"  {e:24s} {v['before']:6.0f} -> {v['after']:6.0f}   task_cmi "
              f"{v['task_cmi_before']:.3f} -> {v['task_cmi_after']:.3f}")
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
