"""Sanity that can fail: with the quick budget, SAC on the true state clearly beats SAC on the
``random`` encoder (untrained VAE encoder; paper: RL performance follows information content).

Run with ``pytest -m slow tests/rl/test_rl_sanity.py -s`` (prints the numbers). The three
training seeds run in parallel worker processes (two at a time on two cores).

The statistic was fixed before the runs it judges: for every training seed both agents are
evaluated on the same 10 episodes (reset seeds ``10_000 + i``: the same hole positions and
initial states), so the comparison is paired. The oracle must (1) beat the random encoder's
mean return in every seed, (2) win a one-sided Wilcoxon signed-rank test over the 30 paired
episodes at p < 0.01, and (3) lead by more than 10 % of its own mean return.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np
import pytest
from scipy import stats

import repbench
from repbench.testing.toy_task import ToyReachTask

SEEDS = (0, 1, 2)


def _task(name: str):
    if name == "toy":
        return ToyReachTask(horizon=50)
    suite = repbench.load_suite("quick")
    return repbench.tasks.get(name)(**suite.task_params.get(name, {}))


def _encoders(task):
    data = task.collect("random", n_episodes=5, steps_per_episode=50, seed=0, progress=False)
    try:
        oracle = repbench.encoders.get("oracle")().fit(data)
        random = repbench.encoders.get("random")(latent_dim=16).fit(data)
    except repbench.RepbenchError:  # encoder plugins not installed: the test-local stand-ins
        from tests.rl.rl_test_encoders import NoiseEncoder, TrueStateEncoder

        oracle, random = TrueStateEncoder().fit(data), NoiseEncoder(latent_dim=16).fit(data)
    return {"oracle": oracle, "random": random}


def _train(task_name: str, encoder_name: str, seed: int) -> dict:
    """One SAC run with the quick suite's RL budget (a worker process)."""
    task = _task(task_name)
    encoder = _encoders(task)[encoder_name]
    rl = repbench.load_suite("quick").rl  # train_steps 6000, eval_episodes 10, 5 curve points
    r = repbench.agents.get("sac")(progress=False).train(
        task, encoder, train_steps=rl.train_steps, seed=seed, eval_episodes=rl.eval_episodes,
        curve_points=rl.curve_points, progress=False)
    return {"returns": r.eval_episode_returns, "success": r.eval_success_rate,
            "curve": r.curve_return, "steps_per_s": r.steps_per_s, "wall": r.wall_time_s}


@pytest.mark.slow
@pytest.mark.parametrize("task_name", ["toy", "PegInHole-v0"])
def test_sac_oracle_beats_random_encoder_on_quick_budget(task_name):
    try:
        _task(task_name)
    except repbench.RepbenchError as exc:
        pytest.skip(f"task {task_name} unavailable: {exc}")
    jobs = [(task_name, enc, seed) for seed in SEEDS for enc in ("oracle", "random")]
    workers = max(1, min(len(jobs), (os.cpu_count() or 1)))
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
        futures = {job: pool.submit(_train, *job) for job in jobs}
        runs = {job: f.result() for job, f in futures.items()}
    o = np.array([runs[(task_name, "oracle", s)]["returns"] for s in SEEDS])
    r = np.array([runs[(task_name, "random", s)]["returns"] for s in SEEDS])
    for (_, enc, seed), run in runs.items():
        print(f"\n[{task_name}] SAC on {enc}, seed {seed}: eval return "
              f"{np.mean(run['returns']):.1f}, success {run['success']:.2f}, curve "
              f"{[round(x, 1) for x in run['curve']]}, {run['steps_per_s']:.1f} steps/s, "
              f"{run['wall']:.0f} s")
    test = stats.wilcoxon(o.ravel(), r.ravel(), alternative="greater")
    print(f"[{task_name}] per-seed means oracle {o.mean(1).round(1).tolist()} vs random "
          f"{r.mean(1).round(1).tolist()}; paired episodes won {(o > r).sum()}/{o.size}; "
          f"one-sided Wilcoxon p = {test.pvalue:.2g}")
    assert (o.mean(axis=1) > r.mean(axis=1)).all()
    assert test.pvalue < 0.01
    assert o.mean() - r.mean() > 0.1 * abs(o.mean())
    if task_name == "toy":  # returns in [-2.9 * 50, 50]: the oracle reaches every hole
        successes = {e: np.mean([runs[(task_name, e, s)]["success"] for s in SEEDS])
                     for e in ("oracle", "random")}
        assert successes["oracle"] >= successes["random"] + 0.5
