"""The agent API: train an RL agent on ``task env ∘ frozen encoder`` and evaluate it."""

from __future__ import annotations

import abc
from dataclasses import asdict, dataclass, field
from typing import Any, ClassVar

from repbench.encoder import Encoder
from repbench.task import Task


@dataclass
class AgentResult:
    """What one (task, encoder, agent, seed) training run produced.

    Attributes:
        curve_steps: environment steps at which the learning curve was sampled.
        curve_return: mean episode return at those steps.
        curve_success: success rate at those steps.
        eval_return: mean return over the fixed evaluation episodes.
        eval_success_rate: success rate over the fixed evaluation episodes.
        eval_episode_returns: the return of each evaluation episode.
        train_steps: environment steps trained.
        wall_time_s: training + evaluation wall time.
        steps_per_s: training environment steps per second.
    """

    curve_steps: list[int]
    curve_return: list[float]
    curve_success: list[float]
    eval_return: float
    eval_success_rate: float
    eval_episode_returns: list[float]
    train_steps: int
    wall_time_s: float
    steps_per_s: float
    extras: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> AgentResult:
        return cls(**d)


class Agent(abc.ABC):
    """Base class of all agents. The constructor stores hyperparameters only."""

    #: Declared version of what this plugin computes. Part of every stage key and result record
    #: in place of the source code: bump it when a change alters results; editing docstrings or
    #: refactoring needs no bump. Older records then show as stale
    #: (:mod:`repbench.pipeline.records`).
    version: ClassVar[int] = 0

    @abc.abstractmethod
    def train(self, task: Task, encoder: Encoder, *, train_steps: int, seed: int,
              eval_episodes: int, curve_points: int = 5, progress: bool = True
              ) -> AgentResult:
        """Train on ``task`` observed through frozen ``encoder`` (μ_z ⊕ robot state) and
        evaluate on fixed episodes (the same for every encoder)."""
