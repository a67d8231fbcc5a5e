"""Door-v0 checks of issue 22 (scripted privileged controller, blind open-loop scripts, what each
modality says about the configuration, speed, contact forces).

    MUJOCO_GL=egl nice -n 19 python studies/task_learnability/door_checks.py privileged
    ... door_checks.py blind      # recorded-and-replayed privileged scripts + sweeps
    ... door_checks.py probes     # R^2 of the configuration from proprio / ft / image
    ... door_checks.py speed      # env steps/s with the camera, Door-v0 vs PegInHole-v0

Prints its numbers; nothing is written.
"""

from __future__ import annotations

import sys
import time

import numpy as np

import repbench  # noqa: F401  (MUJOCO_GL)
from repbench_tasks.door import DoorTask
from repbench_tasks.scripted import PrivilegedDoor, ReplayDoor


def rollout(env, policy, reset) -> dict:
    if hasattr(policy, "reset"):
        policy.reset()
    obs, info = env.reset(seed=reset["seed"], options=reset["options"])
    ret, succ, forces, actions = 0.0, False, [], []
    for _ in range(env.config.horizon):
        a = policy({**obs, "true_state": info["true_state"]})
        actions.append(a)
        obs, r, _, _, info = env.step(a)
        ret += r
        succ |= info["is_success"]
        forces.append(float(np.linalg.norm(obs["ft"][:3])))
    return {"return": ret, "success": succ, "forces": np.array(forces),
            "actions": np.array(actions), "angle": info["door_angle"]}


def privileged(n: int = 40) -> None:
    task = DoorTask(camera=False)
    env = task.make_env().unwrapped
    res = [rollout(env, PrivilegedDoor(), r) for r in task.evaluation_resets(n)]
    f = np.concatenate([r["forces"] for r in res])
    print(f"privileged script: success {np.mean([r['success'] for r in res]):.1%} on {n} "
          f"evaluation resets, mean return {np.mean([r['return'] for r in res]):.1f}, wrist "
          f"|F| median {np.median(f):.2f} N, p99 {np.quantile(f, 0.99):.2f} N, max {f.max():.2f} N")


def sweep_actions(x0: float, y0: float, down: int, pull: tuple[float, float], horizon: int,
                  raster: float = 0.0) -> np.ndarray:
    """Open loop: go down ``down`` steps at (x0, y0) offset actions, then raster in y while
    pressing down (``raster`` amplitude), then pull in direction ``pull``."""
    acts = []
    for t in range(horizon):
        if t < 6:
            a = [x0, y0, 0.0]
        elif t < 6 + down:
            a = [0.0, 0.0, -1.0]
        elif raster and t < 6 + down + 8:
            a = [0.0, raster * (1 if (t // 4) % 2 == 0 else -1), -0.3]
        else:
            a = [pull[0], pull[1], -0.2]
        acts.append(a)
    return np.clip(np.array(acts, np.float32), -1, 1)


def blind(n: int = 40) -> None:
    task = DoorTask(camera=False)
    env = task.make_env().unwrapped
    resets = task.evaluation_resets(n)
    grid = task.config().grid_configs()
    rates = {}
    for idx in range(len(grid)):  # the privileged script recorded on each grid configuration
        rec = rollout(env, PrivilegedDoor(), {"seed": 0, "options": {"config_index": idx}})
        rate = np.mean([rollout(env, ReplayDoor(rec["actions"]), r)["success"] for r in resets])
        rates[f"replay grid {idx}"] = rate
    rng = np.random.default_rng(0)
    for k in range(40):  # sweeps: down somewhere, optionally raster, pull in some direction
        x0, y0 = rng.uniform(-1, 1, 2)
        ang = rng.uniform(-np.pi / 2, np.pi / 2) + np.pi  # towards the robot (-x) +- 90 deg
        acts = sweep_actions(x0, y0, int(rng.integers(4, 9)), (np.cos(ang), np.sin(ang)),
                             env.config.horizon, raster=float(rng.choice([0.0, 0.5, 1.0])))
        rates[f"sweep {k}"] = np.mean([rollout(env, ReplayDoor(acts), r)["success"]
                                       for r in resets])
    ranked = sorted(rates.items(), key=lambda kv: -kv[1])
    print(f"blind open-loop scripts: {len(rates)} tried on {n} evaluation resets; best "
          f"{ranked[0][0]} {ranked[0][1]:.1%}; top 5 {[(k, round(v, 3)) for k, v in ranked[:5]]};"
          f" mean {np.mean(list(rates.values())):.1%}")


def probes() -> None:
    from sklearn.decomposition import PCA
    from sklearn.linear_model import RidgeCV
    from sklearn.neural_network import MLPRegressor
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    from repbench_tasks.door import CONFIG

    task = DoorTask()
    ds = task.collect("random", n_episodes=25, steps_per_episode=40, seed=0, progress=False)
    y = ds.true_state[:, CONFIG].astype(np.float64)
    test = np.isin(ds.episode, [0, 6, 12, 18, 24])  # whole episodes (a grid diagonal) held out
    feats = {"proprio": ds.observations["proprio"], "ft": ds.observations["ft"],
             "image": ds.observations["image"].reshape(len(ds), -1) / 255.0}
    print(f"random data {len(ds)} steps, contact share {ds.metadata['contact_share']:.2f}, "
          f"success share {ds.metadata['success_share']:.2f}; held-out: 5 whole episodes")
    for name, x in feats.items():
        x = np.asarray(x, np.float64)
        pca = [PCA(32)] if name == "image" else []
        ridge = make_pipeline(StandardScaler(), RidgeCV(np.logspace(-3, 3, 13)))
        mlp = make_pipeline(StandardScaler(), *pca,
                            MLPRegressor(hidden_layer_sizes=(64, 64), max_iter=600, random_state=0))
        for label, model in (("ridge", ridge), ("mlp", mlp)):
            model.fit(x[~test], y[~test])
            pred = model.predict(x[test])
            r2 = 1 - ((pred - y[test]) ** 2).sum(0) / ((y[test] - y[test].mean(0)) ** 2).sum(0)
            print(f"  {name:8s} {label:5s} R^2 shift {r2[0]:+.2f} yaw {r2[1]:+.2f}")
    env = task.make_env().unwrapped  # the start image: does it carry the configuration?
    xs, ys = [], []
    for r in task.evaluation_resets(40) + [{"seed": s, "options": {"config_index": s % 25}}
                                           for s in range(60)]:
        obs, info = env.reset(**r)
        xs.append(obs["image"].reshape(-1) / 255.0)
        ys.append(info["true_state"][CONFIG])
    xs, ys = np.array(xs), np.array(ys, np.float64)
    m = make_pipeline(StandardScaler(), PCA(20), RidgeCV(np.logspace(-3, 3, 13)))
    m.fit(xs[40:], ys[40:])
    p = m.predict(xs[:40])
    r2 = 1 - ((p - ys[:40]) ** 2).sum(0) / ((ys[:40] - ys[:40].mean(0)) ** 2).sum(0)
    print(f"  start image -> config (PCA20+ridge, 60 train / 40 eval resets): R^2 shift "
          f"{r2[0]:+.2f} yaw {r2[1]:+.2f}")


def speed(steps: int = 300) -> None:
    from repbench_tasks.peg_in_hole import PegInHoleTask

    for name, task in (("Door-v0", DoorTask()), ("PegInHole-v0", PegInHoleTask()),
                       ("Door-v0", DoorTask())):
        env = task.make_env().unwrapped
        env.reset(seed=0)
        rng = np.random.default_rng(0)
        t0 = time.perf_counter()
        for i in range(steps):
            env.step(rng.uniform(-1, 1, 3).astype(np.float32))
            if (i + 1) % 50 == 0:
                env.reset(seed=i)
        dt = time.perf_counter() - t0
        print(f"  {name}: {steps / dt:.0f} env steps/s with the 64x64 wrist camera")
        env.close()


if __name__ == "__main__":
    {"privileged": privileged, "blind": blind, "probes": probes, "speed": speed}[sys.argv[1]]()
