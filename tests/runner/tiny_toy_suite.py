"""A tiny ToyReach-v0 suite (no on-policy data, 60 RL steps) shared by the runner tests."""

from __future__ import annotations

import json


def tiny_toy_suite(name: str, encoders: list[str]) -> str:
    """Suite TOML text: ``encoders`` on ToyReach-v0 with ksg and regression, SAC, one seed."""
    return f"""
name = "{name}"
tasks = ["ToyReach-v0"]
encoders = {json.dumps(encoders)}
metrics = ["ksg", "regression"]
agents = ["sac"]
seeds = [0]
[dataset]
random_episodes = 3
random_steps = 20
on_policy_episodes = 0
[encoder_training]
latent_dim = 3
epochs = 1
[rl]
train_steps = 60
eval_episodes = 1
curve_points = 1
[metric_settings]
bootstrap = 20
[task_params."ToyReach-v0"]
horizon = 20
[agent_params.sac]
learning_starts = 20
batch_size = 16
normalize_steps = 0
"""
