"""The dataset schema: alignment, temporal pairs, episode splits, files with checksums."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from repbench.dataset import Dataset, episode_split, successor_index
from repbench.errors import DataError


def _dataset(n_episodes: int = 3, steps: int = 5) -> Dataset:
    n = n_episodes * steps
    rng = np.random.default_rng(0)
    return Dataset(
        observations={"image": rng.integers(0, 255, (n, 8, 8, 3), dtype=np.uint8),
                      "ft": rng.normal(size=(n, 6)).astype(np.float32),
                      "proprio": rng.normal(size=(n, 4)).astype(np.float32)},
        action=rng.normal(size=(n, 3)).astype(np.float32),
        true_state=rng.normal(size=(n, 5)).astype(np.float32),
        reward=rng.normal(size=n).astype(np.float32), success=np.zeros(n, bool),
        episode=np.repeat(np.arange(n_episodes), steps),
        step=np.tile(np.arange(steps), n_episodes), metadata={"task": "test"})


def test_successor_pairs_never_cross_episodes() -> None:
    ds = _dataset(3, 5)
    i, j = ds.successor_index()
    assert len(i) == 3 * 4
    assert np.all(ds.episode[i] == ds.episode[j]) and np.all(ds.step[j] == ds.step[i] + 1)
    i3, j3 = successor_index(ds.episode, ds.step, 3)
    assert len(i3) == 3 * 2 and np.all(ds.step[j3] - ds.step[i3] == 3)


def test_episode_split_holds_out_whole_episodes() -> None:
    ds = _dataset(10, 4)
    train, test = episode_split(ds.episode, 0.3, seed=1)
    assert set(ds.episode[train]).isdisjoint(ds.episode[test])
    assert len(set(ds.episode[test])) == 3 and len(train) + len(test) == len(ds)
    with pytest.raises(DataError, match="at least 2 episodes"):
        episode_split(np.zeros(10), 0.3, 0)


def test_save_load_roundtrip(tmp_path: Path) -> None:
    ds = _dataset()
    ds.save(tmp_path / "d.npz")
    back = Dataset.load(tmp_path / "d.npz")
    assert back.checksum() == ds.checksum() and back.metadata == {"task": "test"}
    assert back.obs([0, 1])["true_state"].shape == (2, 5)


def test_truncated_file_is_a_clear_error(tmp_path: Path) -> None:
    p = _dataset().save(tmp_path / "d.npz")
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
    with pytest.raises(DataError, match="truncated or not a repbench dataset"):
        Dataset.load(p)


def test_checksum_mismatch_detected(tmp_path: Path) -> None:
    ds = _dataset()
    p = ds.save(tmp_path / "d.npz")
    with np.load(p) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["reward"] = arrays["reward"] + 1.0
    np.savez_compressed(p, **arrays)
    with pytest.raises(DataError, match="fails its checksum"):
        Dataset.load(p)


@pytest.mark.parametrize("mutate, match", [
    (lambda d: d.__setattr__("reward", d.reward[:-1]), "reward has 14 rows"),
    (lambda d: d.true_state.__setitem__((0, 0), np.nan), "true_state contains NaN"),
    (lambda d: d.__setattr__("step", d.step[::-1].copy()), "sorted by"),
])
def test_invalid_arrays_rejected(mutate, match: str) -> None:  # type: ignore[no-untyped-def]
    ds = _dataset()
    mutate(ds)
    with pytest.raises(DataError, match=match):
        ds.validate()


def test_concatenate_keeps_episodes_distinct() -> None:
    both = Dataset.concatenate([_dataset(2, 3), _dataset(3, 3)])
    assert both.n_episodes == 5 and len(both) == 15


def test_stacked_history_known_answer_and_the_derived_modality() -> None:
    from repbench.dataset import FT_HISTORY, HISTORY_STEPS, stacked_history
    from repbench.testing.synthetic import synthetic_dataset

    values = np.array([[1.0], [2.0], [3.0], [10.0], [20.0]])
    episode = np.array([0, 0, 0, 1, 1])
    out = stacked_history(values, episode, np.arange(5), 3)
    np.testing.assert_array_equal(out, [[1, 1, 1], [1, 1, 2], [1, 2, 3], [10, 10, 10],
                                        [10, 10, 20]])
    np.testing.assert_array_equal(stacked_history(values, episode, np.array([4, 1]), 2),
                                  [[10, 20], [1, 2]])
    d = synthetic_dataset(n_episodes=2, steps=5, seed=0)
    ft = d.observations["ft"]
    batch = d.obs(slice(4, 7))  # the last step of episode 0, the first two of episode 1
    assert batch[FT_HISTORY].shape == (3, HISTORY_STEPS * 6)
    np.testing.assert_array_equal(batch[FT_HISTORY][0], ft[1:5].reshape(-1))
    np.testing.assert_array_equal(batch[FT_HISTORY][1], np.tile(ft[5], HISTORY_STEPS))
    np.testing.assert_array_equal(d.obs(6)[FT_HISTORY], batch[FT_HISTORY][2])  # unbatched
    assert FT_HISTORY not in d.observations  # derived, never stored
