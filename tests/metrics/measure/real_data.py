"""Measurements behind issue 13's closing note, on real PegInHole-v0 arrays (not a test; run
by hand).

    python tests/metrics/measure/real_data.py collect            # ~35 s physics-only
    python tests/metrics/measure/real_data.py cost [metrics] [z-variants]
    python tests/metrics/measure/real_data.py sweep [metrics]

``collect``: 25 x 300 backwards-exploration steps with uniform (off-grid) holes, seed 1000, and
10 x 100 grid steps standing in for the on-policy rows; ``cost``: every metric's value and time
on those 8500 rows for representations built from z°; ``sweep``: z = z° with the hole shifted per
episode by N(0, σ²), the experiment of FACTS.md whose SAC returns are known.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats

OUT = Path("/tmp/met")
SIGMAS = [0.0, 0.002, 0.005, 0.01, 0.03]
FACTS_RETURN = [892, 588, 311, 175, 74]  # FACTS.md, SAC 10k steps, mean of seeds 0-1


def collect() -> None:
    from repbench_tasks.peg_in_hole import PegInHoleTask

    OUT.mkdir(exist_ok=True)
    out = {}
    for name, task, eps, steps, seed in (
            ("heldout", PegInHoleTask(horizon=300, hole_sampling="uniform", camera=False), 25,
             300, 1000),
            ("second", PegInHoleTask(horizon=100, camera=False), 10, 100, 1)):
        t = time.time()
        ds = task.collect("random", n_episodes=eps, steps_per_episode=steps, seed=seed,
                          progress=False)
        obs = ds.obs()
        out.update({f"{name}_z_true": ds.true_state, f"{name}_episode": ds.episode,
                    f"{name}_proprio": obs["proprio"], f"{name}_task_state": task.task_state(obs),
                    f"{name}_action": ds.action})
        print(f"{name}: {time.time() - t:.1f} s, contact {ds.metadata.get('contact_share')}")
    np.savez_compressed(OUT / "real.npz", **out)


def load() -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    from repbench_tasks.peg_in_hole import PegInHoleTask

    f = np.load(OUT / "real.npz")

    def cat(k: str) -> np.ndarray:
        return np.concatenate([f[f"heldout_{k}"], f[f"second_{k}"]])

    z_true = cat("z_true").astype(np.float64)
    episode = np.concatenate([f["heldout_episode"], f["second_episode"] + 1000])
    source = np.r_[np.zeros(len(f["heldout_episode"]), int), np.ones(len(f["second_episode"]),
                                                                        int)]
    proprio = cat("proprio" if "heldout_proprio" in f.files else "robot_state")
    extra = {"task_state": cat("task_state"), "action": cat("action"), "source": source,
             "robot_state": PegInHoleTask().robot_state({"proprio": proprio})}
    return z_true, episode, source, extra


def run(name: str, z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, source: np.ndarray,
        extra: dict[str, np.ndarray], **params: object) -> tuple[object, float, int]:
    from repbench.registry import metrics

    fn = metrics.get(name)
    idx = np.flatnonzero(source == 1) if fn.rows == "on_policy" else np.arange(len(z))
    kw = {k: extra[k][idx] for k in fn.extra_inputs}
    t = time.time()
    res = fn(z[idx], z_true[idx], episode[idx], 0, **kw, **params)
    return res, time.time() - t, idx.size


def cost(names: list[str], variants: list[str]) -> None:
    z_true, episode, source, extra = load()
    rng = np.random.default_rng(0)
    n = len(z_true)
    shifted = z_true.copy()
    shifted[:, 14:16] += 0.005 * rng.standard_normal((episode.max() + 1, 2))[episode]
    zs = {"oracle": z_true, "hole_sigma_0.5cm": shifted,
          "robot_copy": np.hstack([extra["robot_state"], rng.standard_normal((n, 10))]),
          "noise": rng.standard_normal((n, 16))}
    for m in names:
        for v in variants:
            res, dt, rows = run(m, zs[v], z_true, episode, source, extra)
            print(f"{m:22s} {v:17s} rows {rows:5d} value {res.value:9.4f} "
                  f"ci [{res.ci_low}, {res.ci_high}] time {dt:6.1f}s", flush=True)


def sweep(names: list[str]) -> None:
    z_true, episode, source, extra = load()
    shift = np.random.default_rng(0).standard_normal((episode.max() + 1, 2))
    out = {}
    for m in names:
        vals, times = [], []
        for s in SIGMAS:
            z = z_true.copy()
            z[:, 14:16] += s * shift[episode]
            res, dt, _ = run(m, z, z_true, episode, source, extra, n_bootstrap=0)
            vals.append(res.value)
            times.append(dt)
        sign = 1.0 if res.higher_is_better else -1.0
        rho = float(stats.spearmanr(sign * np.array(vals), FACTS_RETURN).statistic)
        out[m] = {"values": vals, "spearman_vs_return": rho, "mean_time_s": float(np.mean(times))}
        print(f"{m:22s} rho {rho:+.2f}  values " + " ".join(f"{v:.4g}" for v in vals)
              + f"  ({np.mean(times):.1f} s)", flush=True)
    (OUT / f"sweep_{'_'.join(names)}.json").write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    from repbench.registry import metrics as _metrics

    cmd = sys.argv[1] if len(sys.argv) > 1 else "cost"
    chosen = sys.argv[2].split(",") if len(sys.argv) > 2 else _metrics.names()
    if cmd == "collect":
        collect()
    elif cmd == "cost":
        cost(chosen, sys.argv[3].split(",") if len(sys.argv) > 3 else ["oracle"])
    else:
        sweep(chosen)
