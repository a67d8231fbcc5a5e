"""The shared base of the trained encoders: the paper's multimodal trunk, input normalization,
encoding, files, and one training loop with early stopping on held-out episodes.

Subclasses (the VAE family in :mod:`~repbench_encoders.vae`, the contrastive encoders in
:mod:`~repbench_encoders.contrastive`, the supervised encoder in
:mod:`~repbench_encoders.supervised`) differ only in their objective: they build their network
around :class:`~repbench_encoders.networks.MultimodalVAENet`'s encoder and implement
:meth:`TrunkEncoder._loss_terms`. So a comparison between them is about the objective, not the
inputs or the architecture. ``encode`` always returns the trunk's μ_z.
"""

from __future__ import annotations

import copy
import inspect
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import torch
from torch import nn
from tqdm.auto import tqdm

from repbench import devices
from repbench.dataset import FT, IMAGE, LAST_ACTION, PROPRIO, Dataset
from repbench.encoder import Encoder
from repbench.errors import ConfigError, DataError, TrainingDivergedError
from repbench_encoders.networks import NetworkSpec, feature_map_size
from repbench_encoders.training import EarlyStopping

__all__ = ["TrunkEncoder", "make_variant", "resolve_device"]

_EVAL_BATCH = 256


def resolve_device(device: str) -> torch.device:
    """``"auto"`` → CUDA when present, else CPU; anything else as given (one rule for all:
    :func:`repbench.devices.resolve_device`)."""
    return torch.device(devices.resolve_device(device))


class TrunkEncoder(Encoder):
    """Base class: the multimodal trunk, trained by a subclass's objective with early stopping.

    Subclasses store (at least) these constructor arguments: ``latent_dim``, ``epochs`` (the
    maximum number of passes), ``batch_size``, ``learning_rate``, ``patience``,
    ``validation_fraction``, ``tol``, ``seed``, ``device``, ``progress``; and implement
    :meth:`_build_net` and :meth:`_loss_terms`. See :mod:`repbench_encoders.training` for the
    early-stopping rule and the history format.
    """

    #: Loss terms reported per epoch (besides the weighted total ``loss``).
    LOSS_TERMS: ClassVar[tuple[str, ...]] = ()
    #: Modalities the dataset must have for ``fit`` (the inputs plus what the objective needs).
    fit_modalities: ClassVar[tuple[str, ...]] = (IMAGE, FT, PROPRIO, LAST_ACTION)

    latent_dim: int = 16  # a hyperparameter here (shadows the base class's abstract property)
    epochs: int
    batch_size: int
    learning_rate: float
    patience: int
    validation_fraction: float
    tol: float
    seed: int
    device: str
    progress: bool

    # -- to implement --------------------------------------------------------------------------
    def _build_net(self, spec: NetworkSpec) -> nn.Module:
        """The network; it must have ``encode(image, ft, proprio) -> (μ, log σ)``."""
        raise NotImplementedError

    def _loss_terms(self, data: dict[str, torch.Tensor], idx: torch.Tensor,
                    idx_next: torch.Tensor | None, gen: torch.Generator, training: bool
                    ) -> dict[str, torch.Tensor]:
        """Unweighted terms of :attr:`LOSS_TERMS` and the weighted total ``loss`` of a batch.

        ``idx_next`` holds each row's successor (same episode) when :attr:`temporal`.
        ``training`` False means evaluation: deterministic where the objective allows it
        (z = μ); ``gen`` then is seeded identically at every evaluation.
        """
        raise NotImplementedError

    @property
    def temporal(self) -> bool:
        """Whether the objective trains on pairs (n, n+1) of one episode."""
        return False

    def _spec_options(self) -> dict[str, Any]:
        """Extra :class:`NetworkSpec` fields (heads, decoder) for this encoder."""
        return {}

    def _extra_tensors(self, dataset: Dataset) -> dict[str, torch.Tensor]:
        """Further per-row training tensors (e.g. a regression target)."""
        return {}

    def _prepare(self, dataset: Dataset) -> None:
        """Learn what the network's shape depends on (called before :meth:`_build_net`)."""

    def _after_step(self) -> None:
        """Called after every optimizer step (e.g. a momentum target network's update)."""

    def _pairs(self, dataset: Dataset) -> tuple[np.ndarray, np.ndarray | None]:
        """Training rows and, for :attr:`temporal` objectives, each row's partner."""
        if not self.temporal:
            return np.arange(len(dataset)), None
        rows, nxt = dataset.successor_index()
        if rows.size == 0:
            raise DataError(f"{type(self).__name__} needs pairs (n, n+1) from one episode; "
                            "the dataset has none (every episode has a single step)")
        return rows, nxt

    def _eval_batch_size(self) -> int:
        """Batch size of held-out evaluation (objectives over a batch use the training one)."""
        return _EVAL_BATCH

    # -- parameters ----------------------------------------------------------------------------
    def check_params(self) -> None:
        name = type(self).__name__

        def integer(key: str, low: int) -> None:
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                what = "a positive integer" if low == 1 else f"an integer >= {low}"
                raise ConfigError(f"{name}: {key} must be {what}, got {v!r}")

        integer("latent_dim", 1)
        integer("epochs", 0)
        integer("batch_size", 1)
        integer("patience", 0)
        lr = self.learning_rate
        if isinstance(lr, bool) or not (isinstance(lr, (int, float)) and math.isfinite(lr)
                                        and lr > 0):
            raise ConfigError(f"{name}: learning_rate must be a finite number > 0, got {lr!r}")
        vf = self.validation_fraction
        if not (isinstance(vf, (int, float)) and 0.0 <= vf < 1.0):
            raise ConfigError(f"{name}: validation_fraction must be in [0, 1), got {vf!r}")
        if not (isinstance(self.tol, (int, float)) and math.isfinite(self.tol) and self.tol >= 0):
            raise ConfigError(f"{name}: tol must be a finite number >= 0, got {self.tol!r}")
        if self.patience > 0 and vf == 0:
            raise ConfigError(f"{name}: early stopping (patience={self.patience}) needs held-out "
                              "episodes; set validation_fraction > 0 (e.g. 0.2) or patience=0")

    def _network_spec(self, dataset: Dataset) -> NetworkSpec:
        name = type(self).__name__
        for m in self.fit_modalities:
            if m not in dataset.observations:
                raise DataError(f"{name} needs the dataset modality {m!r}; the dataset has "
                                f"{dataset.modalities}")
        obs = dataset.observations
        image = obs.get(IMAGE)
        size = 64
        if image is not None:
            if image.ndim != 4 or image.shape[1] != image.shape[2] or image.shape[3] != 3:
                raise DataError(f"{name}: dataset images must be [N, S, S, 3], got {image.shape}")
            size = int(image.shape[1])
        spec = NetworkSpec(
            image_size=size, ft_dim=int(obs[FT].shape[1]), proprio_dim=int(obs[PROPRIO].shape[1]),
            action_dim=int(dataset.action.shape[1]), latent_dim=int(self.latent_dim),
            modalities=tuple(m for m in (IMAGE, FT, PROPRIO) if m in self.required_modalities),
            **self._spec_options(),
        )
        if spec.image_size % 8 or spec.image_size < 32 or feature_map_size(spec) < 1:
            raise DataError(f"{name}: image size {spec.image_size} is not supported by the conv "
                            "stack; use square images whose side is a multiple of 8, >= 32")
        if LAST_ACTION in obs and obs[LAST_ACTION].shape[1] != spec.action_dim:
            raise DataError(f"{name}: dataset action has {spec.action_dim} dims but "
                            f"last_action has {obs[LAST_ACTION].shape[1]}")
        return spec

    # -- fitting -------------------------------------------------------------------------------
    def fit(self, dataset: Dataset) -> TrunkEncoder:
        """Train on ``dataset``: at most ``epochs`` passes, early stopping on held-out episodes
        when ``patience > 0``; the weights of the best held-out epoch are kept. A fit that
        fails (or is interrupted) leaves the encoder unfitted, not half-fitted."""
        self.check_params()
        try:
            return self._fit(dataset)
        except BaseException:
            for key in [k for k in vars(self) if k.endswith("_") and not k.startswith("_")]:
                delattr(self, key)
            raise

    def _fit(self, dataset: Dataset) -> TrunkEncoder:
        name = type(self).__name__
        spec = self._network_spec(dataset)
        rows, nxt = self._pairs(dataset)
        held = np.zeros(rows.size, bool)
        if self.validation_fraction > 0:
            if dataset.n_episodes < 2:
                raise DataError(f"{name}: holding out {self.validation_fraction:g} of the "
                                f"episodes needs at least 2 episodes, the dataset has "
                                f"{dataset.n_episodes}; set validation_fraction=0")
            _, test = dataset.episode_split(self.validation_fraction, self.seed)
            held = np.isin(rows, test)

        device = resolve_device(self.device)
        self.spec_ = spec.to_dict()
        self.stats_ = _statistics(dataset)
        self._device = device
        self._cache: dict[str, torch.Tensor] = {}
        self._prepare(dataset)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(self.seed)
            net = self._build_net(spec)
        # channels_last: the image arrives NHWC, so convolutions skip a layout copy (1.3x faster
        # encode at batch 1 on CPU, bit-identical output)
        self.net_ = net.to(device, memory_format=torch.channels_last)
        data = {**self._dataset_tensors(dataset), **self._extra_tensors(dataset)}
        self.history_: list[dict[str, Any]] = []
        with devices.exact_cuda(device):  # seeded GPU training: the same weights every run
            self._train(data, rows[~held], None if nxt is None else nxt[~held],
                        rows[held], None if nxt is None else nxt[held])
        return self

    def _train(self, data: dict[str, torch.Tensor], rows: np.ndarray, nxt: np.ndarray | None,
               val_rows: np.ndarray, val_nxt: np.ndarray | None) -> None:
        name, net, device = type(self).__name__, self.net_, self._device
        opt = torch.optim.Adam(net.parameters(), lr=self.learning_rate)
        gen = torch.Generator(device=device)
        gen.manual_seed(self.seed)
        rng = np.random.default_rng(self.seed)
        stopper = EarlyStopping(self.patience, self.tol)
        best_weights: dict[str, torch.Tensor] | None = None
        keys = ("loss", *self.LOSS_TERMS)
        bar = tqdm(range(1, self.epochs + 1), desc=name, unit="epoch",
                   disable=not self.progress, leave=False)
        for epoch in bar:
            net.train()
            perm = rng.permutation(rows.size)
            sums = dict.fromkeys(keys, 0.0)
            for start in range(0, perm.size, self.batch_size):
                b = perm[start:start + self.batch_size]
                b_next = None if nxt is None else torch.as_tensor(nxt[b], device=device)
                terms = self._loss_terms(data, torch.as_tensor(rows[b], device=device), b_next,
                                         gen, True)
                loss = terms["loss"]
                if not torch.isfinite(loss):
                    raise TrainingDivergedError(
                        f"{name} training diverged at epoch {epoch}/{self.epochs}: loss is "
                        f"{loss.item()} ({_fmt(terms)}); lower learning_rate "
                        f"(now {self.learning_rate:g}) or check the dataset for NaN/huge values"
                    )
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                self._after_step()
                for k in keys:
                    sums[k] += float(terms[k].detach()) * b.size
            if not all(torch.isfinite(p).all() for p in net.parameters()):
                raise TrainingDivergedError(
                    f"{name} training diverged at epoch {epoch}/{self.epochs}: weights became "
                    f"NaN/inf; lower learning_rate (now {self.learning_rate:g})"
                )
            record: dict[str, Any] = {"epoch": epoch,
                                      "train": {k: v / max(perm.size, 1) for k, v in sums.items()},
                                      "heldout": {}}
            stop = False
            if val_rows.size:
                record["heldout"] = self._evaluate(data, val_rows, val_nxt)
                stop = stopper.update(epoch, record["heldout"]["loss"])
                if stopper.improved and self.patience > 0:
                    best_weights = copy.deepcopy(net.state_dict())
            self.history_.append(record)
            bar.set_postfix({k: f"{v:.3g}" for k, v in record["train"].items() if v})
            if stop:
                break
        bar.close()
        if best_weights is not None:
            net.load_state_dict(best_weights)
        self.best_epoch_ = int(stopper.best_epoch if best_weights is not None
                               else len(self.history_))
        net.eval()

    def _evaluate(self, data: dict[str, torch.Tensor], rows: np.ndarray,
                  nxt: np.ndarray | None) -> dict[str, float]:
        """Mean loss terms over ``rows`` in evaluation mode (fixed seed and batch order, no
        gradients)."""
        gen = torch.Generator(device=self._device)
        gen.manual_seed(self.seed + 1)
        order = np.random.default_rng(self.seed + 1).permutation(rows.size)
        rows = rows[order]
        nxt = None if nxt is None else nxt[order]
        keys = ("loss", *self.LOSS_TERMS)
        sums = dict.fromkeys(keys, 0.0)
        size = self._eval_batch_size()
        self.net_.eval()
        with torch.inference_mode():
            for s in range(0, rows.size, size):
                b = rows[s:s + size]
                b_next = None if nxt is None else torch.as_tensor(nxt[s:s + size],
                                                                  device=self._device)
                terms = self._loss_terms(data, torch.as_tensor(b, device=self._device), b_next,
                                         gen, False)
                for k in keys:
                    sums[k] += float(terms[k]) * b.size
        return {k: v / max(rows.size, 1) for k, v in sums.items()}

    def loss_terms(self, dataset: Dataset) -> dict[str, float]:
        """Mean loss terms on ``dataset`` in evaluation mode (z = μ where the objective samples;
        for the VAE family the same quantity as the held-out curve of :attr:`history_`)."""
        self.check_is_fitted()
        data = {**self._dataset_tensors(dataset), **self._extra_tensors(dataset)}
        rows, nxt = self._pairs(dataset)
        with devices.exact_cuda(self._device):
            return self._evaluate(data, rows, nxt)

    def _dataset_tensors(self, dataset: Dataset) -> dict[str, torch.Tensor]:
        """The whole dataset on the device once (images stay uint8)."""
        dev, st = self._device, self.stats_
        obs = dataset.observations

        def std(x: np.ndarray, key: str) -> torch.Tensor:
            return torch.as_tensor((x - st[f"{key}_mean"]) / st[f"{key}_std"],
                                   dtype=torch.float32, device=dev)

        out = {
            "ft": std(obs[FT], "ft"),
            "proprio": std(obs[PROPRIO], "proprio"),
            "action": std(dataset.action, "action"),
            "success": torch.as_tensor(dataset.success.astype(np.int64), device=dev),
        }
        if IMAGE in obs:
            out["image"] = torch.as_tensor(obs[IMAGE], device=dev)
        if LAST_ACTION in obs:
            out["last_action"] = std(obs[LAST_ACTION], "action")
        return out

    def _encode_rows(self, data: dict[str, torch.Tensor], rows: torch.Tensor,
                     image: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """(μ, log σ) of dataset rows; ``image`` (normalized) replaces the stored image."""
        net = self.net_
        reads = self.spec_["modalities"]
        if image is None and IMAGE in reads:
            image = self._image_input(data["image"][rows])
        return net.encode(image if IMAGE in reads else None,
                          data["ft"][rows] if FT in reads else None,
                          data["proprio"][rows] if PROPRIO in reads else None)

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
        for m in modalities:
            if m not in batch and m not in observations:
                raise DataError(f"{name} needs the modality {m!r}; the batch has "
                                f"{sorted(observations)}")
        spec = self.spec_
        s = spec["image_size"]
        expect = {IMAGE: (s, s, 3), FT: (spec["ft_dim"],), PROPRIO: (spec["proprio_dim"],),
                  LAST_ACTION: (spec["action_dim"],)}
        first = self.required_modalities[0]
        n = batch[first].shape[0]
        c = self._constants()
        dev = self._device
        out: dict[str, torch.Tensor] = {}
        for m in modalities:
            arr = batch[m] if m in batch else np.asarray(observations[m])
            if arr.ndim == 0 or arr.shape[0] != n:
                raise DataError(f"{name}: modality {m!r} has {arr.shape[:1]} rows but "
                                f"{first!r} has {n}; every modality needs one row per "
                                "observation")
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

    def _encode_obs(self, observations: Mapping[str, Any]) -> tuple[torch.Tensor, torch.Tensor]:
        self.check_is_fitted()
        x = self._obs_tensors(observations, tuple(self.spec_["modalities"]))
        return self.net_.encode(x.get(IMAGE), x.get(FT), x.get(PROPRIO))

    def encode(self, observations: Mapping[str, Any]) -> np.ndarray:
        """μ_z of an observation batch as float32 [N, latent_dim] (reads only
        :attr:`required_modalities`)."""
        self.check_is_fitted()
        with torch.inference_mode(), devices.exact_cuda(self._device):
            mu, _ = self._encode_obs(observations)
        return mu.cpu().numpy()

    # -- state ---------------------------------------------------------------------------------
    def get_state(self) -> dict[str, Any]:
        self.check_is_fitted()
        state = {k: copy.deepcopy(v) for k, v in vars(self).items()
                 if k.endswith("_") and not k.startswith("_") and k != "net_"}
        state["weights_"] = {k: v.detach().cpu().clone()
                             for k, v in self.net_.state_dict().items()}
        return state

    def set_state(self, state: dict[str, Any]) -> None:
        state = dict(state)
        weights = state.pop("weights_")
        for key, value in state.items():
            setattr(self, key, value)
        self.stats_ = {k: np.asarray(v) for k, v in state["stats_"].items()}
        self.history_ = [dict(h) for h in state.get("history_", [])]
        self.best_epoch_ = int(state.get("best_epoch_", len(self.history_)))
        spec = NetworkSpec.from_dict(state["spec_"])
        self.spec_ = spec.to_dict()
        net = self._build_net(spec)
        net.load_state_dict(weights)
        self._device = resolve_device(self.device)
        self._cache = {}
        self.net_ = net.to(self._device, memory_format=torch.channels_last).eval()

    def __getstate__(self) -> dict[str, Any]:
        # pickling (e.g. to a worker process) drops the device tensor cache
        d = dict(self.__dict__)
        d.pop("_cache", None)
        return d

    def __setstate__(self, d: dict[str, Any]) -> None:
        self.__dict__.update(d)
        self._cache = {}


def make_variant(base: type[TrunkEncoder], name: str, doc: str, *, module: str,
                 required_modalities: tuple[str, ...] | None = None,
                 **defaults: Any) -> type[TrunkEncoder]:
    """A named subclass of ``base`` with other constructor defaults (and, optionally, other
    input modalities).

    The generated ``__init__`` carries ``base``'s full signature with these defaults, so
    ``get_params()`` sees every hyperparameter and ``type(e)(**e.get_params())`` rebuilds it.
    """
    sig = inspect.signature(base.__init__)
    unknown = set(defaults) - set(sig.parameters)
    if unknown:
        raise TypeError(f"{name}: {base.__name__} has no parameters {sorted(unknown)}")
    signature = sig.replace(parameters=[p.replace(default=defaults.get(p.name, p.default))
                                        for p in sig.parameters.values()])

    def __init__(self: TrunkEncoder, *args: Any, **kwargs: Any) -> None:
        bound = signature.bind(self, *args, **kwargs)
        bound.apply_defaults()
        params = dict(bound.arguments)
        del params["self"]
        base.__init__(self, **params)

    __init__.__signature__ = signature  # type: ignore[attr-defined]
    attrs: dict[str, Any] = {"__init__": __init__, "__doc__": doc, "__module__": module,
                             "__qualname__": name}
    if required_modalities is not None:
        attrs["required_modalities"] = tuple(required_modalities)
    return type(name, (base,), attrs)


def _statistics(dataset: Dataset) -> dict[str, np.ndarray]:
    """Input normalization statistics (float64 arrays; std of a constant input → 1)."""
    obs = dataset.observations

    def safe_std(x: np.ndarray, axis: Any) -> np.ndarray:
        s = x.std(axis=axis)
        return np.where(s > 1e-8, s, 1.0)

    out: dict[str, np.ndarray] = {"image_mean": np.full(3, 0.5), "image_std": np.ones(3)}
    if IMAGE in obs:
        img = obs[IMAGE]
        # per-channel image statistics from a strided subset (exact enough, cheap on big data)
        sub = img[:: max(1, len(img) // 512)].astype(np.float64) / 255.0
        out = {"image_mean": sub.mean(axis=(0, 1, 2)), "image_std": safe_std(sub, (0, 1, 2))}
    parts = [dataset.action] + ([obs[LAST_ACTION]] if LAST_ACTION in obs else [])
    actions = np.concatenate(parts).astype(np.float64)
    ft = obs[FT].astype(np.float64)
    proprio = obs[PROPRIO].astype(np.float64)
    return {
        **out, "ft_mean": ft.mean(0), "ft_std": safe_std(ft, 0),
        "proprio_mean": proprio.mean(0), "proprio_std": safe_std(proprio, 0),
        "action_mean": actions.mean(0), "action_std": safe_std(actions, 0),
    }


def _fmt(terms: Mapping[str, torch.Tensor]) -> str:
    return ", ".join(f"{k}={float(v.detach()):.3g}" for k, v in terms.items() if k != "loss")
