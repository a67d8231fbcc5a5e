"""Issue 43, item 2, part 1: can raw robot state and force/torque readings identify the spring?

Collects SurfacePress-v0's ``random`` (training, grid configurations) and ``heldout`` (off-grid
configurations) datasets exactly as the ``quick`` suite's dataset stages do (same task
parameters, episodes, steps and seeds, read from ``repbench/suites/quick.toml``), by default
physics only (``camera=False``: the image is all zeros, nothing else changes; ``--check-camera``
verifies that on the data). Then fits probes on the random dataset and scores held-out R² on the
held-out dataset (whole off-grid episodes, never a split of time steps), for

* targets: log10 stiffness and the rest-height offset (z°), and the 8 columns of
  ``SurfacePressTask.task_state`` (force error among them);
* feature sets: the agent's robot state (tip position and velocity), that plus the current
  F/T reading, that stacked over the last k = 2, 4, 8 steps of the episode (the start padded
  with the first step), F/T alone and F/T history alone, and the k-step stack plus a
  hand-made stiffness estimate ``k_hat`` (the slope of force on tip height over the k steps);
* probes: HistGradientBoostingRegressor (non-linear) and RidgeCV on standardized inputs
  (linear, as the leaderboard's ``task_probe``), and ``k_hat`` itself as a fit-free
  prediction of log10 stiffness (``model = physics``);
* rows: all held-out rows, the rows in contact (wrist force norm above ``--contact-n``) and
  the ``identifiable`` rows (8 steps in contact with the tip moving >= 0.5 mm, where the
  8-step ``k_hat`` is defined).

Writes ``probe.csv`` beside this file. Measured on the 2-core machine under load (one thread):
~18 CPU-s per physics-only dataset (cached after the first run), ~33 CPU-s per camera dataset
for ``--check-camera full``, ~2 CPU-min for the probes: 3 min 43 s of wall time with the full
camera check from nothing, 2 min 28 s with cached data and the default 1-episode check.

    MUJOCO_GL=egl python studies/surface_press_why/probe.py   # datasets cached in /tmp
    MUJOCO_GL=egl python studies/surface_press_why/probe.py --check-camera full
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
TASK = "SurfacePress-v0"
#: Committed checksums of quick's SurfacePress-v0 datasets (leaderboards/quick/records/dataset/).
COMMITTED = {"random": "b2d673a659108aacfb2c8b9469e337bee62a753aa9f3150535ec8b5a84fbfcb7",
             "heldout": "3dc50d633c921656f3919321b158de78bb2855605a3b8ffc493898db8c4987fd"}
KEYS = ("ft", "proprio", "true_state", "action", "reward", "episode")
HISTORY = (2, 4, 8)
KEY_TARGETS = ("log10_k", "rest_offset", "task.force_error", "task.height_above_top",
               "task.setpoint_lead_z")
TASK_COLUMNS = ("dx_plate", "dy_plate", "height_above_top", "force_error", "setpoint_lead_z",
                "tip_vx", "tip_vy", "tip_vz")


# -- data -----------------------------------------------------------------------------------------
def quick_spec(kind: str) -> dict[str, Any]:
    """Task parameters and collection arguments of quick's ``kind`` dataset (as plan.py)."""
    from repbench.pipeline.suite import load_suite

    suite = load_suite("quick")
    ds = suite.dataset_for(TASK)
    params = dict(suite.task_params.get(TASK, {}))
    if kind == "random":
        return {"params": params, "n_episodes": ds.random_episodes,
                "steps": ds.random_steps, "seed": ds.seed}
    params.update(suite.heldout_task_params.get(TASK, {}))
    return {"params": params, "n_episodes": ds.heldout_episodes,
            "steps": ds.heldout_steps or ds.random_steps, "seed": ds.heldout_seed}


def make_task(params: dict[str, Any]) -> Any:
    from repbench.registry import tasks

    return tasks.get(TASK)(**params)


def collect(kind: str, camera: bool, n_episodes: int | None = None) -> tuple[Any, float]:
    """quick's ``kind`` dataset (the first ``n_episodes`` only, if given) and its CPU seconds."""
    spec = quick_spec(kind)
    task = make_task({**spec["params"], "camera": camera})
    t0 = time.process_time()
    ds = task.collect("random", n_episodes=n_episodes or spec["n_episodes"],
                      steps_per_episode=spec["steps"], seed=spec["seed"], progress=False)
    return ds, time.process_time() - t0


def arrays(ds: Any) -> dict[str, np.ndarray]:
    obs = ds.observations
    return {"ft": obs["ft"], "proprio": obs["proprio"], "true_state": ds.true_state,
            "action": ds.action, "reward": ds.reward, "episode": ds.episode}


def load_or_collect(kind: str, cache: Path) -> dict[str, np.ndarray]:
    """Physics-only arrays of quick's ``kind`` dataset, cached as ``cache/<kind>.npz``."""
    path = cache / f"{kind}.npz"
    if path.exists():
        with np.load(path) as f:
            return {k: f[k] for k in KEYS}
    ds, cpu = collect(kind, camera=False)
    print(f"collected {kind} (camera=False): {len(ds)} rows, {cpu:.1f} CPU-s", flush=True)
    data = arrays(ds)
    cache.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **data)
    return data


def check_camera(kind: str, mode: str, physics: dict[str, np.ndarray]) -> list[str]:
    """Compare the camera run with the physics-only arrays: ``short`` (first episode) or
    ``full`` (every episode, plus the camera dataset's checksum against the committed one)."""
    ds, cpu = collect(kind, camera=True, n_episodes=1 if mode == "short" else None)
    cam = arrays(ds)
    n = len(ds)
    lines = [f"{kind}: camera run of {ds.n_episodes} episode(s), {n} rows, {cpu:.1f} CPU-s"]
    for k in KEYS:
        same = np.array_equal(cam[k], physics[k][:n])
        lines.append(f"  {k}: {'identical' if same else 'DIFFERENT'}"
                     + ("" if same else f" (max |diff| {np.abs(cam[k] - physics[k][:n]).max()})"))
    if mode == "full":
        ok = ds.checksum() == COMMITTED[kind]
        lines.append(f"  checksum {'matches' if ok else 'DIFFERS FROM'} the committed record "
                     f"({ds.checksum()[:12]})")
    return lines


# -- features and targets -------------------------------------------------------------------------
def history(x: np.ndarray, episode: np.ndarray, k: int) -> np.ndarray:
    """``x`` at steps t, t-1, ..., t-k+1 of the same episode side by side (the episode's first
    row repeated before its start)."""
    starts = np.searchsorted(episode, episode, side="left")  # each row's episode start
    rows = np.arange(len(x))
    out = [x] + [x[np.maximum(rows - lag, starts)] for lag in range(1, k)]
    return np.concatenate(out, axis=1)


def feature_sets(data: dict[str, np.ndarray], task: Any) -> Iterator[tuple[str, np.ndarray]]:
    robot = task.robot_state({"proprio": data["proprio"]})
    ft = data["ft"].astype(np.float32)
    both = np.concatenate([robot, ft], axis=1)
    yield "robot", robot
    yield "robot+ft", both
    for k in HISTORY:
        yield f"robot+ft x{k}", history(both, data["episode"], k)
    yield "ft", ft
    for k in HISTORY:
        yield f"ft x{k}", history(ft, data["episode"], k)
    for k in HISTORY:
        k_hat = stiffness_estimate(data, k)[:, None]
        yield f"robot+ft x{k} +k_hat", np.concatenate(
            [history(both, data["episode"], k), k_hat], axis=1)


def stiffness_estimate(data: dict[str, np.ndarray], k: int, min_force: float = 1.0,
                       min_span: float = 5e-4) -> np.ndarray:
    """log10 of the spring stiffness from the last ``k`` steps, no fitting: minus the
    least-squares slope of the wrist force's z axis (≈ the spring force, correlation 0.996 in
    contact) on the tip height. NaN unless all ``k`` steps are in contact (force above
    ``min_force`` N), the tip moved at least ``min_span`` m and the slope is positive."""
    force = history(data["ft"][:, 2:3].astype(np.float64), data["episode"], k)
    tip_z = history(data["proprio"][:, 16:17].astype(np.float64), data["episode"], k)
    dz = tip_z - tip_z.mean(1, keepdims=True)
    df = force - force.mean(1, keepdims=True)
    slope = -(dz * df).sum(1) / np.maximum((dz ** 2).sum(1), 1e-12)
    ok = (force > min_force).all(1) & (np.ptp(tip_z, axis=1) >= min_span) & (slope > 0)
    return np.where(ok, np.log10(np.clip(slope, 1.0, None)), np.nan)


def targets(data: dict[str, np.ndarray], task: Any) -> dict[str, np.ndarray]:
    from repbench_tasks.press_env import Z_LOG_K, Z_REST

    z = data["true_state"]
    ts = task.task_state({"proprio": data["proprio"], "true_state": z})
    out = {"log10_k": z[:, Z_LOG_K], "rest_offset": z[:, Z_REST]}
    out.update({f"task.{name}": ts[:, i] for i, name in enumerate(TASK_COLUMNS)})
    return out


# -- probes ---------------------------------------------------------------------------------------
def make_probe(model: str, seed: int) -> Any:
    from sklearn.ensemble import HistGradientBoostingRegressor
    from sklearn.linear_model import RidgeCV
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    if model == "hgb":
        return HistGradientBoostingRegressor(max_iter=300, learning_rate=0.1,
                                             early_stopping=False, random_state=seed)
    return make_pipeline(StandardScaler(), RidgeCV(alphas=np.logspace(-3, 3, 13)))


def r2(y: np.ndarray, pred: np.ndarray) -> float:
    return float(1.0 - np.sum((y - pred) ** 2) / np.sum((y - y.mean()) ** 2))


def contact_rows(data: dict[str, np.ndarray], threshold: float) -> np.ndarray:
    return np.linalg.norm(data["ft"][:, :3], axis=1) > threshold


def run_probes(train: dict[str, np.ndarray], test: dict[str, np.ndarray], models: list[str],
               threshold: float, seed: int) -> list[dict[str, Any]]:
    """Every feature set x model x target; R² on all held-out rows, the rows in contact and the
    rows where the 8-step stiffness estimate is defined (``identifiable``)."""
    task = make_task(quick_spec("random")["params"])
    y_train, y_test = targets(train, task), targets(test, task)
    subsets = {"contact": contact_rows(test, threshold),
               "identifiable": np.isfinite(stiffness_estimate(test, max(HISTORY)))}
    test_sets = dict(feature_sets(test, task))
    rows = physics_rows(test, y_test["log10_k"])
    for fname, x_train in feature_sets(train, task):
        x_test = test_sets[fname]
        for model in models:
            if model == "ridge" and "k_hat" in fname:
                continue  # NaN where the estimate is undefined: trees only
            for tname, y in y_train.items():
                t0 = time.process_time()
                pred = make_probe(model, seed).fit(x_train, y).predict(x_test)
                yt = y_test[tname]
                rows.append({"features": fname, "n_features": x_train.shape[1], "model": model,
                             "target": tname, "r2_heldout": r2(yt, pred),
                             "rmse_heldout": float(np.sqrt(np.mean((yt - pred) ** 2))),
                             "std_heldout": float(yt.std()),
                             **{f"r2_{k}": r2(yt[m], pred[m]) for k, m in subsets.items()},
                             "cpu_s": round(time.process_time() - t0, 2)})
            print(f"  {fname:20s} {model:5s} done", flush=True)
    return rows


def physics_rows(test: dict[str, np.ndarray], log_k: np.ndarray) -> list[dict[str, Any]]:
    """The stiffness estimate itself as the prediction (no fitting), scored on the held-out
    rows where it is defined (``identifiable_share`` of all rows)."""
    rows = []
    for k in HISTORY:
        est = stiffness_estimate(test, k)
        ok = np.isfinite(est)
        rows.append({"features": f"k_hat over {k} steps", "n_features": 2 * k,
                     "model": "physics", "target": "log10_k", "r2_identifiable":
                     r2(log_k[ok], est[ok]), "identifiable_share": round(float(ok.mean()), 3)})
    return rows


def write_csv(rows: list[dict[str, Any]], path: Path) -> None:
    import pandas as pd

    df = pd.DataFrame(rows)
    for c in ("r2_heldout", "r2_contact", "r2_identifiable", "rmse_heldout", "std_heldout"):
        df[c] = df[c].round(4)
    df.to_csv(path, index=False)


def summary(rows: list[dict[str, Any]], model: str, column: str) -> str:
    """One table: feature sets x the five key targets, R² in ``column``."""
    import pandas as pd

    df = pd.DataFrame(rows)
    df = df[(df.model == model) & df.target.isin(KEY_TARGETS)]
    wide = df.pivot_table(index="features", columns="target", values=column, sort=False)
    return wide[[t for t in KEY_TARGETS if t in wide]].round(3).to_string()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cache", type=Path, default=Path("/tmp/surface_press_why"),
                    help="where the physics-only datasets are cached (default %(default)s)")
    ap.add_argument("--check-camera", choices=("none", "short", "full"), default="short",
                    help="compare with the camera run: first episode (short, default) or every "
                         "episode and the committed checksums (full, ~2.5 CPU-min)")
    ap.add_argument("--models", nargs="+", choices=("hgb", "ridge"), default=["hgb", "ridge"])
    ap.add_argument("--contact-n", type=float, default=1.0,
                    help="contact rows: wrist force norm above this (N, default %(default)s)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=HERE / "probe.csv")
    args = ap.parse_args()

    from repbench.devices import torch_threads

    t0, c0 = time.time(), time.process_time()
    with torch_threads(1, blas=True):
        data = {kind: load_or_collect(kind, args.cache) for kind in ("random", "heldout")}
        if args.check_camera != "none":
            for kind in data:
                print("\n".join(check_camera(kind, args.check_camera, data[kind])), flush=True)
        for kind, d in data.items():
            share = contact_rows(d, args.contact_n).mean()
            print(f"{kind}: {len(d['ft'])} rows, {share:.1%} with |F| > {args.contact_n} N")
        rows = run_probes(data["random"], data["heldout"], args.models, args.contact_n,
                          args.seed)
    write_csv(rows, args.out)
    for model in args.models:
        for column in ("r2_heldout", "r2_contact", "r2_identifiable"):
            print(f"\n{model}, {column}:\n{summary(rows, model, column)}")
    for row in rows:
        if row["model"] == "physics":
            print(row)
    print(f"\nwrote {args.out}; {time.time() - t0:.0f} s wall, "
          f"{time.process_time() - c0:.0f} CPU-s in this process")


if __name__ == "__main__":
    main()
