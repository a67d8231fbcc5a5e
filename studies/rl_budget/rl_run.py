"""One SAC run for the RL budget/observation experiments of issue 11 (writes a JSON).

Example: python rl_run.py --encoder vae_lowkl --encoder-file vae_lowkl.pt --steps 10000 --seed 1
"""
import argparse, json, time, sys
from pathlib import Path
import numpy as np

p = argparse.ArgumentParser()
p.add_argument("--encoder", default="oracle_task")
p.add_argument("--encoder-file", default=None)
p.add_argument("--fit-data", default=None)
p.add_argument("--robot-view", default="tip")
p.add_argument("--seed", type=int, default=0)
p.add_argument("--steps", type=int, default=15000)
p.add_argument("--lr", type=float, default=3e-4)
p.add_argument("--hidden", default="256,256")
p.add_argument("--curve-points", type=int, default=15)
p.add_argument("--curve-episodes", type=int, default=25)
p.add_argument("--eval-episodes", type=int, default=40)
p.add_argument("--keep-best", action="store_true")
p.add_argument("--tag", default="")
p.add_argument("--out", default="runs", help="folder for the JSON result")
a = p.parse_args()

import torch
torch.set_num_threads(1)
import repbench
from repbench.rl import SACAgent
from repbench_tasks.peg_in_hole import PegInHoleTask

task = PegInHoleTask(robot_view=a.robot_view)
if a.encoder_file:
    enc = repbench.Encoder.load(a.encoder_file)
else:
    if a.fit_data:
        small = repbench.Dataset.load(a.fit_data)
    else:
        small = PegInHoleTask(robot_view=a.robot_view).collect("random", n_episodes=1, steps_per_episode=3, seed=0, progress=False)
    enc = repbench.encoders.get(a.encoder)().fit(small)
agent = SACAgent(learning_rate=a.lr, hidden_sizes=[int(h) for h in a.hidden.split(",")],
                 curve_episodes=a.curve_episodes, keep_best=a.keep_best, progress=False)
t0 = time.time()
res = agent.train(task, enc, train_steps=a.steps, seed=a.seed, eval_episodes=a.eval_episodes,
                  curve_points=a.curve_points, progress=False)
out = {"args": vars(a), "wall_s": time.time() - t0, **res.to_dict()}
name = f"{a.tag or a.encoder}_{a.robot_view}_lr{a.lr}_h{a.hidden.replace(',', 'x')}_s{a.seed}_n{a.steps}"
Path(a.out).mkdir(parents=True, exist_ok=True)
Path(a.out, f"{name}.json").write_text(json.dumps(out, default=str))
print(name, "return", res.eval_return, "success", res.eval_success_rate, "curve", res.curve_success, f"{time.time()-t0:.0f}s", flush=True)
