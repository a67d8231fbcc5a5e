"""R3M's time-contrastive loss and the inverse-dynamics encoder (the zoo), and the
modality-balanced VAE."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

import repbench
from repbench.dataset import Dataset
from repbench.errors import ConfigError, DataError
from repbench_encoders.control_objectives import (
    ControlObjectiveEncoder,
    r3m_time_contrastive,
    sample_triplets,
)
from repbench_encoders.vae import MultimodalVAE

FAST = {"batch_size": 16, "progress": False}


def _randn(*shape: int, seed: int) -> torch.Tensor:
    return torch.randn(*shape, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)


def test_r3m_loss_matches_its_formula() -> None:
    """−log e^{S(i,j)} / (e^{S(i,j)} + e^{S(i,k)} + Σ_o e^{S(i,o)}), S = −‖·‖², only other
    episodes' rows as the o."""
    a, p, n = _randn(5, 3, seed=0), _randn(5, 3, seed=1), _randn(5, 3, seed=2)
    episode = torch.tensor([0, 0, 1, 2, 2])
    mask = episode[:, None] != episode[None, :]
    expected = 0.0
    for b in range(5):
        s = lambda x, y: -float(((x - y) ** 2).sum())  # noqa: E731
        terms = [s(a[b], p[b]), s(a[b], n[b])] + [s(a[b], a[o]) for o in range(5) if mask[b, o]]
        expected += -(terms[0] - math.log(sum(math.exp(t) for t in terms)))
    assert float(r3m_time_contrastive(a, p, n, a, mask)) == pytest.approx(expected / 5, rel=1e-9)
    # the positive on the anchor, everything else far: the loss goes to 0
    far = a + 100.0
    assert float(r3m_time_contrastive(a, a.clone(), far, far, mask)) < 1e-9
    # one episode in the batch: only the positive and the hard negative compete
    one = torch.zeros(5, 5, dtype=torch.bool)
    equal = float(r3m_time_contrastive(a, n.clone(), n, a, one))
    assert equal == pytest.approx(math.log(2), rel=1e-9)


def test_r3m_triplets_stay_in_order_inside_one_episode(small_dataset: Dataset) -> None:
    enc = ControlObjectiveEncoder(objective="r3m", positive_window=2, negative_window=6, **FAST)
    rows, later = enc._pairs(small_dataset)
    assert np.all(small_dataset.episode[rows] == small_dataset.episode[later])
    assert np.all(small_dataset.step[later] - small_dataset.step[rows] == 3)
    assert rows.size == len(small_dataset) - 3 * small_dataset.n_episodes
    enc._device = torch.device("cpu")
    left = enc._extra_tensors(small_dataset)["steps_left"].numpy()
    assert left[0] == 29 and left[29] == 0 and left[30] == 29  # episodes of 30 steps
    # the sampled positives and hard negatives: same episode, 1-2 and 3-6 steps later (fewer
    # at an episode's end), and every allowed gap is drawn
    idx = torch.as_tensor(rows)
    gen = torch.Generator().manual_seed(0)
    seen: set[int] = set()
    for _ in range(20):
        pos, neg = sample_triplets(idx, torch.as_tensor(left)[idx], 2, 6, gen)
        for other, low, high in ((pos, 1, 2), (neg, 3, 6)):
            assert np.all(small_dataset.episode[other.numpy()] == small_dataset.episode[rows])
            gap = small_dataset.step[other.numpy()] - small_dataset.step[rows]
            assert gap.min() >= low and gap.max() <= high
        seen |= set((small_dataset.step[neg.numpy()] - small_dataset.step[rows]).tolist())
    assert seen == {3, 4, 5, 6}


@pytest.mark.parametrize("name", ["r3m", "inverse_dynamics"])
def test_training_lowers_the_objective(name: str, small_dataset: Dataset) -> None:
    """Measured (one torch thread, 6 epochs): r3m 1.77 -> 0.85, inverse_dynamics 1.96 -> 0.90
    (the synthetic actions are partly predictable from consecutive observations)."""
    enc = repbench.encoders.get(name)(epochs=6, **FAST).fit(small_dataset)
    curve = [h["train"]["objective"] for h in enc.history_]
    assert curve[-1] < 0.7 * curve[0], curve


def test_bad_parameters_are_one_line_errors(tiny_dataset: Dataset) -> None:
    with pytest.raises(ConfigError, match="objective must be one of"):
        ControlObjectiveEncoder(objective="cpc", **FAST).fit(tiny_dataset)
    with pytest.raises(ConfigError, match=r"negative_window .* must be larger"):
        ControlObjectiveEncoder(positive_window=4, negative_window=4, **FAST).fit(tiny_dataset)
    with pytest.raises(DataError, match="needs episodes longer than 9 steps; lower "
                                        "positive_window"):
        ControlObjectiveEncoder(positive_window=8, negative_window=9,
                                **FAST).fit(tiny_dataset)  # episodes of 8 steps


def test_the_balanced_vae_weighs_force_like_the_image(tiny_dataset: Dataset) -> None:
    """At one standard deviation of error per element, the force term (6 axes × scale²) equals
    the image term (pixels × (255 σ_image)²)."""
    enc = repbench.encoders.get("vae_lowkl_balanced")(epochs=1, **FAST).fit(tiny_dataset)
    spec, stats = enc.spec_, enc.stats_
    pixels = spec["image_size"] ** 2 * 3
    image_term = pixels * (255.0 * float(np.mean(stats["image_std"]))) ** 2
    assert spec["ft_dim"] * enc.ft_scale_ ** 2 == pytest.approx(image_term, rel=1e-12)
    assert enc._ft_scale() == enc.ft_scale_ != 255.0
    assert MultimodalVAE(ft_recon_scale=12.5)._ft_scale() == 12.5
    with pytest.raises(ConfigError, match=r'ft_recon_scale must be a finite number >= 0 or '
                                          r'"balanced", got \'equal\''):
        MultimodalVAE(ft_recon_scale="equal", **FAST).fit(tiny_dataset)
