"""Datasets of the peg-in-hole task: determinism, contact share, files, conformance, preview."""

from __future__ import annotations

import numpy as np
import pytest
from repbench_tasks.peg_in_hole import PegInHoleTask

from repbench.dataset import Dataset
from repbench.errors import ConfigError
from repbench.preview import render_preview
from repbench.testing import check_task


@pytest.fixture(scope="module")
def small() -> Dataset:
    return PegInHoleTask().collect("random", n_episodes=2, steps_per_episode=20, seed=3,
                                   progress=False)


def test_same_seed_same_arrays_other_seed_differs(small: Dataset) -> None:
    task = PegInHoleTask()
    again = task.collect("random", n_episodes=2, steps_per_episode=20, seed=3, progress=False)
    assert again.checksum() == small.checksum()
    other = task.collect("random", n_episodes=1, steps_per_episode=20, seed=4, progress=False)
    assert not np.array_equal(other.action, small.action[:20])


def test_random_dataset_is_backwards_exploration_with_contact(small: Dataset) -> None:
    assert small.metadata["kind"] == "random" and small.metadata["task"] == "PegInHole-v0"
    share = small.metadata["contact_share"]
    assert 0.1 < share < 0.95, f"contact share {share}"
    assert small.success[small.step == 0].all(), "every episode starts inserted"
    # hole positions cycle through the grid by episode index
    np.testing.assert_allclose(small.true_state[small.episode == 0, -2], -0.08)
    np.testing.assert_allclose(small.true_state[small.episode == 1, -2:], [[-0.08, -0.04]] * 20)
    assert {"numpy", "robosuite", "mujoco"} <= set(small.metadata["library_versions"])
    # last_action is the previous row's action within an episode
    i, j = small.successor_index()
    np.testing.assert_array_equal(small.observations["last_action"][j], small.action[i])


def test_dataset_save_load_roundtrip(small: Dataset, tmp_path) -> None:
    path = small.save(tmp_path / "peg.npz")
    back = Dataset.load(path)
    assert back.checksum() == small.checksum()
    assert back.metadata["contact_share"] == small.metadata["contact_share"]
    assert back.observations["image"].dtype == np.uint8


def test_on_policy_collection_calls_the_policy_with_true_state() -> None:
    seen = []

    def policy(obs):
        assert obs["image"].shape == (64, 64, 3) and "true_state" in obs
        seen.append(obs["true_state"])
        return np.array([0.0, 0.0, -0.2], np.float32)

    ds = PegInHoleTask(camera=False).collect("on_policy", n_episodes=1, steps_per_episode=5,
                                             seed=0, policy=policy, progress=False)
    assert len(seen) == 5 and len(ds) == 5
    np.testing.assert_array_equal(ds.action, np.tile([0.0, 0.0, -0.2], (5, 1)).astype(np.float32))
    with pytest.raises(ConfigError, match="policy"):
        PegInHoleTask().collect("on_policy", n_episodes=1, steps_per_episode=2, seed=0)
    with pytest.raises(ConfigError, match="kind"):
        PegInHoleTask().collect("expert", n_episodes=1, steps_per_episode=2, seed=0)


def test_conformance_by_name() -> None:
    check_task("PegInHole-v0", n_steps=3, camera=False)


def test_preview_contact_sheet(tmp_path) -> None:
    out = render_preview(PegInHoleTask(), tmp_path / "preview.png", n_frames=6, steps=20)
    assert out.is_file() and out.stat().st_size > 5000
