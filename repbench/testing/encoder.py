"""Conformance checks for encoders: run ``check_encoder`` on your plugin before registering it.

Example::

    from repbench.testing import check_encoder
    check_encoder("vae_lowkl")                # a registered name
    check_encoder(MyEncoder, latent_dim=4)    # a class and constructor arguments
    check_encoder(MyEncoder(latent_dim=4))    # an unfitted instance
"""

from __future__ import annotations

import contextlib
import copy
import inspect
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from repbench.dataset import Dataset
from repbench.encoder import Encoder, check_fit_result, check_latent_dim, check_latents
from repbench.errors import DataError, RepbenchError

#: Constructor arguments check_encoder sets (when the encoder accepts them and the caller did
#: not) so that the check stays fast.
FAST_PARAMS: dict[str, Any] = {"epochs": 1, "batch_size": 16, "progress": False}


def check_encoder(plugin: str | type[Encoder] | Encoder, dataset: Dataset | None = None,
                  **params: Any) -> Encoder:
    """Check an encoder against the :class:`repbench.Encoder` contract; return it fitted.

    Args:
        plugin: a registered name, an ``Encoder`` subclass, or an unfitted instance.
        dataset: data to fit on; by default a small :func:`~repbench.testing.synthetic.
            synthetic_dataset` (3 episodes × 8 steps, 64 × 64 images).
        **params: constructor arguments (override the instance's own, and ``FAST_PARAMS``).

    Checks: the constructor only stores its arguments (``get_params`` rebuilds an equal
    encoder, nothing learned before ``fit``); ``encode`` refuses an unfitted encoder with a
    clear error; ``fit`` returns ``self``; ``encode`` returns finite float32 ``[N,
    latent_dim]``, deterministically, the same for any batch size, without modifying its
    input; a batch missing a required modality raises :class:`~repbench.errors.DataError`
    naming it; ``save``/``load`` round-trips (``torch.load(weights_only=True)``).

    Raises:
        AssertionError: on the first failed check, with a message saying which.
    """
    cls, kwargs = _resolve(plugin, params)
    name = cls.__name__
    if dataset is None:
        from repbench.testing.synthetic import synthetic_dataset

        dataset = synthetic_dataset(n_episodes=3, steps=8, seed=0)

    # -- construction ------------------------------------------------------------------------
    enc = cls(**kwargs)
    got = enc.get_params()
    for key, value in kwargs.items():
        assert _same(got[key], value), (
            f"{name}.__init__ must store argument {key!r} unchanged as self.{key} "
            f"(got {got[key]!r}, passed {value!r})"
        )
    assert not enc.is_fitted, (
        f"{name}.__init__ sets learned attributes (ending in '_'): "
        f"{[k for k in vars(enc) if k.endswith('_') and not k.startswith('_')]}; "
        "only fit() may set them"
    )
    clone = cls(**got)
    assert _same(clone.get_params(), got), f"{name}: type(e)(**e.get_params()) differs from e"

    obs = dataset.obs()
    try:
        enc.encode(obs)
    except RepbenchError as exc:
        assert "fit" in str(exc), f"{name}.encode on an unfitted encoder: unclear message {exc}"
    except Exception as exc:
        raise AssertionError(
            f"{name}.encode on an unfitted encoder raised {type(exc).__name__}: {exc}; raise "
            "a RepbenchError (call self.check_is_fitted())"
        ) from exc
    else:
        raise AssertionError(f"{name}.encode worked before fit(); call self.check_is_fitted()")

    # -- fit and encode ------------------------------------------------------------------------
    fitted = enc.fit(dataset)
    with _as_assertion():  # the checks the encoder and latents stages run too
        check_fit_result(enc, fitted, name)
        dim = check_latent_dim(enc, name)
    before = copy.deepcopy(obs)
    z = enc.encode(obs)
    with _as_assertion():
        check_latents(z, len(dataset), dim, name)  # float32, [N, latent_dim], finite
    for key, value in before.items():
        assert np.array_equal(obs[key], value), f"{name}.encode modified its input {key!r}"
    assert np.array_equal(enc.encode(obs), z), f"{name}.encode is not deterministic"

    # -- batch-size invariance -----------------------------------------------------------------
    tol = 1e-4 * (1.0 + float(np.abs(z).max()))
    singles = np.concatenate([enc.encode(_rows(obs, slice(i, i + 1))) for i in range(3)])
    assert singles.shape == (3, dim), f"{name}.encode of one row must return shape (1, {dim})"
    chunks = np.concatenate([enc.encode(_rows(obs, slice(i, i + 7)))
                             for i in range(0, len(dataset), 7)])
    for label, part, ref in (("1", singles, z[:3]), ("7", chunks, z)):
        err = float(np.abs(part - ref).max())
        assert err <= tol, (
            f"{name}.encode depends on the batch size: batches of {label} differ from one "
            f"batch by {err:.3g} (tolerance {tol:.3g})"
        )

    # -- missing modalities --------------------------------------------------------------------
    for modality in enc.required_modalities:
        partial = {k: v for k, v in obs.items() if k != modality}
        try:
            enc.encode(partial)
        except DataError as exc:
            assert modality in str(exc), (
                f"{name}: the error for a batch lacking {modality!r} does not name it: {exc}"
            )
        except Exception as exc:
            raise AssertionError(
                f"{name}.encode of a batch lacking {modality!r} raised {type(exc).__name__}: "
                f"{exc}; raise DataError (use self.check_observations)"
            ) from exc
        else:
            raise AssertionError(f"{name}.encode accepted a batch lacking {modality!r}")

    # -- save / load ---------------------------------------------------------------------------
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "encoder.pt"
        returned = enc.save(path)
        assert Path(returned).is_file(), f"{name}.save did not write {path}"
        import torch

        torch.load(path, map_location="cpu", weights_only=True)  # no code from the file
        # the generic Encoder.load finds the class by its "module:Name" reference, which a class
        # defined in a script, notebook or exec() does not have; the runner needs it importable
        loaders = [Encoder.load, cls.load] if _importable(cls) else [cls.load]
        for loader in loaders:
            loaded = loader(path)
            assert type(loaded) is cls, f"{name}: load returned a {type(loaded).__name__}"
            assert _same(loaded.get_params(), enc.get_params()), (
                f"{name}: loaded parameters {loaded.get_params()} differ from "
                f"{enc.get_params()}"
            )
            assert loaded.latent_dim == dim, f"{name}: loaded latent_dim differs"
            z_loaded = loaded.encode(obs)
            err = float(np.abs(z_loaded - z).max())
            assert z_loaded.dtype == np.float32 and err <= tol, (
                f"{name}: the loaded encoder encodes differently (max difference {err:.3g})"
            )
    return enc


def _resolve(plugin: Any, params: dict[str, Any]) -> tuple[type[Encoder], dict[str, Any]]:
    if isinstance(plugin, str):
        from repbench.registry import encoders

        cls = encoders.get(plugin)
        base: dict[str, Any] = {}
    elif inspect.isclass(plugin):
        cls, base = plugin, {}
    elif isinstance(plugin, Encoder):
        assert not plugin.is_fitted, "check_encoder needs an unfitted encoder instance"
        cls, base = type(plugin), plugin.get_params()
    else:
        raise AssertionError(f"check_encoder expects a name, class or instance, got {plugin!r}")
    assert inspect.isclass(cls) and issubclass(cls, Encoder), (
        f"{cls!r} is not a subclass of repbench.Encoder"
    )
    accepted = cls._param_names()
    kwargs = {k: v for k, v in FAST_PARAMS.items() if k in accepted}
    kwargs.update(base)
    kwargs.update(params)
    return cls, kwargs


@contextlib.contextmanager
def _as_assertion() -> Iterator[None]:
    """The shared contract checks raise DataError; the conformance kit reports AssertionError."""
    try:
        yield
    except DataError as exc:
        raise AssertionError(str(exc)) from None


def _rows(obs: Mapping[str, np.ndarray], index: slice) -> dict[str, np.ndarray]:
    return {k: v[index] for k, v in obs.items()}


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    return bool(a == b) and type(a) is type(b)


def _importable(cls: type) -> bool:
    """Whether ``cls`` can be found again from its ``module:qualname`` reference."""
    from repbench.errors import PluginError
    from repbench.registry import import_reference

    if cls.__module__ in ("__main__", "builtins"):
        return False
    try:
        return import_reference(f"{cls.__module__}:{cls.__qualname__}") is cls
    except PluginError:
        return False
