"""Baseline encoders: the true state itself, an untrained VAE encoder, PCA, and proprioception.

* ``oracle`` — z = z°, the privileged true state (an upper reference for every metric);
* ``oracle_task`` — z = the task-frame state (same information as z°, the form a controller
  needs: the upper bound of RL return);
* ``random`` — the VAE's encoder architecture with its seeded initial weights, never trained;
* ``pca`` — PCA of the flattened, standardized observation (downsampled image ⊕ ft ⊕ proprio);
* ``proprio_only`` — the standardized robot state, no vision or force.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from repbench.dataset import FT, IMAGE, PROPRIO, TRUE_STATE, Dataset
from repbench.encoder import Encoder, TrueStateEncoder
from repbench.errors import ConfigError, DataError
from repbench_encoders.vae import MultimodalVAE

__all__ = ["OracleEncoder", "OracleTaskEncoder", "PCAEncoder", "ProprioOnlyEncoder",
           "RandomEncoder"]


def _safe_std(x: np.ndarray) -> np.ndarray:
    s = x.std(axis=0)
    return np.where(s > 1e-8, s, 1.0)


def _check_width(name: str, modality: str, arr: np.ndarray, width: int) -> None:
    if arr.ndim != 2 or arr.shape[1] != width:
        raise DataError(f"{name}: modality {modality!r} must have shape [N, {width}] as at fit "
                        f"time, got {list(arr.shape)}")


class OracleEncoder(TrueStateEncoder):
    """The true state z° itself (float32); its latent size is the task's state size.

    The implementation is :class:`repbench.encoder.TrueStateEncoder` (defined once, in the core).
    """

    family = "baseline"


class OracleTaskEncoder(Encoder):
    """The task-frame state: z° in the form a controller needs (the upper bound of the suite).

    For the peg-in-hole, the peg tip's offset from the hole's opening and the tip velocity
    (:meth:`repbench.Task.task_state`). It carries the same information about the hole as
    ``oracle`` (z° holds the joint angles, from which the tip position follows, and the hole
    position), in a different form: ``oracle`` leaves the agent to learn the 2 mm difference
    of two absolute positions, this one hands it the difference. Mutual information cannot
    tell them apart (it is invariant under invertible maps); RL can (FACTS.md: 0 % vs 100 %
    insertion).

    Args:
        task: the registered task whose ``task_state`` defines z; ``None`` takes the task
            named in the fitting dataset's metadata.
    """

    family = "baseline"

    required_modalities = (PROPRIO, TRUE_STATE)

    def __init__(self, task: str | None = None) -> None:
        self.task = task

    def fit(self, dataset: Dataset) -> OracleTaskEncoder:
        """Resolve the task (and its parameters from the dataset's metadata) and the latent
        size."""
        from repbench.registry import tasks

        name = self.task or dataset.metadata.get("task")
        if not name or name not in tasks:
            raise DataError(
                f"{type(self).__name__}: the dataset's metadata names no registered task "
                f"({name!r}); pass task='<task id>'")
        params = dataset.metadata.get("params") or dataset.metadata.get("task_params") or {}
        self.task_id_ = str(name)
        self.task_params_ = {k: v for k, v in dict(params).items()
                             if isinstance(v, (int, float, str, bool, list, tuple))}
        self._task = None
        probe = self._resolve_task().task_state(dataset.obs(slice(0, 1)))
        self.state_dim_ = int(probe.shape[1])
        return self

    def _resolve_task(self) -> Any:
        task = getattr(self, "_task", None)
        if task is None:
            from repbench.registry import tasks

            cls = tasks.get(self.task_id_)
            task = self._task = cls(**accepted_params(cls, self.task_params_))
        return task

    def encode(self, observations: Mapping[str, Any]) -> np.ndarray:
        """``task.task_state(observations)`` as float32 [N, K]."""
        self.check_is_fitted()
        batch = self.check_observations(observations)
        z = np.asarray(self._resolve_task().task_state(batch), dtype=np.float32)
        _check_width(type(self).__name__, "task_state", z, self.state_dim_)
        return z

    @property
    def latent_dim(self) -> int:
        """K, known after ``fit``."""
        self.check_is_fitted()
        return self.state_dim_


def accepted_params(cls: type, params: Mapping[str, Any]) -> dict[str, Any]:
    """The entries of ``params`` that ``cls``'s constructor accepts (tuples restored)."""
    import inspect

    names = set(inspect.signature(cls).parameters)
    return {k: tuple(v) if isinstance(v, list) else v for k, v in params.items() if k in names}


class ProprioOnlyEncoder(Encoder):
    """Robot state only (standardized proprioception), no vision or force."""

    family = "baseline"

    required_modalities = (PROPRIO,)

    def __init__(self) -> None:
        pass

    def fit(self, dataset: Dataset) -> ProprioOnlyEncoder:
        """Store the proprioception mean and standard deviation."""
        p = dataset.observations[PROPRIO].astype(np.float64)
        self.mean_ = p.mean(axis=0)
        self.std_ = _safe_std(p)
        return self

    def encode(self, observations: Mapping[str, Any]) -> np.ndarray:
        """(proprio − mean) / std as float32 [N, P]."""
        self.check_is_fitted()
        p = self.check_observations(observations)[PROPRIO]
        _check_width(type(self).__name__, PROPRIO, p, self.mean_.shape[0])
        return ((p - self.mean_) / self.std_).astype(np.float32)

    @property
    def latent_dim(self) -> int:
        """P, known after ``fit``."""
        self.check_is_fitted()
        return int(self.mean_.shape[0])


class RandomEncoder(MultimodalVAE):
    """The VAE's encoder architecture with its seeded initial weights, never trained.

    Fitting only computes the input normalization statistics; ``encode`` returns μ_z.
    """

    family = "baseline"

    #: its decoder is untrained too: no reconstruction figure for the leaderboard
    save_reconstruction_figure = None

    def __init__(self, latent_dim: int = 16, seed: int = 0, device: str = "auto") -> None:
        super().__init__(latent_dim=latent_dim, epochs=0, seed=seed, device=device,
                         progress=False)


class PCAEncoder(Encoder):
    """PCA (scikit-learn) of the flattened observation: image average-pooled to
    ``image_size`` × ``image_size``, ⊕ ft ⊕ proprio, each feature standardized.

    Args:
        latent_dim: number of principal components kept.
        image_size: side of the downsampled image (must divide the image side).
        seed: seed of the randomized SVD solver (used on large inputs).
    """

    family = "baseline"

    latent_dim: int = 16  # a hyperparameter here (shadows the base class's abstract property)

    def __init__(self, latent_dim: int = 16, image_size: int = 16, seed: int = 0) -> None:
        self.latent_dim = latent_dim
        self.image_size = image_size
        self.seed = seed

    def check_params(self) -> None:
        """latent_dim and image_size must be positive integers."""
        name = type(self).__name__
        if not isinstance(self.latent_dim, (int, np.integer)) or self.latent_dim < 1:
            raise ConfigError(f"{name}: latent_dim must be a positive integer, "
                              f"got {self.latent_dim!r}")
        if not isinstance(self.image_size, (int, np.integer)) or self.image_size < 1:
            raise ConfigError(f"{name}: image_size must be a positive integer, "
                              f"got {self.image_size!r}")

    def _features(self, observations: Mapping[str, Any]) -> np.ndarray:
        batch = self.check_observations(observations)
        img = batch[IMAGE]
        name = type(self).__name__
        if img.ndim != 4 or img.shape[3] != 3 or img.shape[1] != img.shape[2]:
            raise DataError(f"{name}: images must be [N, S, S, 3], got {list(img.shape)}")
        side = img.shape[1]
        if side % self.image_size:
            raise ConfigError(f"{name}: image_size={self.image_size} must divide the image side "
                              f"{side}")
        k = side // self.image_size
        n = img.shape[0]
        small = img.reshape(n, self.image_size, k, self.image_size, k, 3).mean(axis=(2, 4),
                                                                               dtype=np.float64)
        return np.concatenate([small.reshape(n, -1), np.asarray(batch[FT], np.float64),
                               np.asarray(batch[PROPRIO], np.float64)], axis=1)

    def fit(self, dataset: Dataset) -> PCAEncoder:
        """Standardize the features and fit ``sklearn.decomposition.PCA``."""
        from sklearn.decomposition import PCA

        name = type(self).__name__
        self.check_params()
        x = self._features(dataset.obs(with_true_state=False))
        if self.latent_dim > min(x.shape):
            raise ConfigError(
                f"{name}: latent_dim={self.latent_dim} exceeds min(samples, features)="
                f"{min(x.shape)}; lower latent_dim or use more data"
            )
        mean, std = x.mean(axis=0), _safe_std(x)
        pca = PCA(n_components=int(self.latent_dim), random_state=self.seed)
        pca.fit((x - mean) / std)
        self.feature_mean_ = mean
        self.feature_std_ = std
        self.components_ = pca.components_.astype(np.float64)
        self.pca_mean_ = pca.mean_.astype(np.float64)
        self.explained_variance_ratio_ = pca.explained_variance_ratio_.astype(np.float64)
        self.n_features_ = int(x.shape[1])
        return self

    def encode(self, observations: Mapping[str, Any]) -> np.ndarray:
        """Project the standardized features on the principal axes (float32 [N, latent_dim])."""
        self.check_is_fitted()
        x = self._features(observations)
        if x.shape[1] != self.n_features_:
            raise DataError(f"{type(self).__name__}: observation has {x.shape[1]} features but "
                            f"the encoder was fitted on {self.n_features_} (other image, ft or "
                            "proprio size)")
        x = (x - self.feature_mean_) / self.feature_std_
        return ((x - self.pca_mean_) @ self.components_.T).astype(np.float32)
