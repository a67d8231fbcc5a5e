"""Speed: the encoder in the loop must cost little (target: VAE ≥ 90 % of the oracle's steps/s).

Run with ``pytest --benchmark-only -m "slow or not slow" tests/rl -s``. Each benchmark measures
the oracle and a VAE encoder in the same run, alternating rounds so machine load hits both
alike, and reports the ratio in ``extra_info`` (and on stdout with ``-s``).
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np
import pytest

import repbench
from repbench.rl import SACAgent, make_encoded_env
from repbench.rl.agents import torch_threads
from repbench.testing.toy_task import ToyReachTask

from .rl_test_encoders import ConvEncoder, TrueStateEncoder


def _task(name: str) -> Any:
    if name == "toy":
        return ToyReachTask(horizon=50)
    try:
        return repbench.tasks.get(name)(horizon=50)
    except Exception as exc:  # the real task may not be installed yet
        pytest.skip(f"task {name} unavailable: {exc}")


def _encoders(task: Any) -> dict[str, repbench.Encoder]:
    data = task.collect("random", n_episodes=2, steps_per_episode=20, seed=0, progress=False)
    try:
        oracle = repbench.encoders.get("oracle")().fit(data)
        vae = repbench.encoders.get("vae_lowkl")(latent_dim=16, epochs=1, batch_size=16,
                                                  progress=False).fit(data)
    except Exception:  # the encoder plugins may not be installed yet: VAE-sized stand-ins
        oracle = TrueStateEncoder().fit(data)
        vae = ConvEncoder(latent_dim=16).fit(data)
    return {"oracle": oracle, "vae": vae}


def _env_rate(env: Any, n: int, seed: int = 0) -> float:
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    t0 = time.perf_counter()
    for _ in range(n):
        _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, env.action_space.shape))
        if term or trunc:
            env.reset()
    return n / (time.perf_counter() - t0)


@pytest.mark.parametrize("task_name", ["toy", "PegInHole-v0"])
def test_env_steps_vae_vs_oracle(benchmark, task_name):
    task = _task(task_name)
    encs = _encoders(task)
    envs = {k: make_encoded_env(task, e, seed=0) for k, e in encs.items()}
    raw = task.make_env(seed=0)
    rates: dict[str, list[float]] = {"raw": [], "oracle": [], "vae": []}
    n = 300 if task_name == "toy" else 100
    with torch_threads(1):  # as during training
        for _ in range(5):
            rates["raw"].append(_env_rate(raw, n))
            for k, env in envs.items():
                rates[k].append(_env_rate(env, n))
        med = {k: statistics.median(v) for k, v in rates.items()}
        ratio = med["vae"] / med["oracle"]
        benchmark.extra_info.update({f"{k}_steps_per_s": v for k, v in med.items()})
        benchmark.extra_info["vae_over_oracle"] = ratio
        benchmark.extra_info["vae_encode_ms"] = 1e3 * (1 / med["vae"] - 1 / med["oracle"])
        print(f"\n[{task_name}] env steps/s raw {med['raw']:.0f}, oracle {med['oracle']:.0f}, "
              f"VAE {med['vae']:.0f} ({type(encs['vae']).__name__}); VAE/oracle = {ratio:.3f}")
        benchmark.pedantic(_env_rate, args=(envs["vae"], n), rounds=3, iterations=1)


@pytest.mark.parametrize("task_name", ["toy", "PegInHole-v0"])
def test_training_steps_vae_vs_oracle(benchmark, task_name):
    """SAC training steps/s (updates included), oracle vs VAE, same run."""
    task = _task(task_name)
    encs = _encoders(task)
    agent = SACAgent(learning_starts=100, batch_size=256, curve_episodes=1, progress=False)
    steps = 600 if task_name == "toy" else 300
    rates: dict[str, list[float]] = {"oracle": [], "vae": []}
    for rnd in range(2):
        for k, enc in encs.items():
            res = agent.train(task, enc, train_steps=steps, seed=rnd, eval_episodes=1,
                              curve_points=1, progress=False)
            rates[k].append(res.steps_per_s)
    med = {k: statistics.median(v) for k, v in rates.items()}
    ratio = med["vae"] / med["oracle"]
    benchmark.extra_info.update({f"{k}_train_steps_per_s": v for k, v in med.items()})
    benchmark.extra_info["vae_over_oracle"] = ratio
    print(f"\n[{task_name}, SAC training] steps/s oracle {med['oracle']:.1f}, "
          f"VAE {med['vae']:.1f}; VAE/oracle = {ratio:.3f}")
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)


def _updates_per_s(model: Any, n: int) -> float:
    t0 = time.perf_counter()
    model.train(gradient_steps=n, batch_size=256)
    return n / (time.perf_counter() - t0)


def test_sac_update_step_threads(benchmark):
    """SAC gradient updates/s (batch 256, 256×256 networks as the privileged agent uses) with
    one torch thread vs two, alternating rounds in the same run; the faster one is adopted
    as ``torch_threads``'s default."""
    task = ToyReachTask(horizon=50)
    enc = TrueStateEncoder().fit(task.collect("random", n_episodes=2, steps_per_episode=20,
                                              seed=0, progress=False))
    agent = SACAgent(hidden_sizes=(256, 256), learning_starts=0, progress=False)
    env = make_encoded_env(task, enc, seed=0)
    model = agent.build_model(env, seed=0, buffer_size=2000)
    model.learn(total_timesteps=600, progress_bar=False)  # fills the buffer, warms up
    rates: dict[int, list[float]] = {1: [], 2: []}
    for _ in range(3):
        for threads in rates:
            with torch_threads(threads):
                rates[threads].append(_updates_per_s(model, 200))
    med = {k: statistics.median(v) for k, v in rates.items()}
    benchmark.extra_info.update({f"threads_{k}_updates_per_s": v for k, v in med.items()})
    benchmark.extra_info["two_over_one"] = med[2] / med[1]
    print(f"\n[SAC update step] updates/s 1 thread {med[1]:.0f}, 2 threads {med[2]:.0f}; "
          f"2/1 = {med[2] / med[1]:.2f}")
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)


def test_env_steps_without_rendering(benchmark):
    """PegInHole env steps/s for an encoder that reads no image (physics only) vs one that
    does (rendered wrist camera), same run."""
    task = _task("PegInHole-v0")
    envs = {"rendered": task.make_agent_env(seed=0, modalities=("image", "ft", "proprio")),
            "physics_only": task.make_agent_env(seed=0, modalities=("proprio", "true_state"))}
    rates: dict[str, list[float]] = {k: [] for k in envs}
    for _ in range(3):
        for k, env in envs.items():
            rates[k].append(_env_rate(env, 100))
    med = {k: statistics.median(v) for k, v in rates.items()}
    benchmark.extra_info.update({f"{k}_steps_per_s": v for k, v in med.items()})
    ratio = med["physics_only"] / med["rendered"]
    benchmark.extra_info["physics_only_over_rendered"] = ratio
    print(f"\n[PegInHole env] steps/s rendered {med['rendered']:.0f}, physics only "
          f"{med['physics_only']:.0f}; ratio {ratio:.2f}")
    for env in envs.values():
        env.close()
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)


# -- issue 20: the levers of a cheaper RL stage, each old vs new in the same run ----------------

def _filled_model(agent: SACAgent) -> Any:
    """A SAC model on the toy task (22 features, as a 16-D latent ⊕ 6-D robot state) with a
    filled replay buffer, ready to time gradient updates."""
    task = ToyReachTask(horizon=50)
    enc = TrueStateEncoder().fit(task.collect("random", n_episodes=2, steps_per_episode=20,
                                              seed=0, progress=False))
    model = agent.build_model(make_encoded_env(task, enc, seed=0), seed=0, buffer_size=2000)
    model.learn(total_timesteps=600, progress_bar=False)  # fills the buffer, warms up
    return model


def test_sac_update_width_256_vs_128(benchmark):
    """SB3 SAC gradient updates/s with quick's 256×256 networks vs the paper's 128×128, one
    torch thread, alternating rounds in the same run."""
    models = {w: _filled_model(SACAgent(hidden_sizes=(w, w), learning_starts=0,
                                        progress=False)) for w in (256, 128)}
    rates: dict[int, list[float]] = {w: [] for w in models}
    with torch_threads(1):
        for _ in range(3):
            for w, model in models.items():
                rates[w].append(_updates_per_s(model, 200))
    med = {k: statistics.median(v) for k, v in rates.items()}
    benchmark.extra_info.update({f"width_{k}_updates_per_s": v for k, v in med.items()})
    benchmark.extra_info["w128_over_w256"] = med[128] / med[256]
    print(f"\n[SAC update] updates/s 256x256 {med[256]:.0f}, 128x128 {med[128]:.0f}; "
          f"128/256 = {med[128] / med[256]:.2f}")
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)


def test_sac_update_sb3_vs_sbx(benchmark):
    """SB3 (torch) vs SBX (JAX) SAC gradient updates/s, 256×256, one thread each, same run
    (the agents' ``backend = "sbx"``; SBX comes with the ``sbx`` and ``test`` extras)."""
    from repbench.devices import jax_single_thread

    jax_single_thread()  # as the agents do (no effect once JAX is imported)
    sbx = pytest.importorskip("sbx")
    import gymnasium as gym

    class Features(gym.Env):
        observation_space = gym.spaces.Box(-5, 5, (22,), np.float32)
        action_space = gym.spaces.Box(-1, 1, (3,), np.float32)

        def reset(self, *, seed=None, options=None):
            super().reset(seed=seed)
            return self.observation_space.sample(), {}

        def step(self, action):
            return self.observation_space.sample(), 0.0, False, False, {}

    import stable_baselines3 as sb3

    models = {}
    for name, lib in (("sb3", sb3), ("sbx", sbx)):
        m = lib.SAC("MlpPolicy", Features(), policy_kwargs={"net_arch": [256, 256]},
                    learning_starts=0, buffer_size=5000, verbose=0, seed=0)
        m.learn(600)
        m.train(gradient_steps=1, batch_size=256)  # SBX compiles its update here
        models[name] = m
    rates: dict[str, list[float]] = {k: [] for k in models}
    with torch_threads(1):
        for _ in range(3):
            for k, m in models.items():
                t0 = time.perf_counter()
                for _ in range(100):
                    m.train(gradient_steps=1, batch_size=256)
                rates[k].append(100 / (time.perf_counter() - t0))
    med = {k: statistics.median(v) for k, v in rates.items()}
    benchmark.extra_info.update({f"{k}_updates_per_s": v for k, v in med.items()})
    benchmark.extra_info["sbx_over_sb3"] = med["sbx"] / med["sb3"]
    print(f"\n[SAC update 256x256] updates/s SB3 {med['sb3']:.0f}, SBX {med['sbx']:.0f}; "
          f"SBX/SB3 = {med['sbx'] / med['sb3']:.2f}")
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)


def test_encode_one_at_a_time_vs_batched(benchmark):
    """The saving a vectorized evaluation could bring: a VAE encoding 5 evaluation
    observations one call each (today) vs in one batched call, same run (issue 20 measured it
    at ~1 ms per step, against ~1 s to build each extra PegInHole environment: not adopted)."""
    task = ToyReachTask(horizon=50)
    data = task.collect("random", n_episodes=2, steps_per_episode=20, seed=0, progress=False)
    enc = _encoders(task)["vae"]
    rows = [data.obs(slice(i, i + 1)) for i in range(5)]
    batch = data.obs(slice(0, 5))
    times: dict[str, list[float]] = {"one_at_a_time": [], "batched": []}
    with torch_threads(1):
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(20):
                for r in rows:
                    enc.encode(r)
            times["one_at_a_time"].append((time.perf_counter() - t0) / 100)
            t0 = time.perf_counter()
            for _ in range(20):
                enc.encode(batch)
            times["batched"].append((time.perf_counter() - t0) / 100)
    med = {k: statistics.median(v) for k, v in times.items()}
    benchmark.extra_info.update({f"{k}_ms_per_obs": 1e3 * v for k, v in med.items()})
    benchmark.extra_info["saving_ms_per_obs"] = 1e3 * (med["one_at_a_time"] - med["batched"])
    print(f"\n[encode] ms per observation: one at a time {1e3 * med['one_at_a_time']:.2f}, "
          f"batched by 5 {1e3 * med['batched']:.2f}")
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)
