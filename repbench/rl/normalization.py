"""Fixed standardization of the agent's features, carried inside the SB3 policy.

The agent observes ``μ_z ⊕ robot state``: latents of arbitrary scale next to joint angles
(radians), tip positions (metres, where millimetres matter) and velocities. Before training,
:func:`feature_statistics` measures each feature's mean and standard deviation over a short
rollout of uniformly random actions (what SB3's warm-up does anyway);
:class:`StandardizedFeatures` — the policy's features extractor — subtracts and divides by
them. The statistics are fixed for the run and live in the policy's state dict, so a saved
model predicts from raw features with no extra file. Every encoder gets the same treatment, so
the comparison between encoders stays fair; a latent's own scale no longer decides how fast
the agent can learn from it.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

#: Standard deviations below this are treated as constant features (divided by 1).
MIN_STD = 1e-6
#: Standardized features are clipped to ±this many standard deviations.
CLIP = 10.0


def feature_statistics(env: gym.Env, steps: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation (float32 ``[F]``) of ``env``'s flat observations over
    ``steps`` steps of uniformly random actions (episodes reset with seeds ``seed``,
    ``seed + 1``, ...). Constant features get standard deviation 1."""
    if not isinstance(steps, int) or steps < 2:
        raise ValueError(f"feature_statistics needs steps >= 2, got {steps!r}")
    rng = np.random.default_rng(seed)
    low, high = env.action_space.low, env.action_space.high
    episode = 0
    obs, _ = env.reset(seed=seed)
    rows = [np.asarray(obs, np.float64)]
    while len(rows) < steps:
        obs, _, terminated, truncated, _ = env.step(rng.uniform(low, high).astype(np.float32))
        rows.append(np.asarray(obs, np.float64))
        if terminated or truncated:
            episode += 1
            obs, _ = env.reset(seed=seed + episode)
            rows.append(np.asarray(obs, np.float64))
    data = np.stack(rows[:steps])
    std = data.std(axis=0)
    std[std < MIN_STD] = 1.0
    return data.mean(axis=0).astype(np.float32), std.astype(np.float32)


class StandardizedFeatures(BaseFeaturesExtractor):
    """SB3 features extractor ``x ↦ clip((x − mean) / std, ±10)`` with fixed statistics.

    Args:
        observation_space: the flat Box of ``μ_z ⊕ robot state``.
        mean, std: per-feature statistics (lists or arrays of the observation's size).
    """

    def __init__(self, observation_space: gym.spaces.Box, mean: Any, std: Any) -> None:
        size = int(np.prod(observation_space.shape))
        super().__init__(observation_space, features_dim=size)
        mean_t = torch.as_tensor(np.asarray(mean, np.float32).reshape(-1))
        std_t = torch.as_tensor(np.asarray(std, np.float32).reshape(-1))
        if mean_t.numel() != size or std_t.numel() != size:
            raise ValueError(f"StandardizedFeatures: statistics of size {mean_t.numel()}/"
                             f"{std_t.numel()} for observations of size {size}")
        if not bool((std_t > 0).all()):
            raise ValueError("StandardizedFeatures: standard deviations must be > 0")
        self.register_buffer("mean", mean_t)
        self.register_buffer("std", std_t)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        x = observations.flatten(1).float()
        return ((x - self.mean) / self.std).clamp(-CLIP, CLIP)
