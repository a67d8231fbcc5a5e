"""The task API: a gymnasium environment factory, the true state z°, and data collection.

A task's environment returns dict observations with the modalities ``image`` (uint8 HxWx3),
``ft`` (6-axis wrist force/torque), ``proprio`` (robot position and velocity) and
``last_action``; ``info["true_state"]`` carries z° and ``info["is_success"]`` the success flag at
every ``reset`` and ``step``.
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from repbench.dataset import FT, IMAGE, PROPRIO, Dataset
from repbench.errors import DataError

#: A data-collection policy: observation batch of one step (modality → array, with
#: ``true_state`` added) → action.
Policy = Callable[[Mapping[str, np.ndarray]], np.ndarray]


def action_vector(action: Any, size: int, owner: str, dtype: Any = np.float64) -> np.ndarray:
    """``action`` as a flat vector of ``size`` values; :class:`~repbench.errors.DataError`
    naming ``owner`` (e.g. ``PegInHoleEnv.step``), the expected shape and the one passed when
    it holds another number of values (any shape with ``size`` values, such as ``(1, size)``
    from a batch of one, is accepted as before)."""
    try:
        arr = np.asarray(action, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{owner}: action must be {size} numbers (expected shape ({size},)), "
                        f"got {type(action).__name__} {action!r:.60} ({exc})") from None
    if arr.size != size:
        raise DataError(f"{owner}: action has the wrong shape: expected shape ({size},) "
                        f"({size} values in [-1, 1]), got shape {arr.shape}")
    return arr.reshape(size)


class Task(abc.ABC):
    """Base class of all tasks. The constructor stores hyperparameters only."""

    #: Declared version of what this plugin computes. Part of every stage key and result record
    #: in place of the source code: bump it when a change alters results; editing docstrings or
    #: refactoring needs no bump. Older records then show as stale
    #: (:mod:`repbench.pipeline.records`).
    version: ClassVar[int] = 0

    #: Versioned id, as in gymnasium (``PegInHole-v0``).
    task_id: ClassVar[str]

    @classmethod
    def sensing(cls) -> str:
        """What the observations carry by default, in a few words (``repbench list tasks``);
        empty when the task does not say."""
        return ""

    @abc.abstractmethod
    def make_env(self, seed: int | None = None, **overrides: Any) -> Any:
        """Build a fresh gymnasium environment (dict observations, continuous actions)."""

    @abc.abstractmethod
    def true_state(self, env: Any) -> np.ndarray:
        """The true state z° of ``env`` now, float32 [S]."""

    @abc.abstractmethod
    def collect(self, kind: str, *, n_episodes: int, steps_per_episode: int, seed: int,
                policy: Policy | None = None, progress: bool = True) -> Dataset:
        """Collect a dataset: ``kind="random"`` (backwards exploration from the goal) or
        ``kind="on_policy"`` (``policy`` required)."""

    def robot_state(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
        """The robot-state part of an observation, appended to μ_z for the RL agent."""
        return np.asarray(observation[PROPRIO], dtype=np.float32)

    def make_agent_env(self, seed: int | None = None, *,
                       modalities: Sequence[str] = (IMAGE, FT, PROPRIO)) -> Any:
        """The environment an RL agent trains in, given the modalities its encoder reads.

        Tasks that can skip work for unread modalities (rendering when no encoder reads the
        ``image``) override this; the default is :meth:`make_env`.
        """
        return self.make_env(seed=seed)

    def evaluation_resets(self, n: int) -> list[dict[str, Any]]:
        """Keyword arguments of ``env.reset`` for ``n`` fixed evaluation episodes (the same for
        every encoder and agent). Default: reset seeds ``10_000 + i``; tasks override this to
        cover their initial conditions systematically."""
        return [{"seed": 10_000 + i} for i in range(n)]

    def task_state(self, observations: Mapping[str, np.ndarray]) -> np.ndarray:
        """The task-frame state of an observation batch (with ``true_state``), float32 [N, K].

        The same information as z° for the task's goal, in the form a controller needs (for
        the peg-in-hole: the peg tip's offset from the hole's opening and the tip velocity).
        The ``oracle_task`` encoder exposes it, the privileged agent observes it, and metrics
        that ask "how much of what the agent needs is decodable from z" predict it. Tasks
        without one raise ``NotImplementedError``.
        """
        raise NotImplementedError(
            f"task {getattr(self, 'task_id', type(self).__name__)} defines no task_state; "
            "implement Task.task_state to use the privileged agent and task-frame metrics")

    def get_params(self) -> dict[str, Any]:
        import inspect

        sig = inspect.signature(type(self).__init__)
        return {p: getattr(self, p) for p in sig.parameters if p != "self"
                and sig.parameters[p].kind not in (inspect.Parameter.VAR_POSITIONAL,
                                                   inspect.Parameter.VAR_KEYWORD)}
