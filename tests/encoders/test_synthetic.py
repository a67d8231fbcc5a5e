"""The synthetic dataset generator: schema, determinism, speed-relevant size, content."""

from __future__ import annotations

import time

import numpy as np
import pytest

from repbench.dataset import Dataset
from repbench.errors import DataError
from repbench.testing.synthetic import SUCCESS_RADIUS, synthetic_dataset


def test_schema_and_determinism(tmp_path) -> None:
    t0 = time.perf_counter()
    d = synthetic_dataset()
    elapsed = time.perf_counter() - t0
    assert len(d) == 120 and d.n_episodes == 4
    assert d.observations["image"].shape == (120, 64, 64, 3)
    assert d.observations["image"].dtype == np.uint8
    assert d.observations["ft"].shape == (120, 6) and d.observations["ft"].dtype == np.float32
    assert d.observations["proprio"].shape == (120, 4)
    assert d.observations["last_action"].shape == d.action.shape == (120, 2)
    assert d.true_state.shape == (120, 6)
    assert d.checksum() == synthetic_dataset().checksum()
    assert d.checksum() != synthetic_dataset(seed=1).checksum()
    assert Dataset.load(d.save(tmp_path / "d.npz")).checksum() == d.checksum()
    # last_action at n is the action at n-1 within an episode, zero at its start
    i, j = d.successor_index()
    assert np.array_equal(d.observations["last_action"][j], d.action[i])
    assert np.all(d.observations["last_action"][d.step == 0] == 0)
    assert elapsed < 5.0  # generous: a gross regression guard, not a benchmark


def test_content_follows_the_true_state() -> None:
    d = synthetic_dataset(n_episodes=6, steps=30)
    pos, hole = d.true_state[:, :2], d.true_state[:, 4:]
    dist = np.linalg.norm(hole - pos, axis=1)
    assert np.array_equal(d.success, dist < SUCCESS_RADIUS) and d.success.any()
    assert not d.success.all()
    # the dark disk's centroid moves with hole - position
    dark = d.observations["image"].mean(-1) < 80
    visible = dark.sum((1, 2)) > 20
    _, xs = np.mgrid[0:64, 0:64]
    cx = (dark * xs).sum((1, 2))[visible] / dark.sum((1, 2))[visible]
    rel_x = (hole - pos)[visible, 0]
    assert np.corrcoef(cx, rel_x)[0, 1] > 0.95
    # force spikes near the hole
    contact = d.observations["ft"][:, 2]
    assert contact[dist < 0.1].mean() > 5 * max(contact[dist > 0.5].mean(), 0.5)
    # proprio is the end-effector position and velocity plus small noise
    np.testing.assert_allclose(d.observations["proprio"], d.true_state[:, :4], atol=0.06)


def test_bad_arguments() -> None:
    with pytest.raises(DataError, match="steps >= 2"):
        synthetic_dataset(steps=1)
    with pytest.raises(DataError, match="image_size >= 8"):
        synthetic_dataset(image_size=4)
