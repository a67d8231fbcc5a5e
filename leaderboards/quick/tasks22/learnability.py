"""Learnability of a task at quick's privileged budget: the privileged SAC agent (task-frame
state ⊕ robot state, ``oracle_task``), trained exactly as the quick suite's full-state stage
trains it, must reach >= 90 % evaluation success in every seed (issue 22).

    nice -n 19 python leaderboards/quick/tasks22/learnability.py --task SurfacePress-v0 --seeds 0 1 2

Prints one line per seed (success, return, kept step, wall time) and writes them as JSON lines
to ``--out`` (default ``learnability_<task>.jsonl`` beside this file).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import repbench
from repbench.rl.full_state import (
    PRIVILEGED_AGENT_PARAMS,
    fitted_privileged_encoder,
    train_full_state_agent,
)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--task", required=True)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--suite", default="quick")
    ap.add_argument("--backend", default="sb3", choices=("sb3", "sbx"),
                    help="privileged_params backend (the brief: sb3)")
    ap.add_argument("--steps", type=int, default=None, help="default: the suite's "
                    "full_state_train_steps")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()

    suite = repbench.load_suite(args.suite)
    rl = suite.rl
    # as repbench.pipeline.plan builds the privileged stage: the suite's SAC settings, then
    # PRIVILEGED_AGENT_PARAMS, then the suite's explicit privileged settings
    params = {**suite.agent_params.get("sac", {}), **PRIVILEGED_AGENT_PARAMS,
              **rl.privileged_params, "backend": args.backend}
    steps = args.steps or rl.full_state_train_steps
    task = repbench.tasks.get(args.task)(**suite.task_params.get(args.task, {}))
    data = task.collect("random", n_episodes=2, steps_per_episode=5, seed=suite.dataset.seed,
                        progress=False)
    out = Path(args.out or Path(__file__).with_name(f"learnability_{args.task}.jsonl"))
    print(f"{args.task}: privileged SAC, {steps} steps, eval {rl.eval_episodes} episodes, "
          f"params {params}", flush=True)
    for seed in args.seeds:
        t0 = time.perf_counter()
        encoder = fitted_privileged_encoder(task, data, seed, rl.privileged_encoder)
        _, res = train_full_state_agent(task, train_steps=steps, seed=seed, encoder=encoder,
                                        eval_episodes=rl.eval_episodes,
                                        curve_points=rl.curve_points, progress=False, **params)
        wall = time.perf_counter() - t0
        row = {"task": args.task, "seed": seed, "train_steps": steps,
               "success": res.eval_success_rate, "return": res.eval_return,
               "kept_step": res.extras.get("kept_step"), "curve_steps": res.curve_steps,
               "curve_success": res.curve_success, "wall_s": round(wall, 1),
               "backend": args.backend, "passes_90": res.eval_success_rate >= 0.9}
        print(f"seed {seed}: success {res.eval_success_rate:.1%}, return "
              f"{res.eval_return:.1f}, kept step {row['kept_step']}, curve "
              f"{[round(s, 2) for s in res.curve_success]}, {wall:.0f} s", flush=True)
        with out.open("a") as f:
            f.write(json.dumps(row) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
