"""Learnability of a task at quick's privileged budget: the privileged SAC agent (task-frame
state ⊕ robot state, ``oracle_task``), trained exactly as the quick suite's full-state stage
trains it, must reach >= 90 % evaluation success in every seed (issue 22).

    nice -n 19 python studies/task_learnability/learnability.py --task SurfacePress-v0 \\
        --seeds 0 1 2

``--encoder proprio_only`` trains the blind baseline instead, as the suite's RL stage does
(``repbench.pipeline.stages._run_rl``): the suite's SAC agent (``[agent_params.sac]``) on the
frozen ``proprio_only`` encoder for the task's ``train_steps`` (``[rl]`` with ``[task_rl]``), fitted
on a ``random`` dataset of ``--fit-episodes`` x the horizon (the suite fits it on its 25 x 300
exploration data; the encoder only standardizes, so a smaller dataset changes little). The issue
asks this one to FAIL:

    nice -n 19 python studies/task_learnability/learnability.py --task Door-v0 --seeds 0 1 2 \
        --encoder proprio_only

Prints one line per seed (success, return, kept step, wall time) and writes them as JSON lines
to ``--out`` (default ``learnability_<task>.jsonl`` beside this file).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

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
    ap.add_argument("--encoder", default="oracle_task", choices=("oracle_task", "proprio_only"),
                    help="oracle_task: the privileged agent (default); proprio_only: the blind "
                    "baseline's SAC with the suite's RL settings")
    ap.add_argument("--fit-episodes", type=int, default=25,
                    help="random episodes the proprio_only encoder is fitted on")
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
    suffix = "" if args.encoder == "oracle_task" else f"_{args.encoder}"
    out = Path(args.out or Path(__file__).with_name(f"learnability_{args.task}{suffix}.jsonl"))
    if args.encoder != "oracle_task":
        return _blind(args, suite, task, out)
    _smoke_learning_starts(params, steps)
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


def _smoke_learning_starts(params: dict[str, Any], steps: int) -> None:
    """A smoke run (``--steps`` below ``learning_starts``): start learning at half the steps."""
    starts = int(params.get("learning_starts", 1000))
    if steps <= starts:
        params["learning_starts"] = max(steps // 2, 1)
        print(f"smoke run: learning_starts {starts} -> {params['learning_starts']} "
              f"(--steps {steps})", flush=True)


def _blind(args: argparse.Namespace, suite: Any, task: Any, out: Path) -> int:
    """The suite's RL stage on a frozen baseline encoder (as ``stages._run_rl``)."""
    rl = suite.rl_for(args.task)
    params = dict(suite.agent_params.get("sac", {}))
    steps = args.steps or rl.train_steps
    _smoke_learning_starts(params, steps)
    horizon = int(getattr(task, "horizon", 100))
    data = task.collect("random", n_episodes=args.fit_episodes, steps_per_episode=horizon,
                        seed=suite.dataset.seed, progress=False)
    print(f"{args.task}: {args.encoder} SAC, {steps} steps, eval {rl.eval_episodes} episodes, "
          f"params {params}", flush=True)
    for seed in args.seeds:
        t0 = time.perf_counter()
        encoder = repbench.encoders.get(args.encoder)().fit(data)
        agent = repbench.agents.get("sac")(**params)
        res = agent.train(task, encoder, train_steps=steps, seed=seed,
                          eval_episodes=rl.eval_episodes, curve_points=rl.curve_points,
                          progress=False)
        wall = time.perf_counter() - t0
        row = {"task": args.task, "encoder": args.encoder, "seed": seed, "train_steps": steps,
               "success": res.eval_success_rate, "return": res.eval_return,
               "curve_steps": res.curve_steps, "curve_success": res.curve_success,
               "wall_s": round(wall, 1), "fails_below_50": res.eval_success_rate < 0.5}
        print(f"seed {seed}: success {res.eval_success_rate:.1%}, return "
              f"{res.eval_return:.1f}, curve {[round(s, 2) for s in res.curve_success]}, "
              f"{wall:.0f} s", flush=True)
        with out.open("a") as f:
            f.write(json.dumps(row) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
