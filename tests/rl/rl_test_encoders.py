"""Small encoders for the RL tests (stand-ins until the real ``oracle``/``vae`` exist)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch

import repbench
from repbench.encoder import TrueStateEncoder  # z = z°, the oracle

__all__ = ["BadEncoder", "ConvEncoder", "NoiseEncoder", "TrueStateEncoder"]


class NoiseEncoder(repbench.Encoder):
    """A representation independent of the state: a fixed vector, like an untrained encoder
    whose output does not vary with the scene (the worst case)."""

    required_modalities = ("image",)

    def __init__(self, latent_dim: int = 8, seed: int = 0) -> None:
        self.latent_dim_param = latent_dim
        self.seed = seed

    def get_params(self) -> dict[str, Any]:
        return {"latent_dim": self.latent_dim_param, "seed": self.seed}

    def fit(self, dataset: repbench.Dataset) -> NoiseEncoder:
        self.z_ = np.random.default_rng(self.seed).normal(size=self.latent_dim_param)
        return self

    def encode(self, observations: Mapping[str, Any]) -> np.ndarray:
        n = len(self.check_observations(observations)["image"])
        return np.tile(self.z_.astype(np.float32), (n, 1))

    @property
    def latent_dim(self) -> int:
        return self.latent_dim_param


class BadEncoder(TrueStateEncoder):
    """Returns the wrong number of columns, or NaN (``mode``)."""

    def __init__(self, mode: str = "shape") -> None:
        self.mode = mode

    def encode(self, observations: Mapping[str, Any]) -> np.ndarray:
        z = super().encode(observations)
        if self.mode == "shape":
            return z[:, :-1]
        return np.full_like(z, np.nan)


class ConvEncoder(repbench.Encoder):
    """A VAE-sized torch encoder with random weights (the paper's conv stack 32→128, k4 s2,
    force/proprio MLPs of 16, fusion 64 → μ_z): for speed measurements."""

    required_modalities = ("image", "ft", "proprio")

    def __init__(self, latent_dim: int = 16, seed: int = 0) -> None:
        self.latent_dim_param = latent_dim
        self.seed = seed

    def get_params(self) -> dict[str, Any]:
        return {"latent_dim": self.latent_dim_param, "seed": self.seed}

    def fit(self, dataset: repbench.Dataset) -> ConvEncoder:
        torch.manual_seed(self.seed)
        p = dataset.observations["proprio"].shape[1]
        nn = torch.nn
        self.conv_ = nn.Sequential(
            nn.Conv2d(3, 32, 4, 2), nn.ReLU(), nn.Conv2d(32, 64, 4, 2), nn.ReLU(),
            nn.Conv2d(64, 128, 4, 2), nn.ReLU(), nn.Conv2d(128, 128, 4, 1), nn.ReLU(),
            nn.Flatten())
        with torch.no_grad():
            n_conv = self.conv_(torch.zeros(1, 3, 64, 64)).shape[1]
        self.ft_ = nn.Sequential(nn.Linear(6, 16), nn.ReLU())
        self.proprio_ = nn.Sequential(nn.Linear(p, 16), nn.ReLU())
        self.fusion_ = nn.Sequential(nn.Linear(n_conv + 32, 64), nn.ReLU(),
                                     nn.Linear(64, 2 * self.latent_dim_param))
        return self

    def encode(self, observations: Mapping[str, Any]) -> np.ndarray:
        b = self.check_observations(observations)
        with torch.no_grad():
            img = torch.from_numpy(b["image"]).permute(0, 3, 1, 2).float() / 255.0
            h = torch.cat([self.conv_(img), self.ft_(torch.from_numpy(b["ft"]).float()),
                           self.proprio_(torch.from_numpy(b["proprio"]).float())], 1)
            mu = self.fusion_(h)[:, : self.latent_dim_param]
        return mu.numpy().astype(np.float32)

    @property
    def latent_dim(self) -> int:
        return self.latent_dim_param
