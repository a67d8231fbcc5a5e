"""Datasets of the peg-in-hole task: determinism, contact share, files, conformance, preview."""

from __future__ import annotations

import numpy as np
import pytest

from repbench.dataset import Dataset
from repbench.errors import ConfigError
from repbench.preview import render_preview
from repbench.testing import check_task
from repbench_tasks.collection import collect
from repbench_tasks.env import PegInHoleEnv
from repbench_tasks.peg_in_hole import PegInHoleTask


@pytest.fixture(scope="module")
def small() -> Dataset:
    return PegInHoleTask().collect("random", n_episodes=2, steps_per_episode=20, seed=3,
                                   progress=False)


def test_same_seed_same_arrays_other_seed_differs(small: Dataset, env: PegInHoleEnv,
                                                  physics_env: PegInHoleEnv) -> None:
    # another environment instance, used before: the same arrays, images included
    env.reset(seed=11, options={"start": "above"})
    env.step(np.array([1.0, -1.0, 0.5]))
    again, _ = collect(env, "random", n_episodes=2, steps_per_episode=20, seed=3,
                       progress=False)
    assert again.checksum() == small.checksum()
    other, _ = collect(physics_env, "random", n_episodes=1, steps_per_episode=20, seed=4,
                       progress=False)
    assert not np.array_equal(other.action, small.action[:20])


def test_random_dataset_is_backwards_exploration_with_contact(small: Dataset) -> None:
    assert small.metadata["kind"] == "random" and small.metadata["task"] == "PegInHole-v0"
    assert 0 <= small.metadata["contact_share"] <= 1
    assert small.success[small.step == 0].all(), "every episode starts inserted"
    # hole positions cycle through the grid by episode index
    np.testing.assert_allclose(small.true_state[small.episode == 0, -2], -0.08)
    np.testing.assert_allclose(small.true_state[small.episode == 1, -2:], [[-0.08, -0.04]] * 20)
    assert {"numpy", "robosuite", "mujoco"} <= set(small.metadata["library_versions"])
    # last_action is the previous row's action within an episode
    i, j = small.successor_index()
    np.testing.assert_array_equal(small.observations["last_action"][j], small.action[i])


def test_random_exploration_has_a_real_contact_share(physics_env: PegInHoleEnv) -> None:
    """3 x 100 steps: contact share in the band measured over seeds 0-11 (0.26-0.38), free
    space still the majority, about 0 N in free motion and tens of newtons in contact."""
    _, stats = collect(physics_env, "random", n_episodes=3, steps_per_episode=100, seed=0,
                       progress=False)
    assert 0.2 < stats["contact_share"] < 0.5, stats
    assert stats["free_space_share"] >= 0.4 and stats["success_share"] < 0.5, stats
    q = stats["ft_force_quantiles"]
    assert q["q10"] < 1.0 < 10.0 < q["q90"], f"free ~0 N and contact tens of N expected: {q}"


@pytest.mark.slow
def test_approach_phases_raise_the_contact_share(physics_env: PegInHoleEnv) -> None:
    """Pure backwards exploration (approach phases off) touches much less: 0.18 vs 0.38."""
    shares = [collect(physics_env, "random", n_episodes=3, steps_per_episode=100, seed=0,
                      progress=False, explorer_params=params)[1]["contact_share"]
              for params in ({}, {"p_approach": 0.0})]
    assert shares[0] > shares[1] + 0.1, shares


def test_dataset_save_load_roundtrip(small: Dataset, tmp_path) -> None:
    path = small.save(tmp_path / "peg.npz")
    back = Dataset.load(path)
    assert back.checksum() == small.checksum()
    assert back.metadata["contact_share"] == small.metadata["contact_share"]
    assert back.observations["image"].dtype == np.uint8


def test_on_policy_collection_calls_the_policy_with_true_state(physics_env: PegInHoleEnv
                                                               ) -> None:
    seen = []

    def policy(obs):
        assert obs["image"].shape == (64, 64, 3) and "true_state" in obs
        seen.append(obs["true_state"])
        return np.array([0.0, 0.0, -0.2], np.float32)

    ds, _ = collect(physics_env, "on_policy", n_episodes=1, steps_per_episode=5, seed=0,
                    policy=policy, progress=False)
    assert len(seen) == 5 and len(ds) == 5
    np.testing.assert_array_equal(ds.action, np.tile([0.0, 0.0, -0.2], (5, 1)).astype(np.float32))
    with pytest.raises(ConfigError, match="policy"):
        PegInHoleTask().collect("on_policy", n_episodes=1, steps_per_episode=2, seed=0)
    with pytest.raises(ConfigError, match="kind"):
        PegInHoleTask().collect("expert", n_episodes=1, steps_per_episode=2, seed=0)


def test_conformance_by_name() -> None:
    check_task("PegInHole-v0", n_steps=3, camera=False)


@pytest.mark.slow
def test_preview_contact_sheet(tmp_path) -> None:
    out = render_preview(PegInHoleTask(), tmp_path / "preview.png", n_frames=6, steps=12)
    assert out.is_file() and out.stat().st_size > 5000
