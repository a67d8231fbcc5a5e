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

The SBX (JAX) backend has no torch features extractor: there the same transform,
:func:`standardize`, runs on the observations instead (:class:`StandardizedObservation` for one
environment, :class:`StandardizedVecEnv` for the training VecEnv), and the statistics are saved
beside the model (:func:`repbench.rl.save_policy`).
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


def standardize(x: Any, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """``clip((x − mean) / std, ±CLIP)`` as float32: what :class:`StandardizedFeatures` computes,
    on numpy arrays."""
    out = (np.asarray(x, np.float32) - mean) / std
    return np.clip(out, -CLIP, CLIP).astype(np.float32)


def check_statistics(mean: Any, std: Any, size: int) -> tuple[np.ndarray, np.ndarray]:
    """``(mean, std)`` as float32 ``[size]`` arrays; ValueError for a wrong size or std <= 0."""
    mean_a = np.asarray(mean, np.float32).reshape(-1)
    std_a = np.asarray(std, np.float32).reshape(-1)
    if mean_a.size != size or std_a.size != size:
        raise ValueError(f"feature statistics of size {mean_a.size}/{std_a.size} for "
                         f"observations of size {size}")
    if not bool((std_a > 0).all()):
        raise ValueError("feature statistics: standard deviations must be > 0")
    return mean_a, std_a


class StandardizedObservation(gym.ObservationWrapper):
    """A flat-Box environment whose observations are :func:`standardize`-d with fixed
    statistics (the SBX backend's evaluation environment)."""

    def __init__(self, env: gym.Env, mean: Any, std: Any) -> None:
        super().__init__(env)
        size = int(np.prod(env.observation_space.shape))
        self.mean, self.std = check_statistics(mean, std, size)
        self.observation_space = gym.spaces.Box(-CLIP, CLIP, (size,), np.float32)

    def observation(self, observation: Any) -> np.ndarray:
        return standardize(observation, self.mean, self.std)


def standardized_vec_env(venv: Any, mean: Any, std: Any) -> Any:
    """An SB3 VecEnv whose observations (terminal observations included) are
    :func:`standardize`-d with fixed statistics (the SBX backend's training environment)."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    size = int(np.prod(venv.observation_space.shape))
    mean_a, std_a = check_statistics(mean, std, size)

    class StandardizedVecEnv(VecEnvWrapper):
        """Fixed standardization of every observation of a VecEnv."""

        def __init__(self) -> None:
            super().__init__(venv, observation_space=gym.spaces.Box(-CLIP, CLIP, (size,),
                                                                    np.float32))

        def reset(self) -> np.ndarray:
            return standardize(self.venv.reset(), mean_a, std_a)

        def step_wait(self) -> Any:
            obs, rewards, dones, infos = self.venv.step_wait()
            for info in infos:
                if "terminal_observation" in info:
                    info["terminal_observation"] = standardize(info["terminal_observation"],
                                                               mean_a, std_a)
            return standardize(obs, mean_a, std_a), rewards, dones, infos

    return StandardizedVecEnv()


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
