"""Speed of the paper-architecture VAE (run: pytest --benchmark-only -m "slow or not slow"
tests/encoders). Training samples/s, encode samples/s at batch 256, and µs per encode call at
batch 1 (the RL loop calls it every environment step) — compare the per-sample costs."""

from __future__ import annotations

import numpy as np
import pytest

import repbench
from repbench.testing.synthetic import synthetic_dataset


@pytest.fixture(scope="module")
def data256() -> repbench.Dataset:
    return synthetic_dataset(n_episodes=8, steps=32, seed=0)  # 256 rows, 64 × 64 images


@pytest.fixture(scope="module")
def fitted(data256: repbench.Dataset) -> repbench.Encoder:
    return repbench.encoders.get("vae_lowkl")(epochs=1, progress=False).fit(data256)


@pytest.mark.parametrize("name", ["vae_lowkl", "smooth_lowkl"])
def test_bench_training_samples_per_s(benchmark, name: str, data256) -> None:
    cls = repbench.encoders.get(name)

    def fit() -> None:
        cls(epochs=1, batch_size=64, progress=False).fit(data256)

    benchmark.pedantic(fit, rounds=2, iterations=1, warmup_rounds=0)
    samples = len(data256) if name == "vae_lowkl" else len(data256) - data256.n_episodes
    benchmark.extra_info["samples_per_s"] = samples / benchmark.stats.stats.mean


def test_bench_encode_batch256(benchmark, fitted, data256) -> None:
    obs = data256.obs(np.arange(256))
    z = benchmark(fitted.encode, obs)
    assert z.shape == (256, 16)
    benchmark.extra_info["samples_per_s"] = 256 / benchmark.stats.stats.mean
    benchmark.extra_info["us_per_sample"] = 1e6 * benchmark.stats.stats.mean / 256


def test_bench_encode_batch1(benchmark, fitted, data256) -> None:
    obs = data256.obs(np.arange(1))
    z = benchmark(fitted.encode, obs)
    assert z.shape == (1, 16)
    benchmark.extra_info["us_per_call"] = 1e6 * benchmark.stats.stats.mean


def test_bench_torch_forward_batch1(benchmark, fitted, data256) -> None:
    """The bare network forward at batch 1 (no conversion/validation): the floor for encode."""
    import torch

    obs = data256.obs(np.arange(1))
    x = fitted._obs_tensors(obs, ("image", "ft", "proprio"))

    def forward() -> None:
        with torch.inference_mode():
            fitted.net_.encode(x["image"], x["ft"], x["proprio"])

    benchmark(forward)
    benchmark.extra_info["us_per_call"] = 1e6 * benchmark.stats.stats.mean
