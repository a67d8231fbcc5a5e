"""Loss curves stored with each encoder artifact; suite settings for early stopping."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import matplotlib.image as mpimg
import pytest

import repbench
from repbench.dataset import Dataset
from repbench.errors import ConfigError
from repbench.pipeline.stages import _save_fit_history
from repbench.pipeline.suite import load_suite


class _Writer:
    def __init__(self, root: Path) -> None:
        self.root = root
        self.extra_meta: dict[str, Any] = {}

    def file(self, name: str) -> Path:
        return self.root / name


def test_encoder_artifact_gets_history_and_loss_figure(tiny_dataset: Dataset, tmp_path) -> None:
    enc = repbench.encoders.get("vae_lowkl")(epochs=3, patience=1, validation_fraction=0.34,
                                             batch_size=8, progress=False).fit(tiny_dataset)
    summary = _save_fit_history(enc, "vae_lowkl", _Writer(tmp_path))
    stored = json.loads((tmp_path / "fit_history.json").read_text())
    assert stored == enc.history_
    assert summary["epochs_run"] == len(enc.history_)
    assert summary["best_epoch"] == enc.best_epoch_
    assert summary["heldout_loss"] == enc.history_[enc.best_epoch_ - 1]["heldout"]["loss"]
    img = mpimg.imread(tmp_path / "loss_curves.png")
    assert img.ndim == 3 and img.shape[1] > 400


def test_encoders_without_history_store_nothing(tiny_dataset: Dataset, tmp_path) -> None:
    enc = repbench.encoders.get("pca")(latent_dim=3).fit(tiny_dataset)
    assert _save_fit_history(enc, "pca", _Writer(tmp_path)) == {}
    assert not list(tmp_path.iterdir())


def test_suite_early_stopping_needs_heldout_episodes(tmp_path) -> None:
    base = """
name = "x"
tasks = ["PegInHole-v0"]
encoders = ["vae_lowkl"]
metrics = ["ksg"]
agents = ["sac"]
seeds = [0]
[dataset]
random_episodes = 2
random_steps = 10
on_policy_episodes = 0
on_policy_steps = 10
[rl]
train_steps = 100
eval_episodes = 1
full_state_train_steps = 100
[encoder_training]
epochs = 5
"""
    p = tmp_path / "x.toml"
    p.write_text(base + "patience = 2\nvalidation_fraction = 0.0\n")
    with pytest.raises(ConfigError, match=r"patience > 0 .* needs validation_fraction > 0"):
        load_suite(p)
    p.write_text(base + "patience = 2\nvalidation_fraction = 0.2\n")
    assert load_suite(p).encoder_training.patience == 2
    p.write_text(base)  # the defaults follow quick: early stopping on held-out episodes
    training = load_suite(p).encoder_training
    assert training.patience > 0 and training.validation_fraction > 0


def test_quick_trains_every_encoder_with_early_stopping() -> None:
    from repbench.pipeline.plan import build_plan

    suite = load_suite("quick")
    assert len(suite.encoders) >= 20
    plan = build_plan(suite)
    for name, spec in plan.tasks[0].encoders.items():
        params = spec.config["params"]
        if "patience" in params:
            assert params["patience"] > 0 and params["validation_fraction"] > 0, name
    dims = {n: s.config["params"].get("latent_dim") for n, s in plan.tasks[0].encoders.items()}
    assert dims["vae_lowkl_d4"] == 4 and dims["vae_lowkl_d64"] == 64
    assert dims["vae_lowkl"] == 16
