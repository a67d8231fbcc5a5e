"""The generic plugin registry: registration, lazy references, discovery, clear errors."""

from __future__ import annotations

import numpy as np
import pytest

import repbench
from repbench.errors import PluginError
from repbench.registry import Registry, encoders, import_reference, metrics, tasks


class _Tiny(repbench.Encoder):
    """A tiny encoder for registry tests."""

    required_modalities = ("proprio",)

    def __init__(self, scale: float = 1.0) -> None:
        self.scale = scale

    def fit(self, dataset):  # type: ignore[no-untyped-def]
        self.dim_ = dataset.observations["proprio"].shape[1]
        return self

    def encode(self, observations):  # type: ignore[no-untyped-def]
        return (self.check_observations(observations)["proprio"] * self.scale).astype(np.float32)

    @property
    def latent_dim(self) -> int:
        return self.dim_


@pytest.fixture
def reg() -> Registry:
    return Registry("encoder", None, check=None)


def test_decorator_registers_and_returns_object(reg: Registry) -> None:
    @reg.register("a", description="the a plugin")
    class A:
        pass

    assert reg.get("a") is A
    assert reg.describe("a") == "the a plugin"
    assert "a" in reg and reg.names() == ["a"]


def test_lazy_reference_imported_on_first_get(reg: Registry) -> None:
    reg.register("od", "collections:OrderedDict")
    from collections import OrderedDict

    assert reg.get("od") is OrderedDict


def test_duplicate_name_rejected(reg: Registry) -> None:
    reg.register("x", dict)
    with pytest.raises(PluginError, match="duplicate encoder name 'x'"):
        reg.register("x", list)
    reg.register("x", dict)  # the same plugin again is harmless
    reg.register("x", list, replace=True)
    assert reg.get("x") is list


def test_unknown_name_suggests_close_matches(reg: Registry) -> None:
    reg.register("vae", dict)
    reg.register("vae_lowkl", dict)
    with pytest.raises(PluginError) as info:
        reg.get("vea")
    msg = str(info.value)
    assert "unknown encoder 'vea'" in msg and "did you mean 'vae'" in msg
    assert "known: vae, vae_lowkl" in msg


def test_reference_that_does_not_import(reg: Registry) -> None:
    reg.register("ghost", "no_such_package_xyz.mod:Thing")
    with pytest.raises(PluginError, match=r"cannot import module 'no_such_package_xyz.mod'"):
        reg.get("ghost")
    with pytest.raises(PluginError, match="has no attribute 'Nope'"):
        import_reference("collections:Nope")
    with pytest.raises(PluginError, match=r"write it as 'package.module:Name'"):
        import_reference("collections.OrderedDict")


def test_kind_check_rejects_wrong_base_class() -> None:
    with pytest.raises(PluginError, match=r"subclass of repbench\.Encoder"):
        encoders.register("not_an_encoder_test", dict)
    assert "not_an_encoder_test" not in encoders


def test_metric_registry_requires_metric_objects() -> None:
    with pytest.raises(PluginError, match=r"repbench.Metric"):
        metrics.register("plain_function_test", lambda z, zt, e, r: 0.0)


def test_register_own_encoder_and_use_it() -> None:
    encoders.register("tiny_registry_test", _Tiny)
    try:
        assert encoders.get("tiny_registry_test") is _Tiny
        assert encoders.describe("tiny_registry_test") == "A tiny encoder for registry tests."
    finally:
        encoders.unregister("tiny_registry_test")


def test_builtin_plugins_found_through_entry_points() -> None:
    names = encoders.names()
    for name in ("vae", "vae_lowkl", "success", "pred_z", "pred_im", "smooth", "smooth_lowkl",
                 "oracle", "random", "pca", "proprio_only"):
        assert name in names
    assert "PegInHole-v0" in tasks
    assert {"mine", "ksg", "regression", "smoothness", "coherence"} <= set(metrics.names())
    assert {"sac", "ddpg"} <= set(repbench.agents.names())
