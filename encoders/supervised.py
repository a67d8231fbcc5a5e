"""A supervised encoder: the VAE family's trunk trained to regress the state (a learned upper
bound on what the observations can tell).

``encode`` returns the trunk's μ_z (``latent_dim`` numbers); a linear head maps it to the
standardized target during training (mean squared error). Targets:

* ``"true_state"`` — the paper's z° (``supervised``);
* ``"task"`` — the task-frame state, :meth:`repbench.Task.task_state` of the dataset's task (for
  the peg-in-hole: peg tip minus hole opening and tip velocity; ``supervised_task``). The task is
  found from the dataset's metadata (``task`` and its parameters) through the task registry.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from repbench.dataset import FT, IMAGE, PROPRIO, Dataset
from repbench.errors import ConfigError, DataError
from repbench_encoders.networks import MultimodalVAENet, NetworkSpec
from repbench_encoders.trunk import TrunkEncoder, make_variant

__all__ = ["SupervisedEncoder", "SupervisedTaskEncoder", "task_frame_state"]

TARGETS = ("true_state", "task")


def task_frame_state(dataset: Dataset) -> np.ndarray:
    """The task-frame state of every row of ``dataset``, from the task named in its metadata."""
    from repbench.registry import tasks

    meta = dataset.metadata
    if "task" not in meta and meta.get("parts"):  # Dataset.concatenate keeps the parts' metadata
        meta = meta["parts"][0]
    name = meta.get("task")
    if not isinstance(name, str) or name not in tasks:
        raise DataError(f"target='task' needs the dataset's task to be registered; the dataset's "
                        f"metadata names {name!r} (known: {tasks.names()}); use "
                        "target='true_state'")
    params = meta.get("params", meta.get("task_params", {})) or {}
    task = tasks.get(name)(**params)
    try:
        state = task.task_state(dataset.obs())
    except NotImplementedError as exc:
        raise DataError(f"{exc}; or use target='true_state'") from None
    return np.asarray(state, np.float64)


class _SupervisedNet(nn.Module):
    """The trunk (no decoder) and a linear head from μ_z to the standardized target."""

    def __init__(self, spec: NetworkSpec, target_dim: int) -> None:
        super().__init__()
        self.trunk = MultimodalVAENet(spec)
        self.head = nn.Linear(spec.latent_dim, target_dim)

    def encode(self, image: torch.Tensor | None, ft: torch.Tensor | None,
               proprio: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
        return self.trunk.encode(image, ft, proprio)


class SupervisedEncoder(TrunkEncoder):
    """The multimodal trunk trained to regress ``target`` from image, force and proprioception.

    Args:
        target: ``"true_state"`` (z°) or ``"task"`` (the task-frame state of the dataset's task).
        latent_dim: size D of z (the head maps it linearly to the target).
        epochs: maximum passes over the training rows.
        batch_size: rows per Adam step.
        learning_rate: Adam learning rate.
        patience: stop after this many epochs without a held-out improvement (0: never).
        validation_fraction: share of whole episodes held out (0: none).
        tol: relative held-out improvement that counts for ``patience``.
        seed: seeds initialization, the split and batch order.
        device: ``"auto"``, ``"cpu"``, ``"cuda"``, ...
        progress: show a progress bar while training.
    """

    family = "supervised"

    LOSS_TERMS = ("mse",)
    fit_modalities = (IMAGE, FT, PROPRIO)

    def __init__(self, target: str = "true_state", latent_dim: int = 16, epochs: int = 20,
                 batch_size: int = 64, learning_rate: float = 1e-3, patience: int = 0,
                 validation_fraction: float = 0.0, tol: float = 1e-3, seed: int = 0,
                 device: str = "auto", progress: bool = True) -> None:
        self.target = target
        self.latent_dim = latent_dim
        self.epochs = epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.patience = patience
        self.validation_fraction = validation_fraction
        self.tol = tol
        self.seed = seed
        self.device = device
        self.progress = progress

    def check_params(self) -> None:
        super().check_params()
        if self.target not in TARGETS:
            raise ConfigError(f"{type(self).__name__}: target must be one of {TARGETS}, "
                              f"got {self.target!r}")

    def _targets(self, dataset: Dataset) -> np.ndarray:
        if self.target == "task":
            return task_frame_state(dataset)
        return np.asarray(dataset.true_state, np.float64)

    def _prepare(self, dataset: Dataset) -> None:
        y = self._targets(dataset)
        if y.ndim != 2 or y.shape[0] != len(dataset):
            raise DataError(f"{type(self).__name__}: the {self.target} target must be [N, K], "
                            f"got {list(y.shape)}")
        std = y.std(0)
        self.target_mean_ = y.mean(0)
        self.target_std_ = np.where(std > 1e-8, std, 1.0)
        self.target_dim_ = int(y.shape[1])

    def _spec_options(self) -> dict[str, Any]:
        return {"decoder": False}

    def _build_net(self, spec: NetworkSpec) -> _SupervisedNet:
        return _SupervisedNet(spec, self.target_dim_)

    def _extra_tensors(self, dataset: Dataset) -> dict[str, torch.Tensor]:
        y = (self._targets(dataset) - self.target_mean_) / self.target_std_
        return {"target": torch.as_tensor(y, dtype=torch.float32, device=self._device)}

    def _loss_terms(self, data: dict[str, torch.Tensor], idx: torch.Tensor,
                    idx_next: torch.Tensor | None, gen: torch.Generator, training: bool
                    ) -> dict[str, torch.Tensor]:
        mu, _ = self._encode_rows(data, idx)
        mse = ((self.net_.head(mu) - data["target"][idx]) ** 2).mean()
        return {"loss": mse, "mse": mse}

    def predict(self, observations: Any) -> np.ndarray:
        """The regressed target (in its own units) of an observation batch, float32 [N, K]."""
        with torch.inference_mode():
            mu, _ = self._encode_obs(observations)
            y = self.net_.head(mu).cpu().numpy().astype(np.float64)
        return (y * self.target_std_ + self.target_mean_).astype(np.float32)


SupervisedTaskEncoder = make_variant(
    SupervisedEncoder, "SupervisedTaskEncoder", "Supervised encoder regressing the task-frame "
    "state (Task.task_state) of the dataset's task.", module=__name__, target="task")
