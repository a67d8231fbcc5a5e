"""Sanity that can fail: with the quick budget, SAC on the true state clearly beats SAC on the
``random`` encoder (untrained VAE encoder; paper: RL performance follows information content).

Run with ``pytest -m slow tests/rl/test_rl_sanity.py -s`` (prints the numbers).
"""

from __future__ import annotations

import pytest
from scipy import stats

import repbench
from repbench.testing.toy_task import ToyReachTask


def _task(name: str):
    if name == "toy":
        return ToyReachTask(horizon=50)
    try:
        suite = repbench.load_suite("quick")
        return repbench.tasks.get(name)(**suite.task_params.get(name, {}))
    except repbench.RepbenchError as exc:
        pytest.skip(f"task {name} unavailable: {exc}")


def _encoders(task):
    data = task.collect("random", n_episodes=5, steps_per_episode=50, seed=0, progress=False)
    try:
        oracle = repbench.encoders.get("oracle")().fit(data)
        random = repbench.encoders.get("random")(latent_dim=16).fit(data)
    except repbench.RepbenchError:  # encoder plugins not installed: the test-local stand-ins
        from .rl_test_encoders import NoiseEncoder, TrueStateEncoder

        oracle, random = TrueStateEncoder().fit(data), NoiseEncoder(latent_dim=16).fit(data)
    return oracle, random


@pytest.mark.slow
@pytest.mark.parametrize("task_name", [
    "toy",
    pytest.param("PegInHole-v0", marks=pytest.mark.xfail(
        strict=False, reason="measured: the quick budget (5k steps, seed 0) does not separate "
        "them on peg-in-hole yet: oracle 105.6 vs random 79.5, p = 0.23, no successes")),
])
def test_sac_oracle_beats_random_encoder_on_quick_budget(task_name):
    task = _task(task_name)
    rl = repbench.load_suite("quick").rl  # train_steps 5000, eval_episodes 10, 5 curve points
    oracle, random = _encoders(task)
    results = {}
    for name, enc in (("oracle", oracle), ("random", random)):
        results[name] = repbench.agents.get("sac")(progress=False).train(
            task, enc, train_steps=rl.train_steps, seed=0, eval_episodes=rl.eval_episodes,
            curve_points=rl.curve_points, progress=False)
        r = results[name]
        print(f"\n[{task_name}] SAC on {name} ({type(enc).__name__}): eval return "
              f"{r.eval_return:.2f}, success {r.eval_success_rate:.2f}, curve "
              f"{[round(x, 1) for x in r.curve_return]}, {r.steps_per_s:.1f} steps/s, "
              f"{r.wall_time_s:.0f} s")
    o, r = results["oracle"], results["random"]
    # the same 10 evaluation episodes (hole positions, initial states) for both encoders:
    # one-sided Welch t-test on the per-episode returns, and a mean gap of at least 10 %
    # of the oracle's return scale
    test = stats.ttest_ind(o.eval_episode_returns, r.eval_episode_returns, equal_var=False,
                           alternative="greater")
    print(f"[{task_name}] oracle - random = {o.eval_return - r.eval_return:.2f}, "
          f"one-sided p = {test.pvalue:.2g}")
    assert test.pvalue < 0.01
    assert o.eval_return - r.eval_return > 0.1 * abs(o.eval_return)
    if task_name == "toy":  # returns in [-2.9 * 50, 50]: the oracle reaches every hole
        assert o.eval_success_rate >= r.eval_success_rate + 0.5
