"""Objectives from representation learning *for control*, on the VAE family's trunk.

* ``r3m`` (Nair et al. 2022, without its language term, which needs annotated videos): a
  time-contrastive loss over triplets of one episode, anchor i, positive j and hard negative k
  with i < j < k (j closer in time than k), plus rows of other episodes as negatives; the
  similarity is the negative squared L2 distance, S(a, b) = −‖z_a − z_b‖²:

      L = −log [ e^{S(i,j)} / (e^{S(i,j)} + e^{S(i,k)} + Σ_{o ∈ other episodes} e^{S(i,o)}) ]

  plus R3M's L1 and L2 penalties on z (:func:`r3m_time_contrastive`).
* ``inverse_dynamics`` (multi-step inverse models, e.g. ACRO, Islam et al. 2023): a head
  predicts the action a_n taken at step n from (z_n, z_{n+k}); the mean squared error of the
  standardized action. What such a latent keeps is what the agent's own actions control.

``encode`` returns the trunk's μ_z.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch
from torch import nn

from repbench.dataset import Dataset
from repbench.errors import ConfigError, DataError
from repbench_encoders.networks import MultimodalVAENet, NetworkSpec
from repbench_encoders.trunk import TrunkEncoder, make_variant

__all__ = ["R3M", "ControlObjectiveEncoder", "InverseDynamics", "r3m_time_contrastive",
           "sample_triplets"]

OBJECTIVES = ("r3m", "inverse_dynamics")


def r3m_time_contrastive(anchor: torch.Tensor, positive: torch.Tensor, negative: torch.Tensor,
                         other: torch.Tensor, other_mask: torch.Tensor) -> torch.Tensor:
    """R3M's time-contrastive loss, batch mean.

    ``anchor``, ``positive``, ``negative``: [B, D] (row b's triplet from one episode);
    ``other``: [M, D] candidates from the batch; ``other_mask`` [B, M] True where candidate m
    is a valid negative for row b (another episode).
    """
    s_pos = -(anchor - positive).pow(2).sum(1)
    s_neg = -(anchor - negative).pow(2).sum(1)
    s_other = -torch.cdist(anchor, other).pow(2)
    s_other = s_other.masked_fill(~other_mask, float("-inf"))
    logits = torch.cat([s_pos[:, None], s_neg[:, None], s_other], 1)
    return -torch.log_softmax(logits, dim=1)[:, 0].mean()


def sample_triplets(anchor: torch.Tensor, steps_left: torch.Tensor, positive_window: int,
                    negative_window: int, gen: torch.Generator
                    ) -> tuple[torch.Tensor, torch.Tensor]:
    """R3M's positive and hard-negative rows for ``anchor`` rows (episodes stored as
    consecutive rows; ``steps_left`` ≥ ``positive_window`` + 1 later steps in each anchor's
    episode): the positive 1 to ``positive_window`` steps later, the negative
    ``positive_window`` + 1 to ``negative_window`` steps later (at most the episode's end),
    uniformly."""
    n, dev = anchor.shape[0], anchor.device
    positive = anchor + torch.randint(1, positive_window + 1, (n,), generator=gen, device=dev)
    furthest = torch.clamp(steps_left, max=negative_window)
    u = torch.rand(n, generator=gen, device=dev)
    span = furthest - positive_window  # choices for the negative, >= 1
    negative = anchor + positive_window + 1 + torch.minimum((u * span).long(), span - 1)
    return positive, negative


class _Net(nn.Module):
    def __init__(self, spec: NetworkSpec, objective: str) -> None:
        super().__init__()
        self.trunk = MultimodalVAENet(spec)
        d = spec.latent_dim
        self.action_head = (nn.Sequential(nn.Linear(2 * d, spec.fusion_hidden), nn.ReLU(),
                                          nn.Linear(spec.fusion_hidden, spec.action_dim))
                            if objective == "inverse_dynamics" else None)

    def encode(self, image: torch.Tensor | None, ft: torch.Tensor | None,
               proprio: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
        return self.trunk.encode(image, ft, proprio)


class ControlObjectiveEncoder(TrunkEncoder):
    """The multimodal trunk trained by a control-oriented objective; ``encode`` returns μ_z.

    Args:
        objective: ``"r3m"`` or ``"inverse_dynamics"``.
        latent_dim: size D of z.
        epochs: maximum passes over the training rows.
        batch_size: rows per Adam step.
        learning_rate: Adam learning rate.
        positive_window: R3M's positive is 1 to this many steps after the anchor.
        negative_window: R3M's hard negative is ``positive_window + 1`` to this many steps
            after the anchor (fewer near an episode's end; rows without
            ``positive_window + 1`` later steps in their episode are not anchors).
        l1_weight: R3M's L1 penalty on z (paper: 1e-5).
        l2_weight: R3M's L2 penalty on z (paper: 1e-5).
        horizon: the inverse model sees (z_n, z_{n+horizon}) and predicts a_n.
        patience: stop after this many epochs without a held-out improvement (0: never).
        validation_fraction: share of whole episodes held out (0: none).
        tol: relative held-out improvement that counts for ``patience``.
        seed: seeds initialization, the split, batch order and the sampled triplets.
        device: ``"auto"``, ``"cpu"``, ``"cuda"``, ...
        progress: show a progress bar while training.
    """

    family = "control_objective"

    LOSS_TERMS = ("objective", "sparsity")

    def __init__(self, objective: str = "r3m", latent_dim: int = 16, epochs: int = 20,
                 batch_size: int = 64, learning_rate: float = 1e-3, positive_window: int = 3,
                 negative_window: int = 15, l1_weight: float = 1e-5, l2_weight: float = 1e-5,
                 horizon: int = 1, patience: int = 0, validation_fraction: float = 0.0,
                 tol: float = 1e-3, seed: int = 0, device: str = "auto",
                 progress: bool = True) -> None:
        self.objective = objective
        self.latent_dim = latent_dim
        self.epochs = epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.positive_window = positive_window
        self.negative_window = negative_window
        self.l1_weight = l1_weight
        self.l2_weight = l2_weight
        self.horizon = horizon
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.tol = tol
        self.seed = seed
        self.device = device
        self.progress = progress

    @property
    def temporal(self) -> bool:
        return True

    def check_params(self) -> None:
        super().check_params()
        name = type(self).__name__
        if self.objective not in OBJECTIVES:
            raise ConfigError(f"{name}: objective must be one of {OBJECTIVES}, "
                              f"got {self.objective!r}")
        for key in ("positive_window", "negative_window", "horizon"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ConfigError(f"{name}: {key} must be a positive integer, got {v!r}")
        if self.negative_window <= self.positive_window:
            raise ConfigError(f"{name}: negative_window ({self.negative_window}) must be larger "
                              f"than positive_window ({self.positive_window}): the hard "
                              "negative is further in time than the positive")
        for key in ("l1_weight", "l2_weight"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"{name}: {key} must be a finite number >= 0, got {v!r}")

    def _spec_options(self) -> dict[str, Any]:
        return {"decoder": False}

    def _build_net(self, spec: NetworkSpec) -> _Net:
        return _Net(spec, self.objective)

    def _eval_batch_size(self) -> int:
        return int(self.batch_size)  # R3M's negatives are the batch's other episodes

    def _offset(self) -> int:
        return int(self.positive_window + 1 if self.objective == "r3m" else self.horizon)

    def _pairs(self, dataset: Dataset) -> tuple[np.ndarray, np.ndarray | None]:
        """Anchors with ``_offset()`` later steps in their episode; the partner is that step
        (rows in between are the same episode's consecutive steps)."""
        rows, later = dataset.successor_index(self._offset())
        if rows.size == 0:
            raise DataError(f"{type(self).__name__} needs episodes longer than "
                            f"{self._offset()} steps; lower "
                            f"{'positive_window' if self.objective == 'r3m' else 'horizon'}")
        return rows, later

    def _extra_tensors(self, dataset: Dataset) -> dict[str, torch.Tensor]:
        """Each row's episode and how many later steps its episode has after it."""
        episode = dataset.episode.astype(np.int64)
        last = np.r_[np.flatnonzero(episode[1:] != episode[:-1]), episode.size - 1]
        end = last[np.searchsorted(last, np.arange(episode.size))]
        return {"episode": torch.as_tensor(episode, device=self._device),
                "steps_left": torch.as_tensor(end - np.arange(episode.size), device=self._device)}

    def _loss_terms(self, data: dict[str, torch.Tensor], idx: torch.Tensor,
                    idx_next: torch.Tensor | None, gen: torch.Generator, training: bool
                    ) -> dict[str, torch.Tensor]:
        assert idx_next is not None
        if self.objective == "inverse_dynamics":
            mu, _ = self._encode_rows(data, torch.cat([idx, idx_next]))
            n = idx.shape[0]
            predicted = self.net_.action_head(torch.cat([mu[:n], mu[n:]], 1))
            objective = (predicted - data["action"][idx]).pow(2).sum(1).mean()
            zero = objective.new_zeros(())
            return {"loss": objective, "objective": objective, "sparsity": zero}
        n, pw, nw = idx.shape[0], int(self.positive_window), int(self.negative_window)
        pos, neg = sample_triplets(idx, data["steps_left"][idx], pw, nw, gen)
        mu, _ = self._encode_rows(data, torch.cat([idx, pos, neg]))
        anchor, positive, negative = mu[:n], mu[n:2 * n], mu[2 * n:]
        episode = data["episode"][idx]
        other_mask = episode[:, None] != episode[None, :]
        objective = r3m_time_contrastive(anchor, positive, negative, anchor, other_mask)
        sparsity = (self.l1_weight * mu.abs().sum(1).mean()
                    + self.l2_weight * mu.pow(2).sum(1).mean())
        return {"loss": objective + sparsity, "objective": objective, "sparsity": sparsity}


R3M = make_variant(ControlObjectiveEncoder, "R3M", "R3M's time-contrastive objective with L1/L2 "
                   "sparsity (no language term).", module=__name__, objective="r3m")
InverseDynamics = make_variant(ControlObjectiveEncoder, "InverseDynamics", "Inverse dynamics: "
                               "predict a_n from (z_n, z_{n+1}).", module=__name__,
                               objective="inverse_dynamics")
