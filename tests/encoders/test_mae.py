"""The masked autoencoder: conformance, its masking and patch helpers, that training learns the
masked patches through the latent, bad parameters, bit-identical refits."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from repbench.dataset import FT, PROPRIO, Dataset
from repbench.errors import ConfigError
from repbench.testing import check_encoder
from repbench_encoders.mae import MaskedAutoencoder, patchify, random_masking, unpatchify
from repbench_encoders.trunk import make_variant

FAST = {"batch_size": 8, "progress": False}


def test_conforms(tiny_dataset: Dataset) -> None:
    enc = check_encoder(MaskedAutoencoder, tiny_dataset, epochs=1, batch_size=8, progress=False)
    assert enc.family == "mae" and enc.latent_dim == 16
    assert set(enc.history_[0]["train"]) == {"loss", "recon", "ft_recon"}
    # deterministic encoder: log σ is exactly 0, μ is what encode returns
    with torch.inference_mode():
        mu, log_std = enc._encode_obs(tiny_dataset.obs())
    assert torch.equal(log_std, torch.zeros_like(mu))
    assert np.array_equal(mu.cpu().numpy(), enc.encode(tiny_dataset.obs()))


def test_training_learns_the_masked_patches(small_dataset: Dataset) -> None:
    """The masked patches are reconstructed from z, not just from their positions.

    With these 16-px patches, predicting 0 for every per-patch normalized target scores 0.999,
    the best position-only predictor (each position's mean target) 0.90 on this data, and a decoder
    fed z · 0 reaches 0.95 in the same run; so a loss under 0.8 means image content passes
    through the latent. 16-px patches (16 per image, 4 visible), batch 8 and lr 3e-3 leave the
    plateau at ≈ 1 within seconds. Measured (one torch thread), epoch 1 → 18: 1.084 → 0.540
    (seed 0; seeds 1, 2: 0.561, 0.661). With 8-px patches and the default lr the plateau lasts
    far more steps than a unit test affords (on 7500 rows it ends in epoch 8-9).
    """
    enc = MaskedAutoencoder(epochs=18, patch_size=16, learning_rate=3e-3, **FAST)
    curve = [h["train"]["recon"] for h in enc.fit(small_dataset).history_]
    assert curve[-1] < 0.8, curve
    assert curve[-1] < curve[0] - 0.3, curve


def test_random_masking() -> None:
    n, patches = 32, 64
    for ratio, keep in ((0.75, 16), (0.5, 32), (0.0, 64), (0.9, 6)):
        keep_idx, mask = random_masking(n, patches, ratio, torch.Generator().manual_seed(0))
        assert keep == round((1 - ratio) * patches)
        assert keep_idx.shape == (n, keep) and mask.shape == (n, patches)
        assert mask.dtype == torch.bool
        assert torch.equal((~mask).sum(1), torch.full((n,), keep))
        # keep_idx lists exactly the unmasked patches, in increasing order
        assert torch.all(keep_idx[:, 1:] > keep_idx[:, :-1])
        assert torch.equal(~mask, torch.zeros_like(mask).scatter(1, keep_idx, True))
    keep_idx, mask = random_masking(n, patches, 0.75, torch.Generator().manual_seed(0))
    assert len({tuple(r) for r in mask.tolist()}) == n  # every row its own mask
    again = random_masking(n, patches, 0.75, torch.Generator().manual_seed(0))
    other = random_masking(n, patches, 0.75, torch.Generator().manual_seed(1))
    assert torch.equal(again[0], keep_idx) and torch.equal(again[1], mask)
    assert not torch.equal(other[1], mask)
    # a ratio that would hide everything still leaves one patch visible
    assert random_masking(2, 4, 0.99, torch.Generator().manual_seed(0))[0].shape == (2, 1)


@pytest.mark.parametrize("p", [1, 4, 8, 16])
def test_patchify_round_trip(p: int) -> None:
    img = torch.randn(3, 3, 32, 32, generator=torch.Generator().manual_seed(p))
    patches = patchify(img, p)
    assert patches.shape == (3, (32 // p) ** 2, p * p * 3)
    assert torch.equal(unpatchify(patches, p, 32), img)
    # patch k is the k-th window in row-major order, flattened as (row, column, channel)
    g = 32 // p
    k = g + 1 if g > 1 else 0
    r, c = divmod(k, g)
    window = img[1, :, r * p:(r + 1) * p, c * p:(c + 1) * p].permute(1, 2, 0).reshape(-1)
    assert torch.equal(patches[1, k], window)
    # channels_last input (what the encoder's images are) gives the same patches
    assert torch.equal(patchify(img.contiguous(memory_format=torch.channels_last), p), patches)


def test_patch_order_matches_the_patch_embedding() -> None:
    """The reconstruction targets (patchify) and the encoder's tokens (the strided conv) list
    patches in the same order, so a position embedding means the same patch in both."""
    p = 8
    conv = torch.nn.Conv2d(3, 5, p, stride=p, bias=False)
    img = torch.randn(2, 3, 32, 32, generator=torch.Generator().manual_seed(0))
    tokens = conv(img).flatten(2).transpose(1, 2)  # what the encoder does
    weight = conv.weight.permute(0, 2, 3, 1).reshape(5, -1)  # (out, row, column, channel)
    torch.testing.assert_close(patchify(img, p) @ weight.T, tokens)


def test_bad_parameters(tiny_dataset: Dataset) -> None:
    cases = [
        ({"mask_ratio": 1.0}, r"mask_ratio must be in \[0, 1\)"),
        ({"mask_ratio": -0.1}, r"mask_ratio must be in \[0, 1\)"),
        ({"patch_size": 7}, "patch_size=7 does not divide the image side 64"),
        ({"embed_dim": 60, "num_heads": 8}, "embed_dim=60 must be divisible by num_heads=8"),
        ({"decoder_dim": 30}, "decoder_dim=30 must be divisible by num_heads=4"),
        ({"depth": 0}, "depth must be a positive integer"),
        ({"ft_weight": -1.0}, "ft_weight must be a finite number >= 0"),
    ]
    for params, message in cases:
        enc = MaskedAutoencoder(**params, **FAST)
        with pytest.raises(ConfigError, match=message) as info:
            enc.fit(tiny_dataset)
        assert "\n" not in str(info.value)
        assert not enc.is_fitted, params  # rejected before anything was learned
    blind = make_variant(MaskedAutoencoder, "BlindMAE", "An image-free MAE (invalid).",
                         module=__name__, required_modalities=(FT, PROPRIO))
    with pytest.raises(ConfigError, match="required_modalities must include 'image'") as info:
        blind(**FAST).check_params()  # the planner's check, before any data
    assert "\n" not in str(info.value)
    with pytest.raises(ConfigError, match="must include 'image'"):
        blind(**FAST).fit(tiny_dataset)


def test_refits_are_bit_identical(tiny_dataset: Dataset) -> None:
    obs = tiny_dataset.obs()
    a = MaskedAutoencoder(epochs=2, seed=3, **FAST).fit(tiny_dataset)
    b = MaskedAutoencoder(epochs=2, seed=3, **FAST).fit(tiny_dataset)
    c = MaskedAutoencoder(epochs=2, seed=4, **FAST).fit(tiny_dataset)
    assert np.array_equal(a.encode(obs), b.encode(obs))
    assert a.history_ == b.history_
    assert not np.array_equal(a.encode(obs), c.encode(obs))


def test_without_masking_every_patch_is_a_target(tiny_dataset: Dataset) -> None:
    """mask_ratio=0 hides nothing; the reconstruction then covers all patches (a plain
    autoencoder through z) instead of dividing by zero masked patches."""
    enc = MaskedAutoencoder(epochs=1, mask_ratio=0.0, **FAST).fit(tiny_dataset)
    terms = enc.loss_terms(tiny_dataset)
    assert np.isfinite(terms["recon"]) and terms["recon"] > 0
    # the all-visible training path is the encode path
    net = enc.net_
    x = enc._obs_tensors(tiny_dataset.obs(), ("image", "ft", "proprio"))
    every = torch.arange(net.num_patches).expand(len(tiny_dataset), -1)
    with torch.inference_mode():
        z_all, _ = net.encode(x["image"], x["ft"], x["proprio"], every)
        z, _ = net.encode(x["image"], x["ft"], x["proprio"])
    torch.testing.assert_close(z_all, z)
