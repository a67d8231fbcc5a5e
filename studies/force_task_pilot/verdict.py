"""Issue 57's pilot rule (README.md), applied to a candidate's records. Written before any record.

    python studies/force_task_pilot/verdict.py RECORDS --task SurfacePress-v1 [--train-steps N]

RECORDS: a store or an exported ``records/`` folder; every ``*.json`` under it with
``kind`` ``rl`` (SAC) or ``full_state_agent`` of ``--task`` (and, for RL, ``--train-steps``) is
read. Prints each encoder's per-seed returns, the four criteria and the verdict.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from repbench.analysis.noise_ceiling import noise_ceiling

#: The rule's learned set: the 8 self-supervised encoders of the pilot (no privileged labels).
LEARNED = ("vae_lowkl_ft_proprio", "vae_lowkl_image", "vae_lowkl", "vae_lowkl_balanced", "vae",
           "time_contrastive", "simclr", "r3m")
SEEDS = (0, 1, 2)
R1_MIN = 0.6
PRIVILEGED_MIN = 0.9


def above_at_seed_level(a: dict[int, float], b: dict[int, float]) -> bool:
    """Every seed of ``a`` above every seed of ``b`` (3 vs 3: Mann-Whitney U = 9 of 9, the
    one-sided exact p = 1/20 = 0.05)."""
    return len(a) == len(b) == len(SEEDS) and min(a.values()) > max(b.values())


def read(root: Path, task: str, train_steps: int | None) -> tuple[dict, list[float]]:
    returns: dict[str, dict[int, float]] = {}
    privileged: list[float] = []
    for path in sorted(root.rglob("*.json")):
        try:
            rec = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if not isinstance(rec, dict) or (rec.get("task") or {}).get("name") != task:
            continue
        if rec.get("kind") == "full_state_agent":
            privileged.append(float(rec["values"]["eval_success_rate"]))
        elif rec.get("kind") == "rl" and rec.get("agent", {}).get("name", "sac") == "sac" and (
                train_steps is None or rec["values"].get("train_steps") == train_steps):
            returns.setdefault(rec["encoder"]["name"], {})[int(rec["seed"])] = float(
                rec["values"]["eval_return"])
    return returns, privileged


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("records", type=Path)
    ap.add_argument("--task", required=True)
    ap.add_argument("--train-steps", type=int, default=None)
    args = ap.parse_args()
    returns, privileged = read(args.records, args.task, args.train_steps)
    for enc in sorted(returns, key=lambda e: -sum(returns[e].values()) / len(returns[e])):
        seeds = returns[enc]
        print(f"{enc:22s} " + " ".join(f"{seeds.get(s, float('nan')):7.1f}" for s in SEEDS))
    learned = {e: returns[e] for e in LEARNED if e in returns}
    missing = [e for e in LEARNED if e not in returns or len(returns[e]) < len(SEEDS)]
    nc = noise_ceiling(learned)
    rule1 = nc["r1"] >= R1_MIN
    random = returns.get("random", {})
    beat = [e for e in LEARNED if e in returns and above_at_seed_level(returns[e], random)]
    rule2 = bool(beat)
    rule3 = above_at_seed_level(returns.get("vae_lowkl_ft_proprio", {}),
                                returns.get("vae_lowkl_image", {}))
    rule4 = bool(privileged) and max(privileged) >= PRIVILEGED_MIN
    print(f"1. seed-to-seed Spearman r1 over {nc['n_encoders']} learned encoders "
          f"({nc['n_seeds']} seeds): {nc['r1']:.2f} [{nc['r1_ci_low']:.2f}, "
          f"{nc['r1_ci_high']:.2f}], ceiling {nc['ceiling']:.2f}: "
          f"{'holds' if rule1 else 'fails'} (>= {R1_MIN})")
    print(f"2. self-supervised encoders above random at seed level: {beat or 'none'}: "
          f"{'holds' if rule2 else 'fails'}")
    print(f"3. vae_lowkl_ft_proprio above vae_lowkl_image at seed level: "
          f"{'holds' if rule3 else 'fails'}")
    print(f"4. privileged agent success {privileged or 'no record'}: "
          f"{'holds' if rule4 else 'fails'} (>= {PRIVILEGED_MIN:.0%})")
    complete = not missing and len(privileged) == 1
    verdict = "PASSES" if (rule1 and rule2 and rule3 and rule4) else "FAILS"
    print(f"verdict: {verdict}" + ("" if complete else
                                   f" (INCOMPLETE: missing {missing or 'privileged agent'})"))
    return 0 if complete else 2


if __name__ == "__main__":
    raise SystemExit(main())
