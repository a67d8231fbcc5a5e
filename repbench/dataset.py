"""The dataset schema: episodes of aligned per-step arrays, saved compressed with a checksum.

Rows are ordered by (episode, step), so ``z[n]`` and ``z[n + 1]`` are successive steps whenever
``episode[n] == episode[n + 1]``. Every temporal metric and every auxiliary encoder loss uses
:meth:`Dataset.successor_index` to get pairs that never straddle two episodes.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from repbench.errors import DataError

SCHEMA_VERSION = 1

#: Observation modalities every task provides (``true_state`` is added as a privileged
#: modality so the ``oracle`` encoder can read it; other encoders must ignore it).
IMAGE, FT, PROPRIO, LAST_ACTION, TRUE_STATE = "image", "ft", "proprio", "last_action", "true_state"
#: A derived modality: the last :data:`HISTORY_STEPS` force/torque readings of the episode,
#: oldest first, flattened (``[N, HISTORY_STEPS * 6]``); before the episode's first step its
#: first reading is repeated. :meth:`Dataset.obs` derives it from ``ft``, and the agents'
#: environments add it (:class:`repbench.rl.wrappers.ForceHistory`) for encoders that read it.
FT_HISTORY = "ft_history"
HISTORY_STEPS = 4


@dataclass
class Dataset:
    """Aligned per-step arrays of one or more episodes.

    Attributes:
        observations: modality name → array with a leading step axis: ``image`` uint8
            ``[N, H, W, 3]``, ``ft`` float32 ``[N, 6]``, ``proprio`` float32 ``[N, P]``,
            ``last_action`` float32 ``[N, A]`` (the action that led into this step).
        action: float32 ``[N, A]``, the action taken at step n (leading to step n + 1).
        true_state: float32 ``[N, S]``, the paper's z°.
        reward: float32 ``[N]``, reward received for ``action``.
        success: bool ``[N]``, task success at step n.
        episode: int64 ``[N]``, episode id.
        step: int64 ``[N]``, step index within the episode.
        metadata: JSON-serializable provenance (task, version, seeds, config, library versions).
    """

    observations: dict[str, np.ndarray]
    action: np.ndarray
    true_state: np.ndarray
    reward: np.ndarray
    success: np.ndarray
    episode: np.ndarray
    step: np.ndarray
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.validate()

    # -- basic ---------------------------------------------------------------------------------
    def __len__(self) -> int:
        return int(self.episode.shape[0])

    @property
    def modalities(self) -> list[str]:
        return sorted(self.observations)

    @property
    def n_episodes(self) -> int:
        return int(np.unique(self.episode).size)

    def obs(self, index: np.ndarray | slice | None = None, *, with_true_state: bool = True
            ) -> dict[str, np.ndarray]:
        """Observation batch (modality → array) for ``index``; adds ``true_state`` and the
        derived ``ft_history`` (:data:`FT_HISTORY`)."""
        idx = slice(None) if index is None else index
        batch = {k: v[idx] for k, v in self.observations.items()}
        if FT in self.observations:
            rows = np.arange(len(self))[idx]
            history = stacked_history(self.observations[FT], self.episode, rows, HISTORY_STEPS)
            batch[FT_HISTORY] = history if np.ndim(rows) else history[0]
        if with_true_state:
            batch[TRUE_STATE] = self.true_state[idx]
        return batch

    def validate(self) -> None:
        """Raise :class:`DataError` naming the array at fault."""
        n = self.episode.shape[0] if isinstance(self.episode, np.ndarray) else -1
        arrays: dict[str, Any] = {
            "action": self.action, "true_state": self.true_state, "reward": self.reward,
            "success": self.success, "episode": self.episode, "step": self.step,
        }
        arrays.update({f"observations[{k!r}]": v for k, v in self.observations.items()})
        for name, arr in arrays.items():
            if not isinstance(arr, np.ndarray):
                raise DataError(f"dataset field {name} must be a numpy array, got {type(arr)}")
            if arr.shape[:1] != (n,):
                raise DataError(
                    f"dataset field {name} has {arr.shape[0] if arr.ndim else 0} rows but "
                    f"'episode' has {n}: all per-step arrays must be aligned"
                )
            if arr.dtype.kind == "f" and not np.isfinite(arr).all():
                raise DataError(f"dataset field {name} contains NaN or infinite values")
        if n == 0:
            raise DataError("dataset is empty: collect at least one episode")
        if self.true_state.ndim != 2 or self.action.ndim != 2:
            raise DataError("dataset 'true_state' and 'action' must be 2-D [steps, dim]")
        order = np.lexsort((self.step, self.episode))
        if not np.array_equal(order, np.arange(n)):
            raise DataError("dataset rows must be sorted by (episode, step)")

    # -- temporal structure --------------------------------------------------------------------
    def successor_index(self, offset: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Indices ``(i, j)`` with ``j`` the step ``offset`` after ``i`` in the same episode."""
        return successor_index(self.episode, self.step, offset)

    def episode_split(self, test_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """Row indices ``(train, test)`` holding out whole episodes (no leakage in time)."""
        return episode_split(self.episode, test_fraction, seed)

    def subset(self, index: np.ndarray) -> Dataset:
        """A new dataset of the given rows (index must keep (episode, step) order)."""
        return Dataset(
            observations={k: v[index] for k, v in self.observations.items()},
            action=self.action[index], true_state=self.true_state[index],
            reward=self.reward[index], success=self.success[index],
            episode=self.episode[index], step=self.step[index], metadata=dict(self.metadata),
        )

    @staticmethod
    def concatenate(datasets: list[Dataset]) -> Dataset:
        """Join datasets, renumbering episodes so they stay distinct."""
        if not datasets:
            raise DataError("cannot concatenate an empty list of datasets")
        offset, episodes = 0, []
        for d in datasets:
            _, inv = np.unique(d.episode, return_inverse=True)
            episodes.append(inv.astype(np.int64) + offset)
            offset += int(inv.max()) + 1
        keys = set(datasets[0].observations)
        for d in datasets[1:]:
            if set(d.observations) != keys:
                raise DataError("cannot concatenate datasets with different modalities")
        return Dataset(
            observations={k: np.concatenate([d.observations[k] for d in datasets]) for k in keys},
            action=np.concatenate([d.action for d in datasets]),
            true_state=np.concatenate([d.true_state for d in datasets]),
            reward=np.concatenate([d.reward for d in datasets]),
            success=np.concatenate([d.success for d in datasets]),
            episode=np.concatenate(episodes), step=np.concatenate([d.step for d in datasets]),
            metadata={"parts": [d.metadata for d in datasets]},
        )

    # -- files ---------------------------------------------------------------------------------
    def _arrays(self) -> dict[str, np.ndarray]:
        arrays = {f"obs.{k}": v for k, v in self.observations.items()}
        arrays.update(action=self.action, true_state=self.true_state, reward=self.reward,
                      success=self.success, episode=self.episode, step=self.step)
        return arrays

    def checksum(self) -> str:
        """SHA-256 over every array's name, dtype, shape and bytes."""
        h = hashlib.sha256()
        for name, arr in sorted(self._arrays().items()):
            h.update(f"{name}|{arr.dtype.str}|{arr.shape}".encode())
            h.update(np.ascontiguousarray(arr).tobytes())
        return h.hexdigest()

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write a compressed ``.npz`` with the metadata and checksum inside, atomically."""
        path = Path(path)
        meta = {"schema_version": SCHEMA_VERSION, "checksum": self.checksum(),
                "n_steps": len(self), "metadata": self.metadata}
        buf = io.BytesIO()
        np.savez_compressed(buf, __meta__=np.frombuffer(json.dumps(meta).encode(), np.uint8),
                            **self._arrays())
        tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as f:
            f.write(buf.getvalue())
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Dataset:
        """Load and validate a file written by :meth:`save`; a damaged file raises DataError."""
        path = Path(path)
        if not path.is_file():
            raise DataError(f"dataset file {path} does not exist")
        try:
            with np.load(path, allow_pickle=False) as z:
                raw = {k: z[k] for k in z.files}
        except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
            raise DataError(
                f"dataset file {path} is truncated or not a repbench dataset ({exc}); "
                "delete it and collect again"
            ) from None
        if "__meta__" not in raw:
            raise DataError(f"dataset file {path} has no metadata record; not a repbench dataset")
        meta = json.loads(raw.pop("__meta__").tobytes().decode())
        if meta.get("schema_version") != SCHEMA_VERSION:
            raise DataError(
                f"dataset file {path} has schema version {meta.get('schema_version')}, this "
                f"repbench reads {SCHEMA_VERSION}; collect it again"
            )
        required = {"action", "true_state", "reward", "success", "episode", "step"}
        missing = required - raw.keys()
        if missing:
            raise DataError(f"dataset file {path} lacks arrays {sorted(missing)}")
        ds = cls(
            observations={k[4:]: v for k, v in raw.items() if k.startswith("obs.")},
            action=raw["action"], true_state=raw["true_state"], reward=raw["reward"],
            success=raw["success"], episode=raw["episode"], step=raw["step"],
            metadata=meta.get("metadata", {}),
        )
        if ds.checksum() != meta.get("checksum"):
            raise DataError(
                f"dataset file {path} fails its checksum (modified or mismatched arrays); "
                "delete it and collect again"
            )
        return ds


def stacked_history(values: np.ndarray, episode: np.ndarray, rows: np.ndarray | int,
                    steps: int) -> np.ndarray:
    """For each of ``rows``, the ``steps`` values of its episode ending at it, oldest first and
    flattened (``[len(rows), steps * D]``); before the episode's first row its first value is
    repeated. Rows must be sorted by episode and step, an episode's steps consecutive."""
    values = np.asarray(values)
    episode = np.asarray(episode)
    rows = np.atleast_1d(np.asarray(rows, np.int64))
    if steps < 1:
        raise DataError(f"history steps must be >= 1, got {steps}")
    n = episode.shape[0]
    new = np.r_[True, episode[1:] != episode[:-1]] if n else np.zeros(0, bool)
    start = np.maximum.accumulate(np.where(new, np.arange(n), 0))
    lags = np.arange(steps - 1, -1, -1)
    src = np.maximum(rows[:, None] - lags[None, :], start[rows][:, None])
    return values[src].reshape(rows.size, -1)


def successor_index(episode: np.ndarray, step: np.ndarray | None = None, offset: int = 1
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Pairs ``(i, i + offset)`` of rows in the same episode (rows sorted by episode, step)."""
    if offset < 1:
        raise DataError(f"offset must be >= 1, got {offset}")
    episode = np.asarray(episode)
    n = episode.shape[0]
    if n <= offset:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    i = np.arange(n - offset)
    same = episode[i] == episode[i + offset]
    if step is not None:
        same &= np.asarray(step)[i + offset] - np.asarray(step)[i] == offset
    i = i[same]
    return i, i + offset


def episode_split(episode: np.ndarray, test_fraction: float, seed: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Row indices (train, test) with whole episodes held out; at least one episode each side."""
    if not 0.0 < test_fraction < 1.0:
        raise DataError(f"test_fraction must be in (0, 1), got {test_fraction}")
    ids = np.unique(episode)
    if ids.size < 2:
        raise DataError(
            f"an episode-wise hold-out needs at least 2 episodes, got {ids.size}; "
            "collect more episodes"
        )
    rng = np.random.default_rng(seed)
    n_test = min(max(1, round(test_fraction * ids.size)), ids.size - 1)
    test_ids = rng.choice(ids, size=n_test, replace=False)
    is_test = np.isin(episode, test_ids)
    return np.flatnonzero(~is_test), np.flatnonzero(is_test)


def as_observation_batch(observations: Mapping[str, Any], required: tuple[str, ...],
                         owner: str) -> dict[str, np.ndarray]:
    """Check a batch has the ``required`` modalities with one common leading size."""
    missing = [m for m in required if m not in observations]
    if missing:
        raise DataError(
            f"{owner} needs observation modalities {list(required)} but the batch lacks "
            f"{missing} (it has {sorted(observations)})"
        )
    batch = {m: np.asarray(observations[m]) for m in required}
    sizes = {m: a.shape[0] if a.ndim else -1 for m, a in batch.items()}
    if len(set(sizes.values())) != 1 or -1 in sizes.values():
        raise DataError(f"{owner}: modalities have different batch sizes {sizes}")
    return batch
