"""A masked autoencoder (He et al. 2022) over the wrist image, with force/torque and
proprioception as extra tokens, trained through a ``latent_dim`` bottleneck.

Encoder: a small vision transformer. The normalized image is cut into ``patch_size`` ×
``patch_size`` patches, each embedded by one convolution (kernel = stride = ``patch_size``) plus a
fixed 2-D sine-cosine position embedding. The standardized force/torque vector and the
standardized proprioception vector each become one more token (a linear layer plus a learned
type embedding), and a learned [CLS] token joins them. ``depth`` pre-norm transformer blocks mix
the tokens; z = Linear(LayerNorm([CLS] output)) of size ``latent_dim``. The encoder is
deterministic: ``encode`` returns z (all patches visible) as μ_z, with log σ_z = 0.

Objective (MAE through the bottleneck): per image, ``mask_ratio`` of the patches are hidden (a
per-sample random permutation drawn from the encoder's seeded ``torch.Generator``, so refits are
bit-identical) and the encoder sees only the visible patches, the force/proprio tokens and
[CLS]. A light decoder (``decoder_depth`` blocks of width ``decoder_dim``) receives z projected
to one token plus a shared mask token with a position embedding for *every* patch, and predicts
every patch's pixels. Loss terms:

* ``recon``: mean squared error over the masked patches only, against per-patch normalized
  targets (MAE's ``norm_pix_loss``: each target patch standardized by its own mean and
  variance, eps 1e-6); with no patch masked (``mask_ratio`` rounding to 0) over all patches;
* ``ft_recon``: mean squared error of the standardized force/torque, predicted by a linear
  layer from the decoder's output at the z token (weight ``ft_weight``).

A deliberate departure from MAE: there the decoder reads the encoder's visible-patch tokens, so
the reconstruction trains a token grid that no single vector summarizes. Here the decoder sees
*only* z — the visible tokens never reach it — so everything it reconstructs must pass through
the ``latent_dim``-dimensional latent, and the latent that agents read is exactly what the
objective trains.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from torch import nn

from repbench.dataset import FT, IMAGE, PROPRIO, Dataset
from repbench.errors import ConfigError
from repbench_encoders.networks import NetworkSpec
from repbench_encoders.trunk import TrunkEncoder

__all__ = ["MaskedAutoencoder", "patchify", "random_masking", "sincos_2d", "unpatchify"]

_NORM_PIX_EPS = 1e-6


def patchify(img: torch.Tensor, p: int) -> torch.Tensor:
    """Image ``[B, C, H, W]`` → patches ``[B, (H/p)·(W/p), p·p·C]`` in row-major patch order;
    each patch flattened as (row, column, channel)."""
    b, c, h, w = img.shape
    if h % p or w % p:
        raise ValueError(f"patch size {p} does not divide the image size {h} x {w}")
    x = img.reshape(b, c, h // p, p, w // p, p)
    return x.permute(0, 2, 4, 3, 5, 1).reshape(b, (h // p) * (w // p), p * p * c)


def unpatchify(patches: torch.Tensor, p: int, side: int) -> torch.Tensor:
    """Inverse of :func:`patchify` for a square image: ``[B, L, p·p·C]`` → ``[B, C, side,
    side]``."""
    b, n, d = patches.shape
    g = side // p
    if g * p != side or n != g * g or d % (p * p):
        raise ValueError(f"patches of shape {list(patches.shape)} do not tile a {side} x {side} "
                         f"image with patch size {p}")
    c = d // (p * p)
    x = patches.reshape(b, g, g, p, p, c)
    return x.permute(0, 5, 1, 3, 2, 4).reshape(b, c, side, side)


def random_masking(n: int, num_patches: int, ratio: float, gen: torch.Generator
                   ) -> tuple[torch.Tensor, torch.Tensor]:
    """A random mask per row: ``(keep_idx [n, K], mask [n, num_patches])``.

    Each row keeps K = round((1 − ``ratio``) · ``num_patches``) patches (at least 1), chosen by
    its own random permutation drawn from ``gen`` (on ``gen``'s device); ``keep_idx`` lists them
    in increasing order, ``mask`` is True at the hidden patches.
    """
    keep = max(1, round((1.0 - ratio) * num_patches))
    noise = torch.rand(n, num_patches, generator=gen, device=gen.device)
    order = torch.argsort(noise, dim=1, stable=True)
    keep_idx = order[:, :keep].sort(dim=1).values
    mask = torch.ones(n, num_patches, dtype=torch.bool, device=gen.device)
    mask.scatter_(1, keep_idx, False)
    return keep_idx, mask


def _sincos_1d(pos: torch.Tensor, dim: int) -> torch.Tensor:
    """[len(pos), dim]: sines then cosines of ``pos`` at ⌈dim/2⌉ geometric frequencies."""
    half = (dim + 1) // 2
    omega = 1.0 / 10000.0 ** (torch.arange(half, dtype=torch.float64) / max(half, 1))
    angles = pos.to(torch.float64)[:, None] * omega[None, :]
    return torch.cat([angles.sin(), angles.cos()], 1)[:, :dim]


def sincos_2d(side: int, dim: int) -> torch.Tensor:
    """Fixed 2-D sine-cosine position embeddings of a ``side`` × ``side`` patch grid, float32
    ``[side², dim]`` (row-major, as :func:`patchify`): half the channels encode the row, the rest
    the column (MAE's embedding, for any ``dim``)."""
    grid = torch.arange(side)
    rows, cols = grid.repeat_interleave(side), grid.repeat(side)
    emb = torch.cat([_sincos_1d(rows, dim // 2), _sincos_1d(cols, dim - dim // 2)], 1)
    return emb.float()


def _blocks(width: int, heads: int, depth: int) -> nn.ModuleList:
    return nn.ModuleList([
        nn.TransformerEncoderLayer(width, heads, dim_feedforward=4 * width, dropout=0.0,
                                   activation="gelu", batch_first=True, norm_first=True)
        for _ in range(depth)
    ])


class _MAENet(nn.Module):
    """The ViT encoder (image patches, force/proprio tokens, [CLS] → z) and the z-only decoder."""

    def __init__(self, spec: NetworkSpec, patch_size: int, embed_dim: int, depth: int,
                 num_heads: int, decoder_dim: int, decoder_depth: int) -> None:
        super().__init__()
        self.spec = spec
        self.patch_size = patch_size
        self.side = spec.image_size // patch_size
        self.num_patches = self.side * self.side
        e, d = embed_dim, decoder_dim
        # encoder
        self.patch_embed = nn.Conv2d(3, e, patch_size, stride=patch_size)
        self.register_buffer("pos_embed", sincos_2d(self.side, e)[None], persistent=False)
        self.cls_token = nn.Parameter(torch.zeros(1, 1, e))
        reads = spec.modalities
        self.ft_embed = nn.Linear(spec.ft_dim, e) if FT in reads else None
        self.ft_type = nn.Parameter(torch.zeros(1, 1, e)) if FT in reads else None
        self.proprio_embed = nn.Linear(spec.proprio_dim, e) if PROPRIO in reads else None
        self.proprio_type = nn.Parameter(torch.zeros(1, 1, e)) if PROPRIO in reads else None
        self.blocks = _blocks(e, num_heads, depth)
        self.norm = nn.LayerNorm(e)
        self.to_latent = nn.Linear(e, spec.latent_dim)
        # decoder
        self.z_proj = nn.Linear(spec.latent_dim, d)
        self.mask_token = nn.Parameter(torch.zeros(1, 1, d))
        self.register_buffer("dec_pos_embed", sincos_2d(self.side, d)[None], persistent=False)
        self.dec_blocks = _blocks(d, num_heads, decoder_depth)
        self.dec_norm = nn.LayerNorm(d)
        self.pixel_head = nn.Linear(d, patch_size * patch_size * 3)
        self.ft_head = nn.Linear(d, spec.ft_dim)
        for p in (self.cls_token, self.ft_type, self.proprio_type, self.mask_token):
            if p is not None:
                nn.init.normal_(p, std=0.02)

    def encode(self, image: torch.Tensor | None, ft: torch.Tensor | None,
               proprio: torch.Tensor | None, keep_idx: torch.Tensor | None = None
               ) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalized inputs → (z, zeros). ``keep_idx`` [B, K]: the visible patches (all when
        None)."""
        assert image is not None, "the masked autoencoder needs the image"
        x = self.patch_embed(image).flatten(2).transpose(1, 2) + self.pos_embed  # [B, L, E]
        if keep_idx is not None:
            x = torch.gather(x, 1, keep_idx[:, :, None].expand(-1, -1, x.shape[2]))
        b = x.shape[0]
        tokens = [self.cls_token.expand(b, -1, -1)]
        if self.ft_embed is not None:
            assert ft is not None and self.ft_type is not None
            tokens.append(self.ft_embed(ft)[:, None] + self.ft_type)
        if self.proprio_embed is not None:
            assert proprio is not None and self.proprio_type is not None
            tokens.append(self.proprio_embed(proprio)[:, None] + self.proprio_type)
        h = torch.cat([*tokens, x], 1)
        for block in self.blocks:
            h = block(h)
        z = self.to_latent(self.norm(h[:, 0]))
        return z, torch.zeros_like(z)

    def decode(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """z → (every patch's pixels [B, L, p·p·3], standardized force/torque [B, ft_dim])."""
        b = z.shape[0]
        patches = (self.mask_token + self.dec_pos_embed).expand(b, -1, -1)
        h = torch.cat([self.z_proj(z)[:, None], patches], 1)
        for block in self.dec_blocks:
            h = block(h)
        h = self.dec_norm(h)
        return self.pixel_head(h[:, 1:]), self.ft_head(h[:, 0])


class MaskedAutoencoder(TrunkEncoder):
    """A masked autoencoder whose decoder reads only the latent; ``encode`` returns z.

    See the module docstring for the network and the objective.

    Args:
        latent_dim: size D of z, the bottleneck between encoder and decoder.
        epochs: maximum passes over the training rows.
        batch_size: rows per Adam step.
        learning_rate: Adam learning rate.
        patch_size: side of the square image patches; must divide the image side.
        embed_dim: token width of the encoder; a multiple of ``num_heads``.
        depth: transformer blocks of the encoder.
        num_heads: attention heads of every block (encoder and decoder).
        decoder_dim: token width of the decoder; a multiple of ``num_heads``.
        decoder_depth: transformer blocks of the decoder (at least 1: attention is how z
            reaches the patch tokens).
        mask_ratio: share of the patches hidden from the encoder during training, in [0, 1).
        ft_weight: weight of the force/torque reconstruction term.
        patience: stop after this many epochs without a held-out improvement (0: never).
        validation_fraction: share of whole episodes held out (0: none).
        tol: relative held-out improvement that counts for ``patience``.
        seed: seeds initialization, the split, batch order and the masks.
        device: ``"auto"``, ``"cpu"``, ``"cuda"``, ...
        progress: show a progress bar while training.
    """

    family = "mae"

    LOSS_TERMS = ("recon", "ft_recon")
    fit_modalities = (IMAGE, FT, PROPRIO)

    def __init__(self, latent_dim: int = 16, epochs: int = 20, batch_size: int = 64,
                 learning_rate: float = 1e-3, patch_size: int = 8, embed_dim: int = 64,
                 depth: int = 3, num_heads: int = 4, decoder_dim: int = 64,
                 decoder_depth: int = 1, mask_ratio: float = 0.75, ft_weight: float = 1.0,
                 patience: int = 0, validation_fraction: float = 0.0, tol: float = 1e-3,
                 seed: int = 0, device: str = "auto", progress: bool = True) -> None:
        self.latent_dim = latent_dim
        self.epochs = epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.patch_size = patch_size
        self.embed_dim = embed_dim
        self.depth = depth
        self.num_heads = num_heads
        self.decoder_dim = decoder_dim
        self.decoder_depth = decoder_depth
        self.mask_ratio = mask_ratio
        self.ft_weight = ft_weight
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.tol = tol
        self.seed = seed
        self.device = device
        self.progress = progress

    def check_params(self) -> None:
        super().check_params()
        name = type(self).__name__
        if IMAGE not in self.required_modalities:
            raise ConfigError(f"{name}: a masked autoencoder reconstructs the image, so "
                              f"required_modalities must include {IMAGE!r}, got "
                              f"{tuple(self.required_modalities)}")
        for key in ("patch_size", "embed_dim", "depth", "num_heads", "decoder_dim",
                    "decoder_depth"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ConfigError(f"{name}: {key} must be a positive integer, got {v!r}")
        mr = self.mask_ratio
        if isinstance(mr, bool) or not (isinstance(mr, (int, float)) and 0.0 <= mr < 1.0):
            raise ConfigError(f"{name}: mask_ratio must be in [0, 1) (the encoder needs visible "
                              f"patches), got {mr!r}; MAE uses 0.75")
        fw = self.ft_weight
        if not (isinstance(fw, (int, float)) and math.isfinite(fw) and fw >= 0):
            raise ConfigError(f"{name}: ft_weight must be a finite number >= 0, got {fw!r}")
        for key in ("embed_dim", "decoder_dim"):
            v = getattr(self, key)
            if v % self.num_heads:
                raise ConfigError(f"{name}: {key}={v} must be divisible by num_heads="
                                  f"{self.num_heads}; change {key} to a multiple of num_heads "
                                  "or num_heads to a divisor of it")

    def _network_spec(self, dataset: Dataset) -> NetworkSpec:
        spec = super()._network_spec(dataset)
        side, p = spec.image_size, self.patch_size
        if side % p:
            divisors = [d for d in range(2, side) if side % d == 0]
            raise ConfigError(f"{type(self).__name__}: patch_size={p} does not divide the image "
                              f"side {side}; use a divisor of {side} such as {divisors}")
        return spec

    def _spec_options(self) -> dict[str, Any]:
        return {"decoder": False}

    def _build_net(self, spec: NetworkSpec) -> _MAENet:
        return _MAENet(spec, int(self.patch_size), int(self.embed_dim), int(self.depth),
                       int(self.num_heads), int(self.decoder_dim), int(self.decoder_depth))

    def _loss_terms(self, data: dict[str, torch.Tensor], idx: torch.Tensor,
                    idx_next: torch.Tensor | None, gen: torch.Generator, training: bool
                    ) -> dict[str, torch.Tensor]:
        net: _MAENet = self.net_
        reads = self.spec_["modalities"]
        image = self._image_input(data["image"][idx])
        ft = data["ft"][idx]
        keep_idx, mask = random_masking(idx.shape[0], net.num_patches, float(self.mask_ratio),
                                        gen)
        z, _ = net.encode(image, ft if FT in reads else None,
                          data["proprio"][idx] if PROPRIO in reads else None, keep_idx)
        pred_pixels, pred_ft = net.decode(z)
        target = patchify(image, net.patch_size)
        mean = target.mean(-1, keepdim=True)
        var = target.var(-1, keepdim=True)
        target = (target - mean) / (var + _NORM_PIX_EPS).sqrt()
        per_patch = ((pred_pixels - target) ** 2).mean(-1)  # [B, L]
        weight = mask.to(per_patch.dtype) if bool(mask.any()) else torch.ones_like(per_patch)
        recon = (per_patch * weight).sum() / weight.sum()
        ft_recon = ((pred_ft - ft) ** 2).mean()
        return {"loss": recon + self.ft_weight * ft_recon, "recon": recon, "ft_recon": ft_recon}
