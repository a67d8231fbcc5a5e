"""Learning curves of the issue-11 RL budget experiments (JSONs from rl_run.py) → PNG + CSV.

Usage: python plot_curves.py OUT_DIR [RUNS_DIR (default OUT_DIR/runs)]
"""
import json, glob, sys, csv
from pathlib import Path
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

out = Path(sys.argv[1]); out.mkdir(parents=True, exist_ok=True)
runs_dir = Path(sys.argv[2]) if len(sys.argv) > 2 else out / "runs"
runs = []
for f in sorted(glob.glob(str(runs_dir / "*.json"))):
    d = json.loads(Path(f).read_text())
    a = d["args"]
    if a.get("tag") == "probe":
        continue
    label = (f"{a.get('tag') or a['encoder']} (robot state: {a['robot_view']}, "
             f"{a['steps'] // 1000}k steps)")
    runs.append((label, a["seed"], a["steps"], d))
with open(out / "runs.csv", "w", newline="") as fh:
    w = csv.writer(fh)
    w.writerow(["run", "seed", "train_steps", "eval_return", "eval_success", "eval_episodes",
                "curve_steps", "curve_success", "curve_return", "wall_s_under_load"])
    for label, seed, steps, d in runs:
        w.writerow([label, seed, steps, round(d["eval_return"], 1), d["eval_success_rate"],
                    len(d["eval_episode_returns"]), d["curve_steps"],
                    [round(x, 3) for x in d["curve_success"]],
                    [round(x, 1) for x in d["curve_return"]], round(d["wall_s"])])
labels = sorted({r[0] for r in runs})
cmap = plt.get_cmap("tab10")
fig, axes = plt.subplots(1, 2, figsize=(11, 4))
for i, lab in enumerate(labels):
    for label, seed, steps, d in runs:
        if label != lab:
            continue
        kw = dict(color=cmap(i % 10), marker=".", alpha=0.8,
                  label=lab if seed == min(r[1] for r in runs if r[0] == lab) else None)
        axes[0].plot(d["curve_steps"], d["curve_success"], **kw)
        axes[1].plot(d["curve_steps"], d["curve_return"], **kw)
axes[0].set_ylabel("success rate (curve episodes)")
axes[1].set_ylabel("return (curve episodes)")
for ax in axes:
    ax.set_xlabel("environment steps"); ax.axvline(10000, color="grey", ls=":", lw=0.8)
axes[1].legend(fontsize=7, loc="upper left")
fig.suptitle("SAC on PegInHole-v0: one line per seed; dotted: the quick budget (10k steps)", fontsize=10)
fig.tight_layout()
fig.savefig(out / "rl_learning_curves.png", dpi=110)
print("wrote", out)
