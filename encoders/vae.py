"""The paper's VAE family: one configurable multimodal VAE and its ten registered variants.

Every variant is :class:`MultimodalVAE` with other default loss weights (paper, appendix):
reconstruction 1e-4, KL 10 (standard) or 0.1 (``*LowKL``), success 0.1, next-latent prediction
1.0, next-image prediction 1e-4, smoothness 500 (0.1 for the low-KL twin).

Loss terms, per sample, averaged over the batch:

* ``recon``: squared error of the image in pixel units (0–255, summed over pixels) plus the
  squared error of the standardized force × ``ft_recon_scale`` (summed over its 6 axes), decoded
  from ``z ⊕ last_action`` (the torque input that led into the step);
* ``kl``: KL(q(z|x) ‖ N(0, I)), summed over latent dimensions;
* ``success``: cross-entropy of the success classifier on z;
* ``pred_z``: KL(q(z_{n+1}|x_{n+1}) ‖ p(z_{n+1}|z_n, a_n)), the next-latent predictor's
  Gaussian against the encoder's posterior at n+1;
* ``pred_im``: squared error (pixel units) of the image at n+1 predicted from z_n and a_n;
* ``smooth``: ‖μ_{n+1} − μ_n‖ (Euclidean norm).

Pairs (n, n+1) always come from one episode (:meth:`repbench.Dataset.successor_index`);
variants with a temporal term train on such pairs and apply the VAE terms to both halves.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from repbench.dataset import (
    FT,
    FT_HISTORY,
    HISTORY_STEPS,
    IMAGE,
    LAST_ACTION,
    PROPRIO,
    Dataset,
    stacked_history,
)
from repbench.errors import ConfigError
from repbench_encoders.networks import MultimodalVAENet, NetworkSpec
from repbench_encoders.trunk import TrunkEncoder, make_variant

__all__ = [  # noqa: RUF022 (grouped: the base, the paper's ten, the ablations)
    "MultimodalVAE", "gaussian_kl",
    "VAE", "VAELowKL", "SuccessVAE", "SuccessVAELowKL", "PredZVAE", "PredZVAELowKL",
    "PredImVAE", "PredImVAELowKL", "SmoothVAE", "SmoothVAELowKL",
    "VAELowKLD4", "VAELowKLD64", "ImageOnlyVAELowKL", "FtProprioVAELowKL",
    "VAELowKLBalanced", "ForceHistoryVAE", "VAELowKLFtHistory",
]

LOSS_TERMS = ("recon", "kl", "success", "pred_z", "pred_im", "smooth")


def gaussian_kl(mu_q: torch.Tensor, log_std_q: torch.Tensor, mu_p: torch.Tensor,
                log_std_p: torch.Tensor) -> torch.Tensor:
    """KL(N(μ_q, σ_q²) ‖ N(μ_p, σ_p²)) of diagonal Gaussians, summed over the last axis."""
    var_ratio = (2 * (log_std_q - log_std_p)).exp()
    mean_term = ((mu_q - mu_p) / log_std_p.exp()) ** 2
    return (0.5 * (var_ratio + mean_term - 1.0) - (log_std_q - log_std_p)).sum(-1)


class MultimodalVAE(TrunkEncoder):
    """The paper's multimodal VAE (image + force + proprioception), with optional auxiliary
    losses; ``encode`` returns μ_z.

    Args:
        latent_dim: size D of z (paper: 16).
        epochs: maximum passes over the training samples (or pairs, for temporal variants);
            early stopping (``patience``) may end training sooner.
        batch_size: samples (or pairs) per Adam step.
        learning_rate: Adam learning rate.
        kl_weight: weight of the KL term (paper: 10, low KL: 0.1).
        recon_weight: weight of the reconstruction term (paper: 1e-4).
        success_weight: weight of the success classifier's cross-entropy (paper: 0.1).
        pred_z_weight: weight of the next-latent prediction term (paper: 1.0).
        pred_im_weight: weight of the next-image prediction term (paper: 1e-4).
        smooth_weight: weight of ‖μ_{n+1} − μ_n‖ (paper: 500; 0.1 with low KL).
        ft_recon_scale: standardized force errors are multiplied by this before squaring, so
            one standard deviation of force counts like a full-scale pixel (255); the paper does
            not give the force/image balance. ``"balanced"``: chosen at fit time so that the
            two modalities weigh the same when each is off by one of its standard deviations
            per element: 255 · σ_image · √(pixels·3 / force axes), σ_image the images' mean
            per-channel standard deviation (in [0, 1] units); with 64 × 64 images ≈ 45 × that
            of a pixel per axis times σ_image (:meth:`MultimodalVAE.balanced_ft_scale`).
        patience: stop after this many epochs without a held-out improvement and keep the best
            epoch's weights (0: train all ``epochs``).
        validation_fraction: share of whole episodes held out for the held-out loss curve and
            early stopping (0: no held-out data).
        tol: relative held-out improvement that counts for ``patience``.
        seed: seeds initialization, the held-out split, batch order and the noise.
        device: ``"auto"`` (CUDA when present), ``"cpu"``, ``"cuda"``, ``"cuda:1"``, ...
        progress: show a progress bar with the loss terms while training.
    """

    family = "vae"

    LOSS_TERMS = LOSS_TERMS

    def __init__(self, latent_dim: int = 16, epochs: int = 20, batch_size: int = 64,
                 learning_rate: float = 1e-3, kl_weight: float = 10.0, recon_weight: float = 1e-4,
                 success_weight: float = 0.0, pred_z_weight: float = 0.0,
                 pred_im_weight: float = 0.0, smooth_weight: float = 0.0,
                 ft_recon_scale: float | str = 255.0, patience: int = 0,
                 validation_fraction: float = 0.0, tol: float = 1e-3, seed: int = 0,
                 device: str = "auto", progress: bool = True) -> None:
        self.latent_dim = latent_dim
        self.epochs = epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.kl_weight = kl_weight
        self.recon_weight = recon_weight
        self.success_weight = success_weight
        self.pred_z_weight = pred_z_weight
        self.pred_im_weight = pred_im_weight
        self.smooth_weight = smooth_weight
        self.ft_recon_scale = ft_recon_scale
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.tol = tol
        self.seed = seed
        self.device = device
        self.progress = progress

    # -- configuration -------------------------------------------------------------------------
    @property
    def temporal(self) -> bool:
        """Whether a loss term needs pairs (n, n+1)."""
        return self.pred_z_weight > 0 or self.pred_im_weight > 0 or self.smooth_weight > 0

    def check_params(self) -> None:
        super().check_params()
        name = type(self).__name__
        for w in ("kl_weight", "recon_weight", "success_weight", "pred_z_weight",
                  "pred_im_weight", "smooth_weight", "ft_recon_scale"):
            v = getattr(self, w)
            if w == "ft_recon_scale" and v == "balanced":
                continue
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                hint = ' or "balanced"' if w == "ft_recon_scale" else ""
                raise ConfigError(f"{name}: {w} must be a finite number >= 0{hint}, got {v!r}")

    def _prepare(self, dataset: Dataset) -> None:
        if self.ft_recon_scale == "balanced":
            self.ft_scale_ = self.balanced_ft_scale(self.stats_, self.spec_)

    def _ft_scale(self) -> float:
        """The force reconstruction scale in use (a number, or the one fixed at fit time)."""
        if self.ft_recon_scale == "balanced":
            return float(self.ft_scale_)
        return float(self.ft_recon_scale)

    @staticmethod
    def balanced_ft_scale(stats: Mapping[str, np.ndarray], spec: Mapping[str, Any]) -> float:
        """The force scale at which one standard deviation of error per element weighs the
        same in the image term (summed over its pixels) as in the force term (over its axes)."""
        pixels = int(spec["image_size"]) ** 2 * 3
        image_std = float(np.mean(stats["image_std"]))
        return 255.0 * image_std * math.sqrt(pixels / int(spec["ft_dim"]))

    def _spec_options(self) -> dict[str, Any]:
        return {"success_head": self.success_weight > 0, "pred_z_head": self.pred_z_weight > 0,
                "pred_im_head": self.pred_im_weight > 0}

    def _build_net(self, spec: NetworkSpec) -> MultimodalVAENet:
        net = MultimodalVAENet(spec)
        # start the image decoder at the mean colour (its last bias), not at black
        assert net.image_dec is not None
        with torch.no_grad():
            net.image_dec.deconv[-1].bias.copy_(
                torch.as_tensor(self.stats_["image_mean"], dtype=torch.float32))
        return net

    def _loss_terms(self, data: dict[str, torch.Tensor], idx: torch.Tensor,
                    idx_next: torch.Tensor | None, gen: torch.Generator, training: bool
                    ) -> dict[str, torch.Tensor]:
        """Unweighted loss terms and the weighted total ``loss`` for one batch.

        In evaluation (``training`` False) z = μ, deterministically; otherwise z is sampled.
        """
        net = self.net_
        rows = idx if idx_next is None else torch.cat([idx, idx_next])
        img_u8 = data["image"][rows]
        mu, log_std = self._encode_rows(data, rows)
        if not training:
            z = mu
        else:
            noise = torch.randn(mu.shape, generator=gen, device=mu.device, dtype=mu.dtype)
            z = mu + log_std.exp() * noise
        img_hat, ft_hat = net.decode(z, data["last_action"][rows])
        target = img_u8.permute(0, 3, 1, 2).float() / 255.0
        recon = (((img_hat - target) * 255.0) ** 2).flatten(1).sum(1) + (
            ((ft_hat - data["ft"][rows]) * self._ft_scale()) ** 2).sum(1)
        kl = gaussian_kl(mu, log_std, torch.zeros_like(mu), torch.zeros_like(log_std))
        zero = mu.new_zeros(())
        terms = {"recon": recon.mean(), "kl": kl.mean(), "success": zero, "pred_z": zero,
                 "pred_im": zero, "smooth": zero}
        if self.success_weight > 0:
            terms["success"] = F.cross_entropy(net.success_logits(z), data["success"][rows])
        if idx_next is not None:
            n = idx.shape[0]
            a_n = data["action"][idx]
            if self.pred_z_weight > 0:
                p_mu, p_log_std = net.predict_next_latent(z[:n], a_n)
                terms["pred_z"] = gaussian_kl(mu[n:], log_std[n:], p_mu, p_log_std).mean()
            if self.pred_im_weight > 0:
                im_next = net.predict_next_image(z[:n], a_n)
                terms["pred_im"] = (((im_next - target[n:]) * 255.0) ** 2).flatten(1).sum(1).mean()
            if self.smooth_weight > 0:
                terms["smooth"] = (((mu[n:] - mu[:n]) ** 2).sum(1) + 1e-12).sqrt().mean()
        terms["loss"] = (
            self.recon_weight * terms["recon"] + self.kl_weight * terms["kl"]
            + self.success_weight * terms["success"] + self.pred_z_weight * terms["pred_z"]
            + self.pred_im_weight * terms["pred_im"] + self.smooth_weight * terms["smooth"]
        )
        return terms

    def reconstruct(self, observations: Mapping[str, Any]) -> dict[str, np.ndarray]:
        """Decode μ_z ⊕ last_action: ``image`` uint8 [N, H, W, 3] and ``ft`` float32 [N, 6]."""
        x = self._obs_tensors(observations, (LAST_ACTION,))
        with torch.inference_mode():
            mu, _ = self._encode_obs(observations)
            img, ft = self.net_.decode(mu, x[LAST_ACTION])
        return {IMAGE: _to_uint8(img), FT: self._unstandardize_ft(ft)}

    def predict_next_image(self, observations: Mapping[str, Any], action: np.ndarray
                           ) -> np.ndarray:
        """Image at n+1 predicted from μ_z at n and the action at n (``pred_im`` variants)."""
        if self.net_.pred_im_fc is None:
            raise ConfigError(f"{type(self).__name__} has no next-image predictor "
                              "(pred_im_weight is 0)")
        c = self._constants()
        a = torch.as_tensor(np.asarray(action, np.float32), device=self._device)
        with torch.inference_mode():
            mu, _ = self._encode_obs(observations)
            img = self.net_.predict_next_image(mu, (a - c["action_mean"]) / c["action_std"])
        return _to_uint8(img)

    def save_reconstruction_figure(self, dataset: Dataset, path: str | os.PathLike[str],
                                   n: int = 8) -> Path:
        """The paper's appendix figure for this encoder (see :mod:`repbench_encoders.figures`);
        the runner calls it after fitting and shows the PNG on the leaderboard page."""
        from repbench_encoders.figures import save_reconstruction_figure

        return save_reconstruction_figure(self, dataset, path, n=n)

    def _unstandardize_ft(self, ft: torch.Tensor) -> np.ndarray:
        c = self._constants()
        return (ft * c["ft_std"] + c["ft_mean"]).cpu().numpy().astype(np.float32)

def _to_uint8(img: torch.Tensor) -> np.ndarray:
    return (img.clamp(0, 1) * 255).round().to(torch.uint8).permute(0, 2, 3, 1).cpu().numpy()


# -- the ten registered variants (defaults only; the paper's weights) ------------------------
# Each lists its parameters explicitly so that get_params() rebuilds it (scikit-learn style).


def _variant(name: str, doc: str, **defaults: Any) -> type[MultimodalVAE]:
    """A named :class:`MultimodalVAE` with other defaults (see :func:`make_variant`)."""
    return make_variant(MultimodalVAE, name, doc, module=__name__, **defaults)


# The paper's ten encoders (§IV and appendix): KL weight 10 ("standard") or 0.1 ("low KL").
VAE = _variant("VAE", "Multimodal VAE reconstructing image and force (KL weight 10).")
VAELowKL = _variant("VAELowKL", "Multimodal VAE with the low KL weight 0.1.", kl_weight=0.1)
SuccessVAE = _variant("SuccessVAE", "VAE plus a success classifier (weight 0.1); KL weight 10.",
                      success_weight=0.1)
SuccessVAELowKL = _variant("SuccessVAELowKL", "VAE plus a success classifier (weight 0.1); "
                           "KL weight 0.1.", kl_weight=0.1, success_weight=0.1)
PredZVAE = _variant("PredZVAE", "VAE plus a next-latent predictor (weight 1.0); KL weight 10.",
                    pred_z_weight=1.0)
PredZVAELowKL = _variant("PredZVAELowKL", "VAE plus a next-latent predictor (weight 1.0); "
                         "KL weight 0.1.", kl_weight=0.1, pred_z_weight=1.0)
PredImVAE = _variant("PredImVAE", "VAE plus next-image prediction from z_n and a_n "
                     "(weight 1e-4); KL weight 10.", pred_im_weight=1e-4)
PredImVAELowKL = _variant("PredImVAELowKL", "VAE plus next-image prediction (weight 1e-4); "
                          "KL weight 0.1.", kl_weight=0.1, pred_im_weight=1e-4)
SmoothVAE = _variant("SmoothVAE", "VAE plus the smoothness penalty ‖μ_{n+1} − μ_n‖ "
                     "(weight 500); KL weight 10.", smooth_weight=500.0)
SmoothVAELowKL = _variant("SmoothVAELowKL", "VAE plus the smoothness penalty with the paper's "
                          "low-KL weight 0.1; KL weight 0.1.", kl_weight=0.1, smooth_weight=0.1)

# Ablations beyond the paper (issue 12): the latent size, and which modalities the encoder reads.
# The per-modality encoders keep the objective (reconstruct image and force from z ⊕ torque), so
# only their input differs from ``vae_lowkl``.
VAELowKLD4 = _variant("VAELowKLD4", "``vae_lowkl`` with a 4-D latent.", kl_weight=0.1,
                      latent_dim=4)
VAELowKLD64 = _variant("VAELowKLD64", "``vae_lowkl`` with a 64-D latent.", kl_weight=0.1,
                       latent_dim=64)
ImageOnlyVAELowKL = _variant(
    "ImageOnlyVAELowKL", "``vae_lowkl`` whose encoder reads only the wrist image (it still "
    "reconstructs image and force).", kl_weight=0.1, required_modalities=(IMAGE,))
FtProprioVAELowKL = _variant(
    "FtProprioVAELowKL", "``vae_lowkl`` whose encoder reads force/torque and proprioception, "
    "not the image (it still reconstructs image and force).", kl_weight=0.1,
    required_modalities=(FT, PROPRIO))

# The encoder zoo (issue 43): the pixel loss outweighs force ~80:1 at the default scale (12288
# pixel errors against 6 force errors), so the force reading may be drowned; this one balances
# the two modalities.
VAELowKLBalanced = _variant(
    "VAELowKLBalanced", "``vae_lowkl`` with modality-balanced reconstruction: force/torque "
    "weighs as much as the image at equal per-element error in standard deviations.",
    kl_weight=0.1, ft_recon_scale="balanced")


class ForceHistoryVAE(MultimodalVAE):
    """A :class:`MultimodalVAE` whose force branch reads the last
    :data:`~repbench.dataset.HISTORY_STEPS` force/torque readings of the episode
    (``ft_history``) instead of the current one, and reconstructs them: one reading cannot tell
    a stiff surface from a soft one whose rest height differs, a few at different depths can.

    Agents' environments supply ``ft_history`` (:class:`repbench.rl.wrappers.ForceHistory`);
    :meth:`repbench.Dataset.obs` derives it from stored episodes.
    """

    def fit(self, dataset: Dataset) -> ForceHistoryVAE:
        """Train with each row's force input replaced by its ``ft_history``."""
        if FT not in dataset.observations:
            return super().fit(dataset)  # the base class names the missing modality
        history = stacked_history(dataset.observations[FT], dataset.episode,
                                  np.arange(len(dataset)), HISTORY_STEPS)
        widened = dataclasses.replace(
            dataset, observations={**dataset.observations, FT: history.astype(np.float32)})
        super().fit(widened)
        return self

    def _network_spec(self, dataset: Dataset) -> NetworkSpec:
        spec = super()._network_spec(dataset)
        reads = [m for m in (IMAGE, FT, PROPRIO)
                 if m in self.required_modalities or (m == FT and FT_HISTORY in
                                                      self.required_modalities)]
        return dataclasses.replace(spec, modalities=tuple(reads))

    def _encode_obs(self, observations: Mapping[str, Any]) -> tuple[torch.Tensor, torch.Tensor]:
        self.check_observations(observations)  # names ft_history if it is missing
        return super()._encode_obs({**observations, FT: observations[FT_HISTORY]})


VAELowKLFtHistory = make_variant(
    ForceHistoryVAE, "VAELowKLFtHistory", "``vae_lowkl`` whose force branch reads (and "
    "reconstructs) the last 4 force/torque readings of the episode.", module=__name__,
    kl_weight=0.1, required_modalities=(IMAGE, FT_HISTORY, PROPRIO))
