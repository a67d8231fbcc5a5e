"""Speed of the peg-in-hole environment: tuned wrist rendering vs robosuite's default rendering
vs physics only, measured in the same run (run with ``pytest --benchmark-only -m "slow or not
slow" tests/tasks``). The ratios are printed at the end of the session and stored in
``extra_info``. Other processes share the cores, so ratios of the best rounds are printed beside
the ratios of the means."""

from __future__ import annotations

import numpy as np
import pytest

from repbench_tasks.peg_in_hole import PegInHoleTask

STEPS = 20
RATES: dict[str, float] = {}
BEST: dict[str, float] = {}
MODES = {"physics_only": {"camera": False}, "default_render": {"fast_render": False},
         "tuned_render": {}}


@pytest.mark.benchmark(group="peg-in-hole env steps")
@pytest.mark.parametrize("mode", list(MODES))
def test_env_steps_per_second(benchmark, mode: str) -> None:
    env = PegInHoleTask(horizon=10_000, **MODES[mode]).make_env().unwrapped
    actions = np.random.default_rng(0).uniform(-1, 1, (STEPS, 3)).astype(np.float32)
    env.reset(seed=0, options={"start": "inserted"})

    def run() -> None:
        for a in actions:
            env.step(a)

    try:
        benchmark.pedantic(run, rounds=5 if mode == "default_render" else 15, warmup_rounds=1)
    finally:
        env.close()
    RATES[mode] = STEPS / benchmark.stats.stats.mean
    BEST[mode] = STEPS / benchmark.stats.stats.min
    benchmark.extra_info["steps_per_s"] = RATES[mode]
    benchmark.extra_info["steps_per_s_best_round"] = BEST[mode]
    if mode == "tuned_render" and {"physics_only", "default_render"} <= RATES.keys():
        for label, rates in (("mean", RATES), ("best round", BEST)):
            ratios = {"tuned_over_default": rates["tuned_render"] / rates["default_render"],
                      "tuned_over_physics": rates["tuned_render"] / rates["physics_only"]}
            if label == "mean":
                benchmark.extra_info.update(ratios)
            print(f"\npeg-in-hole steps/s ({label}): "
                  + ", ".join(f"{k} {v:.1f}" for k, v in rates.items())
                  + f"; tuned/default = {ratios['tuned_over_default']:.1f}x, "
                  f"tuned/physics-only = {ratios['tuned_over_physics']:.0%}")
