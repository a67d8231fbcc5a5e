"""Training to convergence: the early-stopping rule, held-out episodes, restored weights."""

from __future__ import annotations

import numpy as np
import pytest

from repbench.dataset import Dataset
from repbench.errors import ConfigError, DataError
from repbench_encoders.training import EarlyStopping
from repbench_encoders.vae import VAELowKL

FAST = {"batch_size": 8, "progress": False}


def _run(curve: list[float], patience: int, tol: float = 1e-3) -> tuple[int, EarlyStopping]:
    """Feed ``curve`` to a stopper; return the epoch it stopped at (len + 1 if never)."""
    stopper = EarlyStopping(patience, tol)
    for epoch, value in enumerate(curve, start=1):
        if stopper.update(epoch, value):
            return epoch, stopper
    return len(curve) + 1, stopper


def test_stops_on_a_plateau_and_not_before() -> None:
    # falls for 6 epochs, then a plateau with noise below the 0.1 % tolerance
    curve = [10.0, 8.0, 6.0, 5.0, 4.5, 4.2] + [4.2 * (1 + 1e-4 * (-1) ** i) for i in range(10)]
    stopped, stopper = _run(curve, patience=3)
    assert stopped == 9  # epochs 7, 8, 9 do not improve: stop after the third
    assert stopper.best_epoch == 6 and stopper.best == 4.2
    for patience in (1, 2, 5):
        assert _run(curve, patience)[0] == 6 + patience


def test_does_not_stop_while_improving() -> None:
    curve = [100.0 * 0.98 ** i for i in range(50)]  # 2 % per epoch > tolerance
    stopped, stopper = _run(curve, patience=1)
    assert stopped == 51 and stopper.best_epoch == 50


def test_a_late_improvement_resets_patience() -> None:
    curve = [5.0, 4.0, 4.0, 4.0, 3.0, 3.0, 3.0, 3.0]
    stopped, stopper = _run(curve, patience=3)
    assert stopped == 8 and stopper.best_epoch == 5


def test_improvements_below_tol_do_not_count_and_nan_never_improves() -> None:
    # each below 0.1 % under the best (1.0), which therefore stays the best
    curve = [1.0, 0.9995, 0.9992, 0.9991]
    assert _run(curve, patience=3, tol=1e-3)[0] == 4
    assert _run(curve, patience=3, tol=0.0)[0] == 5
    assert _run([1.0, float("nan"), float("nan")], patience=2)[0] == 3
    assert _run([1.0] * 20, patience=0)[0] == 21  # patience 0: never stops


def test_encoder_stops_when_heldout_loss_is_flat(tiny_dataset: Dataset) -> None:
    # a learning rate too small to move anything: the held-out loss is flat from epoch 1
    enc = VAELowKL(epochs=20, patience=2, validation_fraction=0.34, learning_rate=1e-12,
                   **FAST).fit(tiny_dataset)
    assert len(enc.history_) == 3 and enc.best_epoch_ == 1
    assert [h["epoch"] for h in enc.history_] == [1, 2, 3]
    for h in enc.history_:
        assert set(h["train"]) == set(h["heldout"]) == {"loss", *VAELowKL.LOSS_TERMS}


def test_best_heldout_weights_are_restored(small_dataset: Dataset) -> None:
    enc = VAELowKL(epochs=6, patience=2, validation_fraction=0.25, learning_rate=3e-3,
                   **FAST).fit(small_dataset)
    heldout = [h["heldout"]["loss"] for h in enc.history_]
    assert enc.best_epoch_ == int(np.argmin(heldout)) + 1
    _, test = small_dataset.episode_split(0.25, enc.seed)  # the episodes fit held out
    again = enc.loss_terms(small_dataset.subset(test))["loss"]
    assert again == pytest.approx(min(heldout), rel=1e-4)


def test_heldout_rows_are_whole_episodes(small_dataset: Dataset) -> None:
    _, test = small_dataset.episode_split(0.25, 0)
    held_episodes = set(small_dataset.episode[test])
    assert held_episodes and all(
        (small_dataset.episode[test] == e).sum() == (small_dataset.episode == e).sum()
        for e in held_episodes)
    # training on the rest only: the train curve's first epoch saw 3 of 4 episodes
    enc = VAELowKL(epochs=1, patience=1, validation_fraction=0.25, **FAST).fit(small_dataset)
    assert enc.history_[0]["heldout"]["loss"] > 0


def test_bad_early_stopping_settings(tiny_dataset: Dataset) -> None:
    with pytest.raises(ConfigError, match="needs held-out episodes; set validation_fraction"):
        VAELowKL(epochs=2, patience=2, **FAST).fit(tiny_dataset)
    with pytest.raises(ConfigError, match=r"validation_fraction must be in \[0, 1\)"):
        VAELowKL(epochs=2, validation_fraction=1.0, **FAST).fit(tiny_dataset)
    with pytest.raises(ConfigError, match="patience must be an integer >= 0"):
        VAELowKL(epochs=2, patience=-1, **FAST).fit(tiny_dataset)
    one_episode = tiny_dataset.subset(np.flatnonzero(tiny_dataset.episode == 0))
    with pytest.raises(DataError, match="needs at least 2 episodes"):
        VAELowKL(epochs=1, validation_fraction=0.2, **FAST).fit(one_episode)


def test_history_survives_save_and_load(tiny_dataset: Dataset, tmp_path) -> None:
    enc = VAELowKL(epochs=2, patience=1, validation_fraction=0.34, **FAST).fit(tiny_dataset)
    loaded = VAELowKL.load(enc.save(tmp_path / "e.pt"))
    assert loaded.history_ == enc.history_ and loaded.best_epoch_ == enc.best_epoch_


def test_a_failed_fit_leaves_the_encoder_unfitted(tiny_dataset) -> None:
    """The objective's preparation fails after the input statistics were learned (the dataset
    names an unknown task for supervised_task's target): the encoder must not look fitted."""
    import dataclasses

    import repbench
    from repbench.errors import RepbenchError

    unknown = dataclasses.replace(tiny_dataset, metadata={"task": "Nope-v0"})
    enc = repbench.encoders.get("supervised_task")(epochs=1, progress=False)
    with pytest.raises(DataError, match="needs the dataset's task to be registered"):
        enc.fit(unknown)
    assert not enc.is_fitted
    with pytest.raises(RepbenchError, match="is not fitted"):
        enc.encode(tiny_dataset.obs())
