"""The VAE family: paper defaults, losses against references, training sanity, errors."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import repbench
from repbench.dataset import Dataset
from repbench.errors import ConfigError, DataError, TrainingDivergedError
from repbench_encoders.vae import MultimodalVAE, VAELowKL, gaussian_kl

FAST = {"epochs": 1, "batch_size": 8, "progress": False}

# the paper's appendix: (kl, success, pred_z, pred_im, smooth) weights; recon 1e-4 everywhere
PAPER_WEIGHTS = {
    "vae": (10.0, 0, 0, 0, 0), "vae_lowkl": (0.1, 0, 0, 0, 0),
    "success": (10.0, 0.1, 0, 0, 0), "success_lowkl": (0.1, 0.1, 0, 0, 0),
    "pred_z": (10.0, 0, 1.0, 0, 0), "pred_z_lowkl": (0.1, 0, 1.0, 0, 0),
    "pred_im": (10.0, 0, 0, 1e-4, 0), "pred_im_lowkl": (0.1, 0, 0, 1e-4, 0),
    "smooth": (10.0, 0, 0, 0, 500.0), "smooth_lowkl": (0.1, 0, 0, 0, 0.1),
}


@pytest.mark.parametrize("name", sorted(PAPER_WEIGHTS))
def test_variants_have_paper_weights(name: str) -> None:
    enc = repbench.encoders.get(name)()
    got = (enc.kl_weight, enc.success_weight, enc.pred_z_weight, enc.pred_im_weight,
           enc.smooth_weight)
    assert got == PAPER_WEIGHTS[name]
    assert enc.recon_weight == 1e-4 and enc.latent_dim == 16
    assert type(enc)(**enc.get_params()).get_params() == enc.get_params()


def test_gaussian_kl_matches_torch_distributions() -> None:
    g = torch.Generator().manual_seed(0)
    mq, lq, mp, lp = (torch.randn(5, 3, generator=g) for _ in range(4))
    ref = torch.distributions.kl_divergence(
        torch.distributions.Normal(mq, lq.exp()), torch.distributions.Normal(mp, lp.exp())
    ).sum(-1)
    torch.testing.assert_close(gaussian_kl(mq, lq, mp, lp), ref)
    assert torch.all(gaussian_kl(mq, lq, mq, lq).abs() < 1e-6)


def test_smooth_term_uses_pairs_within_episodes(tiny_dataset: Dataset) -> None:
    enc = repbench.encoders.get("smooth")(**FAST).fit(tiny_dataset)
    z = enc.encode(tiny_dataset.obs())
    i, j = tiny_dataset.successor_index()
    assert np.all(tiny_dataset.episode[i] == tiny_dataset.episode[j])
    assert i.size == len(tiny_dataset) - tiny_dataset.n_episodes
    expected = np.linalg.norm(z[j] - z[i], axis=1).mean()
    assert enc.loss_terms(tiny_dataset)["smooth"] == pytest.approx(expected, rel=1e-4)


def test_training_lowers_reconstruction_loss(tiny_dataset: Dataset) -> None:
    params = {"batch_size": 8, "progress": False, "seed": 3}
    init = VAELowKL(epochs=0, **params).fit(tiny_dataset).loss_terms(tiny_dataset)
    trained = VAELowKL(epochs=10, **params).fit(tiny_dataset)
    after = trained.loss_terms(tiny_dataset)
    assert after["recon"] < 0.6 * init["recon"], (init, after)  # measured: 0.35
    assert len(trained.history_) == 10


def test_training_is_seeded_and_deterministic(tiny_dataset: Dataset) -> None:
    def z(seed: int) -> np.ndarray:
        enc = repbench.encoders.get("pred_z_lowkl")(seed=seed, **FAST).fit(tiny_dataset)
        return enc.encode(tiny_dataset.obs())

    a, b, c = z(0), z(0), z(1)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)


def test_every_loss_term_is_trained(tiny_dataset: Dataset) -> None:
    small_dataset = tiny_dataset
    enc = MultimodalVAE(kl_weight=0.1, success_weight=0.1, pred_z_weight=1.0,
                        pred_im_weight=1e-4, smooth_weight=0.1, **FAST).fit(small_dataset)
    terms = enc.history_[-1]["train"]
    for key in ("recon", "kl", "success", "pred_z", "pred_im", "smooth"):
        assert np.isfinite(terms[key]) and terms[key] > 0, (key, terms)
    rec = enc.reconstruct(small_dataset.obs(np.arange(5)))
    assert rec["image"].shape == (5, 64, 64, 3) and rec["image"].dtype == np.uint8
    assert rec["ft"].shape == (5, 6) and rec["ft"].dtype == np.float32
    nxt = enc.predict_next_image(small_dataset.obs(np.arange(5)), small_dataset.action[:5])
    assert nxt.shape == (5, 64, 64, 3)


def test_huge_learning_rate_diverges_with_clear_message(tiny_dataset: Dataset) -> None:
    enc = VAELowKL(epochs=3, batch_size=4, learning_rate=1e10, progress=False)
    with pytest.raises(TrainingDivergedError, match=r"VAELowKL training diverged at epoch \d/3"):
        enc.fit(tiny_dataset)


def test_nan_in_data_diverges_with_clear_message(tiny_dataset: Dataset) -> None:
    bad = tiny_dataset.subset(np.arange(len(tiny_dataset)))
    bad.observations["ft"] = bad.observations["ft"].copy()
    bad.observations["ft"][3, 2] = np.nan  # bypasses Dataset.validate, as a corrupt file might
    with pytest.raises(TrainingDivergedError, match=r"SmoothVAE training diverged at epoch 1/1"):
        repbench.encoders.get("smooth")(**FAST).fit(bad)


@pytest.mark.parametrize(("params", "match"), [
    ({"latent_dim": 0}, "latent_dim must be a positive integer"),
    ({"epochs": -1}, "epochs must be an integer >= 0"),
    ({"learning_rate": 0.0}, "learning_rate must be a finite number > 0, got 0.0"),
    ({"learning_rate": True}, "learning_rate must be a finite number > 0, got True"),
    ({"learning_rate": float("inf")}, "learning_rate must be a finite number > 0, got inf"),
    ({"kl_weight": -1.0}, "kl_weight must be a finite number >= 0"),
    ({"device": "tpu9"}, "device 'tpu9' is not a torch device"),
])
def test_bad_parameters_are_rejected(params, match, tiny_dataset: Dataset) -> None:
    with pytest.raises(ConfigError, match=match):
        VAELowKL(**{**FAST, **params}).fit(tiny_dataset)


def test_bad_inputs_are_rejected(tiny_dataset: Dataset) -> None:
    from repbench.testing.synthetic import synthetic_dataset

    with pytest.raises(DataError, match="image size 36 is not supported"):
        VAELowKL(**FAST).fit(synthetic_dataset(2, 5, image_size=36))
    enc = VAELowKL(**FAST).fit(tiny_dataset)
    obs = tiny_dataset.obs()
    with pytest.raises(DataError, match=r"modality 'proprio' must have shape \[N, 4\]"):
        enc.encode({**obs, "proprio": obs["proprio"][:, :3]})
    with pytest.raises(DataError, match="images must be uint8"):
        enc.encode({**obs, "image": obs["image"].astype(np.float32)})
    with pytest.raises(ConfigError, match="no next-image predictor"):
        enc.predict_next_image(obs, tiny_dataset.action)
    with pytest.raises(DataError, match="needs the dataset modality 'last_action'"):
        no_action = tiny_dataset.subset(np.arange(len(tiny_dataset)))
        del no_action.observations["last_action"]
        VAELowKL(**FAST).fit(no_action)


def test_latent_dim_is_configurable(tiny_dataset: Dataset) -> None:
    enc = repbench.encoders.get("vae")(latent_dim=5, **FAST).fit(tiny_dataset)
    assert enc.encode(tiny_dataset.obs()).shape == (len(tiny_dataset), 5)


def test_auto_device_is_cuda_when_present(tiny_dataset: Dataset) -> None:
    enc = VAELowKL(**FAST).fit(tiny_dataset)
    expected = "cuda" if torch.cuda.is_available() else "cpu"
    assert next(enc.net_.parameters()).device.type == expected


@pytest.mark.slow
def test_lowkl_latents_locate_the_hole_better_than_random() -> None:
    """Held-out episodes: ridge regression from z to the hole's position relative to the end
    effector (what the wrist image shows) works better for a trained low-KL VAE."""
    from sklearn.linear_model import RidgeCV
    from sklearn.metrics import r2_score

    from repbench.testing.synthetic import synthetic_dataset

    data = synthetic_dataset(n_episodes=24, steps=15, seed=0)
    train, test = data.episode_split(0.25, seed=0)
    d_train, d_test = data.subset(train), data.subset(test)

    def r2(enc: repbench.Encoder) -> float:
        def target(d: Dataset) -> np.ndarray:
            return d.true_state[:, 4:6] - d.true_state[:, 0:2]

        reg = RidgeCV(alphas=np.logspace(-3, 3, 13))
        reg.fit(enc.encode(d_train.obs()), target(d_train))
        return float(r2_score(target(d_test), reg.predict(enc.encode(d_test.obs()))))

    random_r2 = r2(repbench.encoders.get("random")().fit(d_train))
    vae_r2 = r2(VAELowKL(epochs=20, batch_size=16, progress=False).fit(d_train))
    assert vae_r2 > random_r2 + 0.1, (vae_r2, random_r2)
