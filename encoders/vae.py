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

import inspect
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from tqdm.auto import tqdm

from repbench import devices
from repbench.dataset import FT, IMAGE, LAST_ACTION, PROPRIO, Dataset
from repbench.encoder import Encoder
from repbench.errors import ConfigError, DataError, TrainingDivergedError
from repbench_encoders.networks import MultimodalVAENet, NetworkSpec, feature_map_size

__all__ = [
    "VAE", "MultimodalVAE", "PredImVAE", "PredImVAELowKL", "PredZVAE", "PredZVAELowKL",
    "SmoothVAE", "SmoothVAELowKL", "SuccessVAE", "SuccessVAELowKL", "VAELowKL", "gaussian_kl",
]

LOSS_TERMS = ("recon", "kl", "success", "pred_z", "pred_im", "smooth")


def resolve_device(device: str) -> torch.device:
    """``"auto"`` → CUDA when present, else CPU; anything else as given (one rule for all:
    :func:`repbench.devices.resolve_device`)."""
    return torch.device(devices.resolve_device(device))


def gaussian_kl(mu_q: torch.Tensor, log_std_q: torch.Tensor, mu_p: torch.Tensor,
                log_std_p: torch.Tensor) -> torch.Tensor:
    """KL(N(μ_q, σ_q²) ‖ N(μ_p, σ_p²)) of diagonal Gaussians, summed over the last axis."""
    var_ratio = (2 * (log_std_q - log_std_p)).exp()
    mean_term = ((mu_q - mu_p) / log_std_p.exp()) ** 2
    return (0.5 * (var_ratio + mean_term - 1.0) - (log_std_q - log_std_p)).sum(-1)


class MultimodalVAE(Encoder):
    """The paper's multimodal VAE (image + force + proprioception), with optional auxiliary
    losses; ``encode`` returns μ_z.

    Args:
        latent_dim: size D of z (paper: 16).
        epochs: passes over the training samples (or pairs, for temporal variants).
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
            not give the force/image balance.
        seed: seeds initialization, batch order and the reparameterization noise.
        device: ``"auto"`` (CUDA when present), ``"cpu"``, ``"cuda"``, ``"cuda:1"``, ...
        progress: show a progress bar with the loss terms while training.
    """

    family = "vae"

    latent_dim: int = 16  # a hyperparameter here (shadows the base class's abstract property)

    def __init__(self, latent_dim: int = 16, epochs: int = 20, batch_size: int = 64,
                 learning_rate: float = 1e-3, kl_weight: float = 10.0, recon_weight: float = 1e-4,
                 success_weight: float = 0.0, pred_z_weight: float = 0.0,
                 pred_im_weight: float = 0.0, smooth_weight: float = 0.0,
                 ft_recon_scale: float = 255.0, seed: int = 0, device: str = "auto",
                 progress: bool = True) -> None:
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
        self.seed = seed
        self.device = device
        self.progress = progress

    # -- configuration -------------------------------------------------------------------------
    @property
    def temporal(self) -> bool:
        """Whether a loss term needs pairs (n, n+1)."""
        return self.pred_z_weight > 0 or self.pred_im_weight > 0 or self.smooth_weight > 0

    def check_params(self) -> None:
        """Raise ConfigError for an invalid hyperparameter (also called at plan time)."""
        name = type(self).__name__
        if not isinstance(self.latent_dim, (int, np.integer)) or self.latent_dim < 1:
            raise ConfigError(f"{name}: latent_dim must be a positive integer, "
                              f"got {self.latent_dim!r}")
        if not isinstance(self.epochs, (int, np.integer)) or self.epochs < 0:
            raise ConfigError(f"{name}: epochs must be an integer >= 0, got {self.epochs!r}")
        if not isinstance(self.batch_size, (int, np.integer)) or self.batch_size < 1:
            raise ConfigError(f"{name}: batch_size must be a positive integer, "
                              f"got {self.batch_size!r}")
        if not self.learning_rate > 0:
            raise ConfigError(f"{name}: learning_rate must be > 0, got {self.learning_rate!r}")
        for w in ("kl_weight", "recon_weight", "success_weight", "pred_z_weight",
                  "pred_im_weight", "smooth_weight", "ft_recon_scale"):
            v = getattr(self, w)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"{name}: {w} must be a finite number >= 0, got {v!r}")

    # -- fitting -------------------------------------------------------------------------------
    def fit(self, dataset: Dataset) -> MultimodalVAE:
        """Train on ``dataset`` (image, ft, proprio, last_action; action and success labels)."""
        self.check_params()
        name = type(self).__name__
        for m in (IMAGE, FT, PROPRIO, LAST_ACTION):
            if m not in dataset.observations:
                raise DataError(f"{name} needs the dataset modality {m!r}; the dataset has "
                                f"{dataset.modalities}")
        image = dataset.observations[IMAGE]
        if image.ndim != 4 or image.shape[1] != image.shape[2] or image.shape[3] != 3:
            raise DataError(f"{name}: dataset images must be [N, S, S, 3], got {image.shape}")
        spec = NetworkSpec(
            image_size=int(image.shape[1]), ft_dim=int(dataset.observations[FT].shape[1]),
            proprio_dim=int(dataset.observations[PROPRIO].shape[1]),
            action_dim=int(dataset.observations[LAST_ACTION].shape[1]),
            latent_dim=int(self.latent_dim), success_head=self.success_weight > 0,
            pred_z_head=self.pred_z_weight > 0, pred_im_head=self.pred_im_weight > 0,
        )
        if spec.image_size % 8 or spec.image_size < 32 or feature_map_size(spec) < 1:
            raise DataError(f"{name}: image size {spec.image_size} is not supported by the conv "
                            "stack; use square images whose side is a multiple of 8, >= 32")
        if dataset.action.shape[1] != spec.action_dim:
            raise DataError(f"{name}: dataset action has {dataset.action.shape[1]} dims but "
                            f"last_action has {spec.action_dim}")
        if self.temporal:
            rows, nxt = dataset.successor_index()
            if rows.size == 0:
                raise DataError(f"{name} needs pairs (n, n+1) from one episode; the dataset "
                                "has none (every episode has a single step)")
        else:
            rows, nxt = np.arange(len(dataset)), None

        device = resolve_device(self.device)
        self.spec_ = spec.to_dict()
        self.stats_ = _statistics(dataset)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(self.seed)
            net = MultimodalVAENet(spec)
            # start the image decoder at the mean colour (its last bias), not at black
            last = net.image_dec.deconv[-1]
            with torch.no_grad():
                last.bias.copy_(torch.as_tensor(self.stats_["image_mean"], dtype=torch.float32))
        # channels_last: the image arrives NHWC, so convolutions skip a layout copy (1.3x faster
        # encode at batch 1 on CPU, bit-identical output)
        self.net_ = net.to(device, memory_format=torch.channels_last)
        self._device = device
        self._cache: dict[str, torch.Tensor] = {}
        self.history_: list[dict[str, float]] = []
        data = self._dataset_tensors(dataset)

        opt = torch.optim.Adam(net.parameters(), lr=self.learning_rate)
        gen = torch.Generator(device=device)
        gen.manual_seed(self.seed)
        rng = np.random.default_rng(self.seed)
        net.train()
        bar = tqdm(range(self.epochs), desc=name, unit="epoch", disable=not self.progress,
                   leave=False)
        for epoch in bar:
            perm = rng.permutation(rows.size)
            sums = dict.fromkeys(("loss", *LOSS_TERMS), 0.0)
            for start in range(0, perm.size, self.batch_size):
                b = perm[start:start + self.batch_size]
                b_next = None if nxt is None else torch.as_tensor(nxt[b], device=device)
                terms = self._loss_terms(data, torch.as_tensor(rows[b], device=device), b_next,
                                         gen)
                loss = terms["loss"]
                if not torch.isfinite(loss):
                    raise TrainingDivergedError(
                        f"{name} training diverged at epoch {epoch + 1}/{self.epochs}: loss is "
                        f"{loss.item()} ({_fmt(terms)}); lower learning_rate "
                        f"(now {self.learning_rate:g}) or check the dataset for NaN/huge values"
                    )
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                for k in sums:
                    sums[k] += float(terms[k].detach()) * b.size
            epoch_terms = {k: v / perm.size for k, v in sums.items()}
            if not all(torch.isfinite(p).all() for p in net.parameters()):
                raise TrainingDivergedError(
                    f"{name} training diverged at epoch {epoch + 1}/{self.epochs}: weights became "
                    f"NaN/inf; lower learning_rate (now {self.learning_rate:g})"
                )
            self.history_.append(epoch_terms)
            bar.set_postfix({k: f"{v:.3g}" for k, v in epoch_terms.items() if v})
        bar.close()
        net.eval()
        return self

    def _dataset_tensors(self, dataset: Dataset) -> dict[str, torch.Tensor]:
        """The whole dataset on the device once (images stay uint8)."""
        dev, st = self._device, self.stats_
        obs = dataset.observations

        def std(x: np.ndarray, key: str) -> torch.Tensor:
            return torch.as_tensor((x - st[f"{key}_mean"]) / st[f"{key}_std"],
                                   dtype=torch.float32, device=dev)

        return {
            "image": torch.as_tensor(obs[IMAGE], device=dev),
            "ft": std(obs[FT], "ft"),
            "proprio": std(obs[PROPRIO], "proprio"),
            "last_action": std(obs[LAST_ACTION], "action"),
            "action": std(dataset.action, "action"),
            "success": torch.as_tensor(dataset.success.astype(np.int64), device=dev),
        }

    def _loss_terms(self, data: dict[str, torch.Tensor], idx: torch.Tensor,
                    idx_next: torch.Tensor | None, gen: torch.Generator | None
                    ) -> dict[str, torch.Tensor]:
        """Unweighted loss terms and the weighted total ``loss`` for one batch.

        With ``gen`` None, z = μ (deterministic evaluation); otherwise z is sampled.
        """
        net = self.net_
        rows = idx if idx_next is None else torch.cat([idx, idx_next])
        img_u8 = data["image"][rows]
        x = self._image_input(img_u8)
        mu, log_std = net.encode(x, data["ft"][rows], data["proprio"][rows])
        if gen is None:
            z = mu
        else:
            noise = torch.randn(mu.shape, generator=gen, device=mu.device, dtype=mu.dtype)
            z = mu + log_std.exp() * noise
        img_hat, ft_hat = net.decode(z, data["last_action"][rows])
        target = img_u8.permute(0, 3, 1, 2).float() / 255.0
        recon = (((img_hat - target) * 255.0) ** 2).flatten(1).sum(1) + (
            ((ft_hat - data["ft"][rows]) * self.ft_recon_scale) ** 2).sum(1)
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

    def loss_terms(self, dataset: Dataset, batch_size: int = 256) -> dict[str, float]:
        """Mean loss terms on ``dataset`` with z = μ (no sampling), in eval mode."""
        self.check_is_fitted()
        data = self._dataset_tensors(dataset)
        if self.temporal:
            rows, nxt = dataset.successor_index()
        else:
            rows, nxt = np.arange(len(dataset)), None
        sums = dict.fromkeys(("loss", *LOSS_TERMS), 0.0)
        self.net_.eval()
        with torch.inference_mode():
            for s in range(0, rows.size, batch_size):
                b = rows[s:s + batch_size]
                b_next = None if nxt is None else torch.as_tensor(nxt[s:s + batch_size],
                                                                  device=self._device)
                terms = self._loss_terms(data, torch.as_tensor(b, device=self._device), b_next,
                                         None)
                for k in sums:
                    sums[k] += float(terms[k]) * b.size
        return {k: v / max(rows.size, 1) for k, v in sums.items()}

    # -- encoding ------------------------------------------------------------------------------
    def _constants(self) -> dict[str, torch.Tensor]:
        """Normalization constants as device tensors, built once per fitted state."""
        if not self._cache:
            dev, st = self._device, self.stats_

            def t(x: np.ndarray) -> torch.Tensor:
                return torch.as_tensor(np.asarray(x, np.float32), device=dev)

            self._cache = {
                # image: uint8 * scale + shift == (x / 255 - mean) / std, per channel
                "img_scale": t(1.0 / (255.0 * st["image_std"])).view(1, 3, 1, 1),
                "img_shift": t(-st["image_mean"] / st["image_std"]).view(1, 3, 1, 1),
                "ft_mean": t(st["ft_mean"]), "ft_std": t(st["ft_std"]),
                "proprio_mean": t(st["proprio_mean"]), "proprio_std": t(st["proprio_std"]),
                "action_mean": t(st["action_mean"]), "action_std": t(st["action_std"]),
            }
        return self._cache

    def _image_input(self, img_u8: torch.Tensor) -> torch.Tensor:
        c = self._constants()
        return img_u8.permute(0, 3, 1, 2).float() * c["img_scale"] + c["img_shift"]

    def _obs_tensors(self, observations: Mapping[str, Any], modalities: tuple[str, ...]
                     ) -> dict[str, torch.Tensor]:
        self.check_is_fitted()
        name = type(self).__name__
        batch = self.check_observations(observations)
        if LAST_ACTION in modalities and LAST_ACTION not in observations:
            raise DataError(f"{name} needs the modality 'last_action' (the decoder's torque "
                            f"input); the batch has {sorted(observations)}")
        spec = self.spec_
        s = spec["image_size"]
        expect = {IMAGE: (s, s, 3), FT: (spec["ft_dim"],), PROPRIO: (spec["proprio_dim"],),
                  LAST_ACTION: (spec["action_dim"],)}
        c = self._constants()
        dev = self._device
        out: dict[str, torch.Tensor] = {}
        for m in modalities:
            arr = np.asarray(observations[m]) if m not in batch else batch[m]
            if arr.ndim == 0 or arr.shape[0] != batch[IMAGE].shape[0]:
                raise DataError(f"{name}: modality {m!r} has {arr.shape[:1]} rows but 'image' "
                                f"has {batch[IMAGE].shape[0]}; every modality needs one row "
                                "per observation")
            if arr.shape[1:] != expect[m]:
                raise DataError(f"{name}: modality {m!r} must have shape [N, "
                                f"{', '.join(map(str, expect[m]))}] as at fit time, got "
                                f"{list(arr.shape)}")
            if m == IMAGE:
                if arr.dtype != np.uint8:
                    raise DataError(f"{name}: images must be uint8, got {arr.dtype}")
                out[m] = self._image_input(torch.from_numpy(np.ascontiguousarray(arr)).to(dev))
            else:
                key = "action" if m == LAST_ACTION else m
                x = torch.from_numpy(np.ascontiguousarray(arr, dtype=np.float32)).to(dev)
                out[m] = (x - c[f"{key}_mean"]) / c[f"{key}_std"]
        return out

    def encode(self, observations: Mapping[str, Any]) -> np.ndarray:
        """μ_z of an observation batch (image, ft, proprio) as float32 [N, latent_dim]."""
        x = self._obs_tensors(observations, (IMAGE, FT, PROPRIO))
        with torch.inference_mode():
            mu, _ = self.net_.encode(x[IMAGE], x[FT], x[PROPRIO])
        return mu.cpu().numpy()

    def reconstruct(self, observations: Mapping[str, Any]) -> dict[str, np.ndarray]:
        """Decode μ_z ⊕ last_action: ``image`` uint8 [N, H, W, 3] and ``ft`` float32 [N, 6]."""
        x = self._obs_tensors(observations, (IMAGE, FT, PROPRIO, LAST_ACTION))
        with torch.inference_mode():
            mu, _ = self.net_.encode(x[IMAGE], x[FT], x[PROPRIO])
            img, ft = self.net_.decode(mu, x[LAST_ACTION])
        return {IMAGE: _to_uint8(img), FT: self._unstandardize_ft(ft)}

    def predict_next_image(self, observations: Mapping[str, Any], action: np.ndarray
                           ) -> np.ndarray:
        """Image at n+1 predicted from μ_z at n and the action at n (``pred_im`` variants)."""
        if self.net_.pred_im_fc is None:
            raise ConfigError(f"{type(self).__name__} has no next-image predictor "
                              "(pred_im_weight is 0)")
        x = self._obs_tensors(observations, (IMAGE, FT, PROPRIO))
        c = self._constants()
        a = torch.as_tensor(np.asarray(action, np.float32), device=self._device)
        with torch.inference_mode():
            mu, _ = self.net_.encode(x[IMAGE], x[FT], x[PROPRIO])
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

    # -- state ---------------------------------------------------------------------------------
    def get_state(self) -> dict[str, Any]:
        self.check_is_fitted()
        return {
            "spec_": dict(self.spec_),
            "stats_": dict(self.stats_),
            "history_": [dict(h) for h in self.history_],
            "weights_": {k: v.detach().cpu().clone() for k, v in self.net_.state_dict().items()},
        }

    def set_state(self, state: dict[str, Any]) -> None:
        spec = NetworkSpec.from_dict(state["spec_"])
        net = MultimodalVAENet(spec)
        net.load_state_dict(state["weights_"])
        self._device = resolve_device(self.device)
        self.net_ = net.to(self._device, memory_format=torch.channels_last).eval()
        self.spec_ = spec.to_dict()
        self.stats_ = {k: np.asarray(v) for k, v in state["stats_"].items()}
        self.history_ = [dict(h) for h in state["history_"]]
        self._cache = {}

    def __getstate__(self) -> dict[str, Any]:
        # pickling (e.g. to a worker process) drops the device tensor cache
        d = dict(self.__dict__)
        d.pop("_cache", None)
        return d

    def __setstate__(self, d: dict[str, Any]) -> None:
        self.__dict__.update(d)
        self._cache = {}


def _statistics(dataset: Dataset) -> dict[str, np.ndarray]:
    """Input normalization statistics (float64 arrays; std of a constant input → 1)."""
    obs = dataset.observations

    def safe_std(x: np.ndarray, axis: Any) -> np.ndarray:
        s = x.std(axis=axis)
        return np.where(s > 1e-8, s, 1.0)

    img = obs[IMAGE]
    # per-channel image statistics from a strided subset (exact enough, cheap on big datasets)
    sub = img[:: max(1, len(img) // 512)].astype(np.float64) / 255.0
    actions = np.concatenate([dataset.action, obs[LAST_ACTION]]).astype(np.float64)
    ft = obs[FT].astype(np.float64)
    proprio = obs[PROPRIO].astype(np.float64)
    return {
        "image_mean": sub.mean(axis=(0, 1, 2)), "image_std": safe_std(sub, (0, 1, 2)),
        "ft_mean": ft.mean(0), "ft_std": safe_std(ft, 0),
        "proprio_mean": proprio.mean(0), "proprio_std": safe_std(proprio, 0),
        "action_mean": actions.mean(0), "action_std": safe_std(actions, 0),
    }


def _to_uint8(img: torch.Tensor) -> np.ndarray:
    return (img.clamp(0, 1) * 255).round().to(torch.uint8).permute(0, 2, 3, 1).cpu().numpy()


def _fmt(terms: Mapping[str, torch.Tensor]) -> str:
    return ", ".join(f"{k}={float(v.detach()):.3g}" for k, v in terms.items() if k != "loss")


# -- the ten registered variants (defaults only; the paper's weights) ------------------------
# Each lists its parameters explicitly so that get_params() rebuilds it (scikit-learn style).


def _variant(name: str, doc: str, **defaults: float) -> type[MultimodalVAE]:
    """A named :class:`MultimodalVAE` whose defaults are the paper's weights for one variant.

    The generated ``__init__`` carries ``MultimodalVAE``'s full signature with these defaults,
    so ``get_params()`` sees every hyperparameter and ``type(e)(**e.get_params())`` rebuilds it.
    """
    base = inspect.signature(MultimodalVAE.__init__)
    unknown = set(defaults) - set(base.parameters)
    if unknown:
        raise TypeError(f"{name}: MultimodalVAE has no parameters {sorted(unknown)}")
    signature = base.replace(parameters=[p.replace(default=defaults.get(p.name, p.default))
                                         for p in base.parameters.values()])

    def __init__(self: MultimodalVAE, *args: Any, **kwargs: Any) -> None:
        bound = signature.bind(self, *args, **kwargs)
        bound.apply_defaults()
        params = dict(bound.arguments)
        del params["self"]
        MultimodalVAE.__init__(self, **params)

    __init__.__signature__ = signature  # type: ignore[attr-defined]
    return type(name, (MultimodalVAE,), {"__init__": __init__, "__doc__": doc,
                                          "__module__": __name__, "__qualname__": name})


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
