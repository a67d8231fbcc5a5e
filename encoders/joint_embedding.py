"""Joint-embedding self-supervised encoders of today's literature, on the VAE family's trunk.

Each trains the multimodal trunk's μ_z through a small projection head on two augmented views
of an observation (the image randomly shifted, force and proprioception noised:
:func:`repbench_encoders.contrastive.augmented_inputs`), and differs only in its objective:

* ``simclr`` (Chen et al. 2020): NT-Xent over the 2B views of a batch, every other view a
  negative (:func:`nt_xent`).
* ``byol`` (Grill et al. 2020): an online predictor regresses a momentum (EMA) target network's
  projection of the other view; no negatives (:func:`byol_loss`).
* ``dino`` (Caron et al. 2021): self-distillation; a student's softmax over ``prototypes``
  matches a momentum teacher's centred, sharpened softmax of the other view (:func:`dino_loss`).
* ``vicreg`` (Bardes et al. 2022): invariance + variance + covariance on the projections
  (:func:`vicreg_loss`).
* ``barlow_twins`` (Zbontar et al. 2021): the views' cross-correlation matrix pushed to the
  identity (:func:`barlow_twins_loss`).
* ``spr`` (Schwarzer et al. 2021, one step): self-predictive representations; a transition
  model maps (z_n, a_n) to a prediction of the momentum target's projection of step n+1 of the
  same episode, BYOL's loss between them.

The losses are written here because the field's library for them (``lightly``) cannot be
installed beside this project's CPU torch (its ``torchvision`` dependency needs the CUDA build);
each is tested against a direct, loop-based transcription of its paper's formula and its known
answers (``tests/encoders/test_joint_embedding.py``). The heads (projector, predictor,
transition) use BatchNorm as the papers' do: with LayerNorm instead, BYOL's loss reached 0 by
the second epoch on the peg-in-hole's data (its projections collapsed to one direction) and
DINO's stayed at ln K (a uniform teacher), and both learn with it (measured on synthetic data:
BYOL 1.53 -> 0.35, DINO 3.74 -> 3.10 < ln 64 in 6 epochs). The heads are not part of
``encode``, so the latent never depends on the batch. ``encode`` returns the trunk's μ_z.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from repbench.errors import ConfigError
from repbench_encoders.contrastive import augmented_inputs
from repbench_encoders.networks import MultimodalVAENet, NetworkSpec
from repbench_encoders.trunk import TrunkEncoder, make_variant

__all__ = ["BYOL", "DINO", "SPR", "BarlowTwins", "JointEmbeddingEncoder", "SimCLR", "VICReg",
           "barlow_twins_loss", "byol_loss", "dino_loss", "nt_xent", "vicreg_loss"]

METHODS = ("simclr", "byol", "dino", "vicreg", "barlow_twins", "spr")
_MOMENTUM = ("byol", "dino", "spr")  # methods with an EMA target network


def nt_xent(z1: torch.Tensor, z2: torch.Tensor, temperature: float) -> torch.Tensor:
    """SimCLR's NT-Xent loss of B pairs: each of the 2B views must pick its partner among the
    other 2B − 1 by cosine similarity over ``temperature``; the mean cross-entropy."""
    z = F.normalize(torch.cat([z1, z2]), dim=1)
    n = z1.shape[0]
    logits = z @ z.T / temperature
    logits = logits.masked_fill(torch.eye(2 * n, dtype=torch.bool, device=z.device),
                                float("-inf"))
    partner = torch.cat([torch.arange(n, 2 * n), torch.arange(n)]).to(z.device)
    return F.cross_entropy(logits, partner)


def byol_loss(prediction: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """BYOL's regression loss ‖p̂ − t̂‖² = 2 − 2 cos(p, t) of unit vectors, batch mean; the
    target carries no gradient."""
    p = F.normalize(prediction, dim=1)
    t = F.normalize(target.detach(), dim=1)
    return (2 - 2 * (p * t).sum(1)).mean()


def dino_loss(student: torch.Tensor, teacher: torch.Tensor, center: torch.Tensor,
              student_temperature: float, teacher_temperature: float) -> torch.Tensor:
    """DINO's cross-entropy −Σ_k P_t(k) log P_s(k), batch mean: P_t the softmax of the centred
    teacher logits at the (sharper) teacher temperature, without gradient; P_s the student's."""
    p_teacher = F.softmax((teacher.detach() - center) / teacher_temperature, dim=1)
    log_p_student = F.log_softmax(student / student_temperature, dim=1)
    return -(p_teacher * log_p_student).sum(1).mean()


def _off_diagonal(m: torch.Tensor) -> torch.Tensor:
    return m[~torch.eye(m.shape[0], dtype=torch.bool, device=m.device)]


def vicreg_loss(z1: torch.Tensor, z2: torch.Tensor, sim_weight: float = 25.0,
                var_weight: float = 25.0, cov_weight: float = 1.0, eps: float = 1e-4
                ) -> dict[str, torch.Tensor]:
    """VICReg's three terms and their weighted sum ``loss``: invariance (MSE between the
    views), variance (hinge keeping each dimension's standard deviation above 1, per view),
    covariance (squared off-diagonal covariances over the dimension D, per view)."""
    d = z1.shape[1]
    invariance = F.mse_loss(z1, z2)
    variance = z1.new_zeros(())
    covariance = z1.new_zeros(())
    for z in (z1, z2):
        z = z - z.mean(0)
        std = torch.sqrt(z.var(0) + eps)
        variance = variance + F.relu(1 - std).mean() / 2
        cov = z.T @ z / (z.shape[0] - 1)
        covariance = covariance + _off_diagonal(cov).pow(2).sum() / d
    loss = sim_weight * invariance + var_weight * variance + cov_weight * covariance
    return {"loss": loss, "invariance": invariance, "variance": variance,
            "covariance": covariance}


def barlow_twins_loss(z1: torch.Tensor, z2: torch.Tensor, off_diagonal_weight: float,
                      eps: float = 1e-5) -> torch.Tensor:
    """Barlow Twins: C = the cross-correlation of the batch-standardized views;
    Σ_i (1 − C_ii)² + λ Σ_{i≠j} C_ij²."""
    n = z1.shape[0]
    a = (z1 - z1.mean(0)) / (z1.std(0, unbiased=False) + eps)
    b = (z2 - z2.mean(0)) / (z2.std(0, unbiased=False) + eps)
    c = a.T @ b / n
    on = (1 - torch.diagonal(c)).pow(2).sum()
    return on + off_diagonal_weight * _off_diagonal(c).pow(2).sum()


def _head(n_in: int, hidden: int, n_out: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(n_in, hidden), nn.BatchNorm1d(hidden), nn.ReLU(),
                         nn.Linear(hidden, n_out))


class _L2Normalize(nn.Module):
    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.normalize(x, dim=1)


class _JointEmbeddingNet(nn.Module):
    """The trunk, its projection head and the method's extra parts: a predictor (BYOL, SPR), a
    transition model (SPR), prototypes (DINO), and a frozen momentum copy of trunk + head."""

    def __init__(self, spec: NetworkSpec, method: str, projector_dim: int, prototypes: int,
                 action_dim: int) -> None:
        super().__init__()
        d = spec.latent_dim
        self.trunk = MultimodalVAENet(spec)
        self.projector: nn.Module = _head(d, projector_dim, projector_dim)
        out = projector_dim
        if method == "dino":  # DINO's head: MLP, L2-normalized bottleneck, weight-normed prototypes
            out = prototypes
            last = nn.utils.parametrizations.weight_norm(
                nn.Linear(projector_dim, prototypes, bias=False))
            self.projector = nn.Sequential(self.projector, _L2Normalize(), last)
        self.predictor = (_head(projector_dim, projector_dim, projector_dim)
                          if method in ("byol", "spr") else None)
        self.transition = _head(d + action_dim, spec.fusion_hidden, d) if method == "spr" else None
        self.target: nn.ModuleDict | None = None
        if method in _MOMENTUM:
            self.target = nn.ModuleDict({"trunk": copy.deepcopy(self.trunk),
                                         "projector": copy.deepcopy(self.projector)})
            self.target.requires_grad_(False)
        self.register_buffer("center", torch.zeros(out))  # DINO's teacher centre

    def encode(self, image: torch.Tensor | None, ft: torch.Tensor | None,
               proprio: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
        return self.trunk.encode(image, ft, proprio)

    def target_projection(self, image: torch.Tensor | None, ft: torch.Tensor | None,
                          proprio: torch.Tensor | None) -> torch.Tensor:
        assert self.target is not None
        with torch.no_grad():
            mu, _ = self.target["trunk"].encode(image, ft, proprio)
            return self.target["projector"](mu)

    @torch.no_grad()
    def update_target(self, momentum: float) -> None:
        """target ← momentum · target + (1 − momentum) · online."""
        assert self.target is not None
        for online, tgt in ((self.trunk, self.target["trunk"]),
                            (self.projector, self.target["projector"])):
            for p, q in zip(online.parameters(), tgt.parameters(), strict=True):
                q.mul_(momentum).add_(p.detach(), alpha=1 - momentum)


class JointEmbeddingEncoder(TrunkEncoder):
    """The multimodal trunk trained by a joint-embedding objective (``method``); ``encode``
    returns the trunk's μ_z.

    Args:
        method: one of ``simclr``, ``byol``, ``dino``, ``vicreg``, ``barlow_twins``, ``spr``.
        latent_dim: size D of z.
        epochs: maximum passes over the training rows (pairs (n, n+1) for ``spr``).
        batch_size: rows per Adam step (SimCLR's negatives are the batch's other views).
        learning_rate: Adam learning rate.
        projector_dim: width of the projection head (and its output; DINO's head outputs
            ``prototypes`` logits).
        shift: largest random image shift of a view, in pixels.
        input_noise: standard deviation of the noise on standardized force and proprioception
            per view.
        temperature: SimCLR's NT-Xent temperature.
        momentum: EMA rate of the target network (BYOL, DINO, SPR).
        prototypes: number of DINO's output prototypes K.
        student_temperature: DINO's student softmax temperature.
        teacher_temperature: DINO's (sharper) teacher softmax temperature.
        center_momentum: EMA rate of DINO's teacher centre.
        off_diagonal_weight: Barlow Twins' λ (the paper's 5e-3 is for 8192 dimensions; about
            1/``projector_dim`` here).
        patience: stop after this many epochs without a held-out improvement (0: never).
        validation_fraction: share of whole episodes held out (0: none).
        tol: relative held-out improvement that counts for ``patience``.
        seed: seeds initialization, the split, batch order and the augmentations.
        device: ``"auto"``, ``"cpu"``, ``"cuda"``, ...
        progress: show a progress bar while training.
    """

    family = "joint_embedding"
    #: 1: BatchNorm heads (0, LayerNorm heads, collapsed for BYOL and DINO; never in a record)
    version = 1

    LOSS_TERMS = ("objective", "invariance", "variance", "covariance", "embedding_std")

    def __init__(self, method: str = "simclr", latent_dim: int = 16, epochs: int = 20,
                 batch_size: int = 64, learning_rate: float = 1e-3, projector_dim: int = 64,
                 shift: int = 4, input_noise: float = 0.5, temperature: float = 0.1,
                 momentum: float = 0.99, prototypes: int = 64,
                 student_temperature: float = 0.1, teacher_temperature: float = 0.04,
                 center_momentum: float = 0.9, off_diagonal_weight: float = 0.02,
                 patience: int = 0, validation_fraction: float = 0.0, tol: float = 1e-3,
                 seed: int = 0, device: str = "auto", progress: bool = True) -> None:
        self.method = method
        self.latent_dim = latent_dim
        self.epochs = epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.projector_dim = projector_dim
        self.shift = shift
        self.input_noise = input_noise
        self.temperature = temperature
        self.momentum = momentum
        self.prototypes = prototypes
        self.student_temperature = student_temperature
        self.teacher_temperature = teacher_temperature
        self.center_momentum = center_momentum
        self.off_diagonal_weight = off_diagonal_weight
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.tol = tol
        self.seed = seed
        self.device = device
        self.progress = progress

    @property
    def temporal(self) -> bool:
        return self.method == "spr"

    def check_params(self) -> None:
        super().check_params()
        name = type(self).__name__
        if self.method not in METHODS:
            raise ConfigError(f"{name}: method must be one of {METHODS}, got {self.method!r}")
        for key in ("projector_dim", "prototypes"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 2:
                raise ConfigError(f"{name}: {key} must be an integer >= 2, got {v!r}")
        if isinstance(self.shift, bool) or not isinstance(self.shift, (int, np.integer)) \
                or self.shift < 0:
            raise ConfigError(f"{name}: shift must be an integer >= 0, got {self.shift!r}")
        for key in ("temperature", "student_temperature", "teacher_temperature"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"{name}: {key} must be > 0, got {v!r}")
        for key in ("momentum", "center_momentum"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and 0 <= v < 1):
                raise ConfigError(f"{name}: {key} must be in [0, 1), got {v!r}")
        for key in ("input_noise", "off_diagonal_weight"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"{name}: {key} must be a finite number >= 0, got {v!r}")

    def _spec_options(self) -> dict[str, Any]:
        return {"decoder": False}

    def _build_net(self, spec: NetworkSpec) -> _JointEmbeddingNet:
        return _JointEmbeddingNet(spec, self.method, int(self.projector_dim),
                                  int(self.prototypes), spec.action_dim)

    def _eval_batch_size(self) -> int:
        return int(self.batch_size)  # the objectives are over a batch

    def _after_step(self) -> None:
        if self.method in _MOMENTUM:
            self.net_.update_target(float(self.momentum))

    def _loss_terms(self, data: dict[str, torch.Tensor], idx: torch.Tensor,
                    idx_next: torch.Tensor | None, gen: torch.Generator, training: bool
                    ) -> dict[str, torch.Tensor]:
        net, shift, noise = self.net_, int(self.shift), float(self.input_noise)
        if training and idx.shape[0] == 1:  # BatchNorm needs two rows: an epoch's last batch
            idx = idx.repeat(2)
            idx_next = None if idx_next is None else idx_next.repeat(2)
        if self.method == "spr":
            assert idx_next is not None
            online = augmented_inputs(self, data, idx, gen, shift, noise)
            target = augmented_inputs(self, data, idx_next, gen, shift, noise)
            mu, _ = net.encode(*online)
            z_next = net.transition(torch.cat([mu, data["action"][idx]], 1))
            prediction = net.predictor(net.projector(z_next))
            objective = byol_loss(prediction, net.target_projection(*target))
            return self._with_diagnostics(objective, mu, mu)
        view1 = augmented_inputs(self, data, idx, gen, shift, noise)
        view2 = augmented_inputs(self, data, idx, gen, shift, noise)
        mu1, _ = net.encode(*view1)
        mu2, _ = net.encode(*view2)
        p1, p2 = net.projector(mu1), net.projector(mu2)
        extra: dict[str, torch.Tensor] = {}
        if self.method == "simclr":
            objective = nt_xent(p1, p2, float(self.temperature))
        elif self.method == "byol":
            objective = (byol_loss(net.predictor(p1), net.target_projection(*view2))
                         + byol_loss(net.predictor(p2), net.target_projection(*view1))) / 2
        elif self.method == "dino":
            t1, t2 = net.target_projection(*view1), net.target_projection(*view2)
            ts, tt = float(self.student_temperature), float(self.teacher_temperature)
            objective = (dino_loss(p1, t2, net.center, ts, tt)
                         + dino_loss(p2, t1, net.center, ts, tt)) / 2
            if training:
                with torch.no_grad():
                    m = float(self.center_momentum)
                    net.center.mul_(m).add_(torch.cat([t1, t2]).mean(0), alpha=1 - m)
        elif self.method == "vicreg":
            extra = vicreg_loss(p1, p2)
            objective = extra.pop("loss")
        else:  # barlow_twins
            objective = barlow_twins_loss(p1, p2, float(self.off_diagonal_weight))
        return self._with_diagnostics(objective, mu1, mu2, **extra)

    @staticmethod
    def _with_diagnostics(objective: torch.Tensor, mu1: torch.Tensor, mu2: torch.Tensor,
                          **extra: torch.Tensor) -> dict[str, torch.Tensor]:
        """The loss and the reported terms; ``embedding_std`` (mean per-dimension standard
        deviation of μ_z over the batch) shows a collapse, which these objectives risk."""
        zero = objective.new_zeros(())
        with torch.no_grad():
            spread = torch.cat([mu1, mu2]).std(0).mean()
        terms = {"loss": objective, "objective": objective, "invariance": zero,
                 "variance": zero, "covariance": zero, "embedding_std": spread}
        terms.update({k: v.detach() for k, v in extra.items()})
        return terms


def _variant(name: str, doc: str, **defaults: Any) -> type[JointEmbeddingEncoder]:
    return make_variant(JointEmbeddingEncoder, name, doc, module=__name__, **defaults)


SimCLR = _variant("SimCLR", "SimCLR: NT-Xent between two augmented views.", method="simclr")
BYOL = _variant("BYOL", "BYOL: predict a momentum target's projection of the other view.",
                method="byol")
DINO = _variant("DINO", "DINO: self-distillation from a momentum teacher, centred and "
                "sharpened.", method="dino")
VICReg = _variant("VICReg", "VICReg: invariance, variance and covariance terms.",
                  method="vicreg")
BarlowTwins = _variant("BarlowTwins", "Barlow Twins: cross-correlation of the views towards "
                       "the identity.", method="barlow_twins")
SPR = _variant("SPR", "SPR (one step): predict the momentum target's projection of the next "
               "step from z and the action.", method="spr")
