"""The encoder API: scikit-learn–style estimators that map observations to latents.

Write your own in a few lines::

    import numpy as np
    import repbench

    @repbench.encoders.register("mean_pixel")
    class MeanPixel(repbench.Encoder):
        \"\"\"Mean image colour (a toy example).\"\"\"
        required_modalities = ("image",)

        def __init__(self, scale: float = 1.0):
            self.scale = scale

        def fit(self, dataset):
            self.fitted_ = True
            return self

        def encode(self, observations):
            self.check_is_fitted()
            img = self.check_observations(observations)["image"]
            return (img.reshape(len(img), -1, 3).mean(1) * self.scale).astype(np.float32)

        @property
        def latent_dim(self):
            return 3

Rules (checked by :func:`repbench.testing.check_encoder`): the constructor only stores its
arguments under the same names; ``fit`` returns ``self``; learned state ends in ``_``;
``encode`` returns float32 ``[N, latent_dim]`` — the mean μ_z, never a sample — deterministically.
"""

from __future__ import annotations

import abc
import inspect
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np

from repbench.dataset import FT, IMAGE, PROPRIO, TRUE_STATE, Dataset, as_observation_batch
from repbench.errors import DataError, RepbenchError
from repbench.references import import_reference, reference_of

E = TypeVar("E", bound="Encoder")

_FORMAT = "repbench-encoder-v1"


class Encoder(abc.ABC):
    """Base class of all encoders. Subclasses implement ``fit``, ``encode``, ``latent_dim``.

    Torch-based encoders override :meth:`get_state` / :meth:`set_state` to expose their
    tensors; the base class takes care of files.
    """

    #: Declared version of what this plugin computes. Part of every stage key and result record
    #: in place of the source code: bump it when a change alters results; editing docstrings or
    #: refactoring needs no bump. Older records then show as stale
    #: (:mod:`repbench.pipeline.records`).
    version: ClassVar[int] = 0

    #: Modalities ``encode`` reads; batches lacking one are rejected with a clear error.
    required_modalities: ClassVar[tuple[str, ...]] = (IMAGE, FT, PROPRIO)
    #: Which kind of encoder this is, for the leaderboard's within-family correlations:
    #: ``"baseline"`` (oracles, untrained, blind or classical references) or a learned family
    #: (``"vae"``, ``"contrastive"``, ``"supervised"``, ...; default ``"learned"``).
    family: ClassVar[str] = "learned"

    # -- to implement --------------------------------------------------------------------------
    @abc.abstractmethod
    def fit(self: E, dataset: Dataset) -> E:
        """Learn from ``dataset``; return ``self``."""

    @abc.abstractmethod
    def encode(self, observations: Mapping[str, np.ndarray]) -> np.ndarray:
        """Map an observation batch (modality → array, leading batch axis) to float32 [N, D]."""

    @property
    @abc.abstractmethod
    def latent_dim(self) -> int:
        """Size D of the latent vector."""

    # -- parameters (scikit-learn convention) --------------------------------------------------
    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return [
            p.name for p in sig.parameters.values()
            if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
        ]

    def get_params(self) -> dict[str, Any]:
        """Constructor arguments: ``type(e)(**e.get_params())`` rebuilds an unfitted copy."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self: E, **params: Any) -> E:
        valid = set(self._param_names())
        for key, value in params.items():
            if key not in valid:
                raise RepbenchError(
                    f"{type(self).__name__} has no parameter {key!r}; valid: {sorted(valid)}"
                )
            setattr(self, key, value)
        return self

    def check_params(self) -> None:  # noqa: B027 (a hook: the default accepts everything)
        """Raise :class:`repbench.errors.ConfigError` for an invalid hyperparameter.

        The planner calls it on a freshly constructed encoder, so a bad value in a suite file
        fails before anything runs. The default accepts everything; override it (and call it
        from ``fit``) when some values are invalid.
        """

    @property
    def is_fitted(self) -> bool:
        return any(k.endswith("_") and not k.startswith("_") for k in vars(self))

    def check_observations(self, observations: Mapping[str, Any]) -> dict[str, np.ndarray]:
        """Return the required modalities as arrays, or raise DataError naming what is missing."""
        return as_observation_batch(observations, self.required_modalities, type(self).__name__)

    def check_is_fitted(self) -> None:
        if not self.is_fitted:
            raise RepbenchError(f"{type(self).__name__} is not fitted: call fit(dataset) first")

    # -- state and files -----------------------------------------------------------------------
    def get_state(self) -> dict[str, Any]:
        """Learned state as tensors, arrays and plain Python values (no arbitrary objects)."""
        return {k: v for k, v in vars(self).items() if k.endswith("_") and not k.startswith("_")}

    def set_state(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`get_state` returned."""
        for key, value in state.items():
            setattr(self, key, value)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Save hyperparameters and learned state; loadable without executing code from the file."""
        import torch

        self.check_is_fitted()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        payload = {
            "format": _FORMAT,
            "class": reference_of(type(self)),
            "params": self.get_params(),
            "state": _to_saveable(self.get_state()),
        }
        tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
        torch.save(payload, tmp)
        os.replace(tmp, path)
        return path

    @classmethod
    def load(cls: type[E], path: str | os.PathLike[str]) -> E:
        """Load an encoder saved by :meth:`save` (``torch.load(weights_only=True)``)."""
        import torch

        path = Path(path)
        try:
            payload = torch.load(path, map_location="cpu", weights_only=True)
        except FileNotFoundError:
            raise DataError(f"encoder file {path} does not exist") from None
        except Exception as exc:  # torch raises many types for damaged files
            raise DataError(f"encoder file {path} cannot be read ({exc}); fit it again") from None
        if not isinstance(payload, dict) or payload.get("format") != _FORMAT:
            raise DataError(f"{path} is not a repbench encoder file")
        target: type[Encoder] = cls
        if cls is Encoder or inspect.isabstract(cls):
            target = import_reference(payload["class"])
        encoder = target(**payload["params"])
        encoder.set_state(_from_saved(payload["state"]))
        return encoder  # type: ignore[return-value]

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"


class TrueStateEncoder(Encoder):
    """z = z°: the privileged true state itself (float32); its latent size is the task's state size.

    Defined once, here: the ``oracle`` encoder plugin, the full-state agent's observation and the
    conformance kit's default encoder all use it.
    """

    required_modalities = (TRUE_STATE,)

    def __init__(self) -> None:
        pass

    def fit(self: E, dataset: Dataset) -> E:
        """Record the true-state size."""
        self.state_dim_ = int(dataset.true_state.shape[1])
        return self

    def encode(self, observations: Mapping[str, Any]) -> np.ndarray:
        """Return ``observations["true_state"]`` as float32 [N, S]."""
        self.check_is_fitted()
        z = self.check_observations(observations)[TRUE_STATE]
        if z.ndim != 2 or z.shape[1] != self.state_dim_:
            raise DataError(f"{type(self).__name__}: modality {TRUE_STATE!r} must have shape "
                            f"[N, {self.state_dim_}] as at fit time, got {list(z.shape)}")
        return np.array(z, dtype=np.float32, copy=True)

    @property
    def latent_dim(self) -> int:
        """S, known after ``fit``."""
        self.check_is_fitted()
        return self.state_dim_


# -- contract checks on what a fitted encoder returns -----------------------------------------
# One implementation for the conformance kit (repbench.testing.check_encoder, which turns them
# into AssertionErrors) and the encoder and latents stages, so a user encoder that breaks the
# contract stops at its own stage with its name, instead of reaching the metrics.

def check_fit_result(encoder: Encoder, fitted: Any, who: str) -> None:
    """Raise :class:`DataError` unless ``fit`` returned ``encoder`` itself, now fitted.

    ``who`` names the encoder in the message (e.g. ``"encoder 'mine' (MyEncoder)"``).
    """
    if fitted is not encoder:
        raise DataError(f"{who}: fit must return self, returned {_short(fitted)}; end fit with "
                        "`return self`")
    if not encoder.is_fitted:
        raise DataError(f"{who}: fit must set learned attributes ending in '_' (e.g. "
                        "self.mean_ = ...); it set none")


def check_latent_dim(encoder: Encoder, who: str) -> int:
    """The fitted encoder's ``latent_dim``; :class:`DataError` unless it is a positive int."""
    dim = encoder.latent_dim
    if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim < 1:
        raise DataError(f"{who}: latent_dim must be a positive int, got {_short(dim)}")
    return int(dim)


def check_latents(z: Any, n_rows: int, latent_dim: int, who: str, *, float32: bool = True
                  ) -> np.ndarray:
    """Check what ``encode`` returned for ``n_rows`` observations; return it.

    It must be a numpy array of finite numbers of shape ``[n_rows, latent_dim]``, and float32
    when ``float32`` (the contract; the stages pass ``False`` and cast other real dtypes, as
    the RL wrapper does). Raises :class:`DataError` naming ``who``, what came back and the fix.
    """
    fix = "encode must return a float32 array [N, latent_dim], one row per observation"
    if not isinstance(z, np.ndarray):
        raise DataError(f"{who}: encode must return a numpy array, got {type(z).__name__}; "
                        f"{fix}")
    if z.dtype.kind not in "fiu":
        raise DataError(f"{who}: encode returned {z.dtype} values, not numbers; {fix}")
    if float32 and z.dtype != np.float32:
        raise DataError(f"{who}: encode must return float32, got {z.dtype}; return "
                        "z.astype(np.float32)")
    if z.shape != (n_rows, latent_dim):
        raise DataError(f"{who}: encode returned shape {z.shape} for {n_rows} observations, "
                        f"expected {(n_rows, latent_dim)} (latent_dim = {latent_dim}); {fix}")
    if not np.isfinite(z).all():
        bad = int((~np.isfinite(z)).any(axis=1).sum())
        raise DataError(f"{who}: encode returned NaN or infinite values in {bad} of {n_rows} "
                        "rows; check the encoder (diverged training?) and fit it again")
    return z


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 and "\n" not in text else f"a {type(value).__name__}"


def _to_saveable(value: Any) -> Any:
    """numpy arrays → tensors (weights_only can load tensors but not ndarrays)."""
    import torch

    if isinstance(value, np.ndarray):
        return {"__ndarray__": torch.from_numpy(np.ascontiguousarray(value))}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {k: _to_saveable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_to_saveable(v) for v in value)
    return value


def _from_saved(value: Any) -> Any:
    if isinstance(value, dict):
        if set(value) == {"__ndarray__"}:
            return value["__ndarray__"].numpy()
        return {k: _from_saved(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_from_saved(v) for v in value)
    return value
