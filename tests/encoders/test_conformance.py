"""The conformance kit over every registered encoder, and its own failure modes."""

from __future__ import annotations

import numpy as np
import pytest

import repbench
from repbench.errors import DataError
from repbench.testing import check_encoder

PAPER_ENCODERS = [
    "vae", "vae_lowkl", "success", "success_lowkl", "pred_z", "pred_z_lowkl",
    "pred_im", "pred_im_lowkl", "smooth", "smooth_lowkl",
]
BASELINES = ["oracle", "random", "pca", "proprio_only"]
ABLATIONS = ["vae_lowkl_d4", "vae_lowkl_d64", "vae_lowkl_image", "vae_lowkl_ft_proprio",
             "time_contrastive", "curl", "supervised", "supervised_task"]
#: encoders whose objective needs a registered task's task_state (not the synthetic data's)
NEEDS_TASK = {"supervised_task"}


def test_all_encoders_registered() -> None:
    names = set(repbench.encoders.names())
    assert set(PAPER_ENCODERS + BASELINES + ABLATIONS) <= names


@pytest.mark.parametrize("name", repbench.encoders.names())
def test_registered_encoder_conforms(name: str, request: pytest.FixtureRequest) -> None:
    data = request.getfixturevalue("peg_like_dataset" if name in NEEDS_TASK else "tiny_dataset")
    enc = check_encoder(name, data)
    assert enc.is_fitted


@pytest.mark.parametrize("name", sorted(set(repbench.encoders.names()) - NEEDS_TASK))
def test_registered_encoder_conforms_with_early_stopping(name: str,
                                                          tiny_dataset: repbench.Dataset) -> None:
    """The suites' training settings (held-out episodes, patience) work for every encoder."""
    from repbench.pipeline.plan import accepted_kwargs

    cls = repbench.encoders.get(name)
    params = accepted_kwargs(cls, {"epochs": 2, "patience": 1, "validation_fraction": 0.34})
    check_encoder(name, tiny_dataset, **params)


def test_check_encoder_accepts_instance_and_class(tiny_dataset: repbench.Dataset) -> None:
    from repbench_encoders.baselines import PCAEncoder

    assert check_encoder(PCAEncoder(latent_dim=3), tiny_dataset).latent_dim == 3
    assert check_encoder(PCAEncoder, tiny_dataset, latent_dim=5).latent_dim == 5


class _Sampling(repbench.Encoder):
    """Breaks the contract: returns a random sample, not μ."""

    required_modalities = ("proprio",)

    def __init__(self, seed: int = 0) -> None:
        self.seed = seed

    def fit(self, dataset):
        self.rng_ = np.random.default_rng(self.seed)
        return self

    def encode(self, observations):
        self.check_is_fitted()
        p = self.check_observations(observations)["proprio"]
        return (p + self.rng_.normal(size=p.shape)).astype(np.float32)

    @property
    def latent_dim(self) -> int:
        return 4


class _Float64(_Sampling):
    def encode(self, observations):
        self.check_is_fitted()
        return self.check_observations(observations)["proprio"].astype(np.float64)


class _NoModalityCheck(_Sampling):
    def encode(self, observations):
        self.check_is_fitted()
        return np.asarray(observations.get("proprio", np.zeros((1, 4))), np.float32)


class _BatchDependent(_Sampling):
    def encode(self, observations):
        self.check_is_fitted()
        p = self.check_observations(observations)["proprio"]
        return (p - p.mean(0)).astype(np.float32)


@pytest.mark.parametrize(("cls", "message"), [
    (_Sampling, "not deterministic"),
    (_Float64, "float32"),
    (_NoModalityCheck, "lacking 'proprio'"),
    (_BatchDependent, "batch size"),
])
def test_check_encoder_catches_broken_encoders(cls, message, tiny_dataset) -> None:
    with pytest.raises(AssertionError, match=message):
        check_encoder(cls, tiny_dataset)


def test_missing_modality_error_is_clear(tiny_dataset: repbench.Dataset) -> None:
    enc = repbench.encoders.get("vae_lowkl")(epochs=1, progress=False).fit(tiny_dataset)
    obs = tiny_dataset.obs()
    del obs["ft"]
    with pytest.raises(DataError, match=r"VAELowKL needs .* lacks \['ft'\]"):
        enc.encode(obs)
