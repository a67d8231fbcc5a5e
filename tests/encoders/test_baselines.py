"""Baselines against known answers and references."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import repbench
from repbench.dataset import Dataset
from repbench.errors import ConfigError, DataError


def test_oracle_returns_the_true_state(small_dataset: Dataset) -> None:
    enc = repbench.encoders.get("oracle")().fit(small_dataset)
    z = enc.encode(small_dataset.obs())
    assert enc.latent_dim == small_dataset.true_state.shape[1]
    assert z.dtype == np.float32 and np.array_equal(z, small_dataset.true_state)
    with pytest.raises(DataError, match="true_state"):
        enc.encode(small_dataset.obs(with_true_state=False))


def test_proprio_only_is_standardized_proprio(small_dataset: Dataset) -> None:
    enc = repbench.encoders.get("proprio_only")().fit(small_dataset)
    p = small_dataset.observations["proprio"].astype(np.float64)
    expected = (p - p.mean(0)) / p.std(0)
    np.testing.assert_allclose(enc.encode({"proprio": p}), expected, rtol=1e-5, atol=1e-5)
    assert enc.latent_dim == p.shape[1]


def test_pca_matches_sklearn_pipeline(small_dataset: Dataset) -> None:
    from sklearn.decomposition import PCA
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    enc = repbench.encoders.get("pca")(latent_dim=6, image_size=8).fit(small_dataset)
    obs = small_dataset.obs()
    img = obs["image"].astype(np.float64).reshape(len(small_dataset), 8, 8, 8, 8, 3).mean((2, 4))
    x = np.concatenate([img.reshape(len(img), -1), obs["ft"], obs["proprio"]], axis=1)
    ref = make_pipeline(StandardScaler(), PCA(n_components=6, random_state=0)).fit_transform(x)
    np.testing.assert_allclose(enc.encode(obs), ref, rtol=1e-4, atol=1e-4)
    ratios = enc.explained_variance_ratio_
    assert np.all(np.diff(ratios) <= 1e-12) and ratios.sum() <= 1.0


def test_pca_rejects_impossible_sizes(tiny_dataset: Dataset) -> None:
    with pytest.raises(ConfigError, match="latent_dim=30 exceeds"):
        repbench.encoders.get("pca")(latent_dim=30).fit(tiny_dataset)
    with pytest.raises(ConfigError, match="image_size=5 must divide"):
        repbench.encoders.get("pca")(image_size=5).fit(tiny_dataset)


def test_random_encoder_is_the_untrained_vae_encoder(tiny_dataset: Dataset) -> None:
    rand = repbench.encoders.get("random")(seed=4).fit(tiny_dataset)
    untrained = repbench.encoders.get("vae")(seed=4, epochs=0, progress=False).fit(tiny_dataset)
    for (k, a), b in zip(rand.net_.state_dict().items(), untrained.net_.state_dict().values(),
                         strict=True):
        assert torch.equal(a, b), k
    assert rand.history_ == []
    other = repbench.encoders.get("random")(seed=5).fit(tiny_dataset)
    assert not np.allclose(rand.encode(tiny_dataset.obs()), other.encode(tiny_dataset.obs()))
