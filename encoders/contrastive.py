"""Contrastive encoders on the VAE family's trunk and inputs: only the objective differs.

Both train the trunk's μ_z with InfoNCE (van den Oord et al. 2018): in a batch of B pairs
(anchor_i, positive_i), a critic scores every anchor against every positive and the loss is the
cross-entropy of picking the right one,

    L = −(1/B) Σ_i log [ exp(s(a_i, p_i) / τ) / Σ_j exp(s(a_i, p_j) / τ) ],

with s the cosine similarity and τ a temperature. ln B − L is a lower bound on I(anchor;
positive) that can never exceed ln B (:func:`info_nce`).

* ``time_contrastive`` — positives are the observation ``time_offset`` steps later in the same
  episode (:meth:`repbench.Dataset.successor_index`, so never across episodes); the other pairs
  of the batch, drawn from all episodes, are the negatives (time-contrastive networks, CPC).
* ``curl`` — CURL-style instance discrimination (Laskin et al. 2020): two independently augmented
  views of the same observation are positives. The wrist image is randomly shifted by up to
  ``shift`` pixels (pad with the border, crop back: DrQ's random shift, Kostrikov et al. 2020).
  Force and proprioception get independent Gaussian noise of ``input_noise`` standard deviations,
  because without it two views share exact force/proprio values and the task is solved by them
  alone, leaving the image unused. A shared encoder embeds both views (SimCLR-style; CURL's
  momentum key encoder is left out to keep one set of weights).

The random shift is ten lines of torch rather than a library call: kornia's per-sample crops draw
from torch's global random state, while every random choice here comes from the encoder's own
seeded ``torch.Generator`` (bit-identical refits, no hidden global state), and the project takes
on no new dependency for it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from repbench.dataset import FT, IMAGE, PROPRIO, Dataset
from repbench.errors import ConfigError, DataError
from repbench_encoders.networks import MultimodalVAENet, NetworkSpec
from repbench_encoders.trunk import TrunkEncoder, make_variant

__all__ = ["AugmentContrastive", "ContrastiveEncoder", "TimeContrastive", "augmented_inputs",
           "info_nce", "random_shift"]

OBJECTIVES = ("time", "augment")


def info_nce(anchor: torch.Tensor, positive: torch.Tensor, temperature: float = 0.1
             ) -> torch.Tensor:
    """InfoNCE loss of a batch: row i of ``anchor`` should pick row i of ``positive``.

    Cosine similarity over ``temperature``; returns the mean cross-entropy (≥ 0). ``ln B −
    loss`` is the InfoNCE lower bound on the mutual information, at most ln B.
    """
    a = F.normalize(anchor, dim=1)
    p = F.normalize(positive, dim=1)
    logits = a @ p.T / temperature
    labels = torch.arange(a.shape[0], device=a.device)
    return F.cross_entropy(logits, labels)


def random_shift(image: torch.Tensor, pad: int, gen: torch.Generator) -> torch.Tensor:
    """Shift each image of ``[B, C, H, W]`` by its own random integer offset in [−pad, pad]²:
    replicate-pad by ``pad`` and crop back to H × W (DrQ's augmentation)."""
    if pad == 0:
        return image
    b, _, h, w = image.shape
    padded = F.pad(image, (pad, pad, pad, pad), mode="replicate")
    dev = image.device
    sy = torch.randint(0, 2 * pad + 1, (b,), generator=gen, device=dev)
    sx = torch.randint(0, 2 * pad + 1, (b,), generator=gen, device=dev)
    rows = torch.arange(h, device=dev)[None, :] + sy[:, None]  # [B, H]
    cols = torch.arange(w, device=dev)[None, :] + sx[:, None]  # [B, W]
    batch = torch.arange(b, device=dev)[:, None, None]
    out = padded.permute(0, 2, 3, 1)[batch, rows[:, :, None], cols[:, None, :]]  # [B, H, W, C]
    return out.permute(0, 3, 1, 2).contiguous(memory_format=torch.channels_last)


def augmented_inputs(encoder: TrunkEncoder, data: dict[str, torch.Tensor], rows: torch.Tensor,
                     gen: torch.Generator, shift: int, input_noise: float
                     ) -> tuple[torch.Tensor | None, torch.Tensor | None, torch.Tensor | None]:
    """One augmented view of dataset ``rows`` as the trunk's ``(image, ft, proprio)`` inputs
    (None for a modality ``encoder`` does not read): the image randomly shifted by up to
    ``shift`` pixels (:func:`random_shift`), standardized force and proprioception with
    Gaussian noise of ``input_noise`` standard deviations."""
    reads = encoder.spec_["modalities"]
    image = ft = proprio = None
    if IMAGE in reads:
        image = random_shift(encoder._image_input(data["image"][rows]), shift, gen)
    if FT in reads:
        ft = data["ft"][rows]
        ft = ft + input_noise * torch.randn(ft.shape, generator=gen, device=ft.device)
    if PROPRIO in reads:
        proprio = data["proprio"][rows]
        proprio = proprio + input_noise * torch.randn(proprio.shape, generator=gen,
                                                      device=proprio.device)
    return image, ft, proprio


class ContrastiveEncoder(TrunkEncoder):
    """The multimodal trunk trained with InfoNCE; ``encode`` returns the trunk's μ_z.

    Args:
        objective: ``"time"`` (positives: the step ``time_offset`` later in the same episode) or
            ``"augment"`` (positives: another augmented view of the same observation).
        latent_dim: size D of z.
        epochs: maximum passes over the training rows (pairs for ``"time"``).
        batch_size: pairs per Adam step; the other B − 1 pairs are the negatives.
        learning_rate: Adam learning rate.
        temperature: τ of the cosine critic.
        time_offset: steps between anchor and positive (``"time"``).
        shift: largest image shift in pixels (``"augment"``).
        input_noise: standard deviation of the noise on standardized force and proprioception
            per view (``"augment"``).
        patience: stop after this many epochs without a held-out improvement (0: never).
        validation_fraction: share of whole episodes held out (0: none).
        tol: relative held-out improvement that counts for ``patience``.
        seed: seeds initialization, the split, batch order and the augmentations.
        device: ``"auto"``, ``"cpu"``, ``"cuda"``, ...
        progress: show a progress bar while training.
    """

    family = "contrastive"

    LOSS_TERMS = ("infonce", "top1")

    def __init__(self, objective: str = "time", latent_dim: int = 16, epochs: int = 20,
                 batch_size: int = 64, learning_rate: float = 1e-3, temperature: float = 0.1,
                 time_offset: int = 1, shift: int = 4, input_noise: float = 0.5,
                 patience: int = 0, validation_fraction: float = 0.0, tol: float = 1e-3,
                 seed: int = 0, device: str = "auto", progress: bool = True) -> None:
        self.objective = objective
        self.latent_dim = latent_dim
        self.epochs = epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.temperature = temperature
        self.time_offset = time_offset
        self.shift = shift
        self.input_noise = input_noise
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.tol = tol
        self.seed = seed
        self.device = device
        self.progress = progress

    @property
    def temporal(self) -> bool:
        return self.objective == "time"

    def check_params(self) -> None:
        super().check_params()
        name = type(self).__name__
        if self.objective not in OBJECTIVES:
            raise ConfigError(f"{name}: objective must be one of {OBJECTIVES}, "
                              f"got {self.objective!r}")
        if not (isinstance(self.temperature, (int, float)) and math.isfinite(self.temperature)
                and self.temperature > 0):
            raise ConfigError(f"{name}: temperature must be > 0, got {self.temperature!r}")
        for key in ("time_offset", "shift"):
            v = getattr(self, key)
            low = 1 if key == "time_offset" else 0
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                raise ConfigError(f"{name}: {key} must be an integer >= {low}, got {v!r}")
        if not (isinstance(self.input_noise, (int, float)) and math.isfinite(self.input_noise)
                and self.input_noise >= 0):
            raise ConfigError(f"{name}: input_noise must be a finite number >= 0, "
                              f"got {self.input_noise!r}")

    def _spec_options(self) -> dict[str, Any]:
        return {"decoder": False}

    def _build_net(self, spec: NetworkSpec) -> MultimodalVAENet:
        return MultimodalVAENet(spec)

    def _pairs(self, dataset: Dataset) -> tuple[np.ndarray, np.ndarray | None]:
        if not self.temporal:
            return np.arange(len(dataset)), None
        rows, nxt = dataset.successor_index(self.time_offset)
        if rows.size == 0:
            raise DataError(f"{type(self).__name__} needs pairs (n, n+{self.time_offset}) from "
                            "one episode; the dataset's episodes are too short")
        return rows, nxt

    def _eval_batch_size(self) -> int:
        return int(self.batch_size)  # InfoNCE depends on the number of negatives

    def _view(self, data: dict[str, torch.Tensor], rows: torch.Tensor, gen: torch.Generator
              ) -> torch.Tensor:
        """μ_z of one augmented view of ``rows``."""
        mu, _ = self.net_.encode(*augmented_inputs(self, data, rows, gen, int(self.shift),
                                                   float(self.input_noise)))
        return mu

    def _loss_terms(self, data: dict[str, torch.Tensor], idx: torch.Tensor,
                    idx_next: torch.Tensor | None, gen: torch.Generator, training: bool
                    ) -> dict[str, torch.Tensor]:
        if self.temporal:
            assert idx_next is not None
            mu, _ = self._encode_rows(data, torch.cat([idx, idx_next]))
            anchor, positive = mu[:idx.shape[0]], mu[idx.shape[0]:]
        else:
            anchor, positive = self._view(data, idx, gen), self._view(data, idx, gen)
        loss = info_nce(anchor, positive, self.temperature)
        with torch.no_grad():
            sim = F.normalize(anchor, dim=1) @ F.normalize(positive, dim=1).T
            top1 = (sim.argmax(1) == torch.arange(sim.shape[0], device=sim.device)).float().mean()
        return {"loss": loss, "infonce": loss, "top1": top1}


TimeContrastive = make_variant(
    ContrastiveEncoder, "TimeContrastive", "Time-contrastive encoder: InfoNCE with the next "
    "step of the same episode as the positive.", module=__name__, objective="time")
AugmentContrastive = make_variant(
    ContrastiveEncoder, "AugmentContrastive", "CURL-style encoder: InfoNCE between two randomly "
    "shifted (image) and noised (force, proprio) views of one observation.", module=__name__,
    objective="augment")
