"""The agent's view of a task: ``μ_z`` of a frozen encoder concatenated with the robot state.

:class:`FrozenEncoderObservation` wraps a task environment (dict observations, ``true_state``
in ``info``) and returns the flat float32 vector the paper's agents observe (§IV):
``concat(encoder.encode(obs)[0], task.robot_state(obs))``. The encoder runs in eval mode under
``torch.no_grad``; every observation is checked (shape, NaN) so a broken encoder fails on the
first step with a message naming it, not hours later.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from repbench.dataset import FT, FT_HISTORY, HISTORY_STEPS, TRUE_STATE
from repbench.encoder import Encoder
from repbench.errors import ConfigError, DataError
from repbench.task import Task


def encoder_label(encoder: Encoder) -> str:
    """A short name for messages: the class name (the registry name is not known here)."""
    return type(encoder).__name__


def freeze_encoder(encoder: Encoder) -> Encoder:
    """Put every torch module held by ``encoder`` in eval mode and stop its gradients."""
    try:
        import torch
    except ImportError:  # pragma: no cover - torch is a dependency
        return encoder
    for value in vars(encoder).values():
        if isinstance(value, torch.nn.Module):
            value.eval()
            for p in value.parameters():
                p.requires_grad_(False)
    return encoder


def check_encoder_ready(encoder: Encoder) -> None:
    """Raise ConfigError unless ``encoder`` is a fitted :class:`repbench.Encoder`."""
    if not isinstance(encoder, Encoder):
        raise ConfigError(f"expected a repbench.Encoder for the agent, got {type(encoder)!r}")
    if not encoder.is_fitted:
        raise ConfigError(
            f"encoder {encoder_label(encoder)} is not fitted: call fit(dataset) (or load a "
            "fitted one) before training an agent on it"
        )


def batch_one(observation: Mapping[str, Any], true_state: np.ndarray | None
              ) -> dict[str, np.ndarray]:
    """One step's observation dict → a batch of one (leading axis), with ``true_state``."""
    batch = {k: np.asarray(v)[None] for k, v in observation.items()}
    if true_state is not None:
        batch[TRUE_STATE] = np.asarray(true_state, np.float32)[None]
    return batch


class ObservationEncoder:
    """``observation dict (+ true_state) → μ_z ⊕ robot state`` with the checks, batch of one.

    Shared by the gymnasium wrapper (training, evaluation) and the policy used for on-policy
    data collection, so both see exactly the same features.
    """

    def __init__(self, task: Task, encoder: Encoder, expected_dim: int | None = None) -> None:
        check_encoder_ready(encoder)
        self.task = task
        self.encoder = freeze_encoder(encoder)
        self.latent_dim = int(encoder.latent_dim)
        self.expected_dim = expected_dim
        self.robot_dim: int | None = None

    @property
    def name(self) -> str:
        return encoder_label(self.encoder)

    def __call__(self, observation: Mapping[str, Any], true_state: np.ndarray | None
                 ) -> np.ndarray:
        """Features (float32 ``[latent_dim + robot_dim]``) of one unbatched observation."""
        return self.encode_batch(batch_one(observation, true_state))[0]

    def encode_batch(self, batch: Mapping[str, Any]) -> np.ndarray:
        """Features ``[N, latent_dim + robot_dim]`` of an observation batch (with
        ``true_state``), encoded in one ``encoder.encode`` call."""
        import torch

        for key, value in batch.items():
            arr = np.asarray(value)
            if arr.dtype.kind == "f" and not np.isfinite(arr).all():
                raise DataError(
                    f"observation modality {key!r} of task {self.task.task_id} contains NaN or "
                    f"inf; encoder {self.name} cannot encode it: fix the task/sensor"
                )
        n = len(next(iter(batch.values())))
        with torch.no_grad():
            z = np.asarray(self.encoder.encode(batch))
        if z.shape != (n, self.latent_dim):
            raise DataError(
                f"encoder {self.name} returned shape {z.shape} for {n} observation(s) but its "
                f"latent_dim is {self.latent_dim}: encode must return [N, latent_dim]"
            )
        if not np.isfinite(z).all():
            raise DataError(
                f"encoder {self.name} returned NaN or inf for an observation of task "
                f"{self.task.task_id}: the encoder is broken (diverged training?); refit it"
            )
        robot = np.stack([
            np.asarray(self.task.robot_state({k: v[i] for k, v in batch.items()
                                              if k != TRUE_STATE}), np.float32).reshape(-1)
            for i in range(n)])
        if not np.isfinite(robot).all():
            raise DataError(
                f"robot state of task {self.task.task_id} contains NaN or inf; the agent on "
                f"encoder {self.name} cannot use it"
            )
        if self.robot_dim is None:
            self.robot_dim = robot.shape[1]
        features = np.concatenate([z.astype(np.float32), robot], axis=1)
        if self.expected_dim is not None and features.shape[1] != self.expected_dim:
            raise ConfigError(
                f"encoder {self.name} gives latent_dim {self.latent_dim} + robot state "
                f"{robot.shape[1]} = {features.shape[1]} features but the agent was built for "
                f"{self.expected_dim}: use the encoder the agent was trained with"
            )
        return features


class FrozenEncoderObservation(gym.Wrapper):
    """Gymnasium wrapper: dict observation → float32 ``μ_z ⊕ robot state`` (a flat Box).

    The observation of ``reset`` and ``step`` is encoded together with ``info["true_state"]``
    (so the ``oracle`` encoder works). ``info`` is passed through unchanged.

    Args:
        env: a task environment (dict observations, ``true_state`` in ``info``).
        task: the task that built ``env`` (for ``robot_state`` and messages).
        encoder: a fitted encoder; it is put in eval mode and used without gradients.
        expected_dim: if given, the feature size the agent was built for (checked every step).
    """

    def __init__(self, env: gym.Env, task: Task, encoder: Encoder,
                 expected_dim: int | None = None) -> None:
        super().__init__(env)
        self.features = ObservationEncoder(task, encoder, expected_dim)
        obs, info = env.reset(seed=0)  # probe once for the robot-state size
        dim = self.features(obs, info.get(TRUE_STATE)).size
        self.observation_space = spaces.Box(-np.inf, np.inf, (dim,), np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        return self.features(obs, info.get(TRUE_STATE)), info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self.features(obs, info.get(TRUE_STATE)), reward, terminated, truncated, info


def make_encoded_env(task: Task, encoder: Encoder, seed: int | None = None,
                     expected_dim: int | None = None) -> gym.Env:
    """``task.make_agent_env(seed)`` observed through ``encoder``; truncated at
    ``task.horizon``. The environment skips rendering when the encoder does not read the
    image (:meth:`repbench.Task.make_agent_env`).

    Also wrapped in ``gymnasium.wrappers.TimeLimit`` when the task has a ``horizon``
    (harmless when the environment already truncates there itself).
    """
    env = agent_env(task, encoder.required_modalities, seed)
    return FrozenEncoderObservation(env, task, encoder, expected_dim)


def agent_env(task: Task, modalities: Any, seed: int | None = None) -> gym.Env:
    """``task.make_agent_env`` for an encoder reading ``modalities`` (no rendering when it
    does not read the image), truncated at ``task.horizon``; with the derived ``ft_history``
    modality added (:class:`ForceHistory`) when the encoder reads it."""
    modalities = tuple(modalities)
    env = task.make_agent_env(seed=seed, modalities=modalities)
    if FT_HISTORY in modalities:
        env = ForceHistory(env)
    horizon = getattr(task, "horizon", None)
    if horizon:
        env = gym.wrappers.TimeLimit(env, max_episode_steps=int(horizon))
    return env


class ForceHistory(gym.Wrapper):
    """Adds ``ft_history`` to a dict-observation environment: the episode's last
    :data:`~repbench.dataset.HISTORY_STEPS` ``ft`` readings, oldest first, flattened, the
    first reading repeated before the episode's start — what :meth:`repbench.Dataset.obs`
    derives from a stored episode (:func:`repbench.dataset.stacked_history`)."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        ft = env.observation_space[FT]
        self.observation_space = spaces.Dict({
            **env.observation_space.spaces,
            FT_HISTORY: spaces.Box(-np.inf, np.inf, (HISTORY_STEPS * ft.shape[0],),
                                   np.float32)})
        self._readings: list[np.ndarray] = []

    def _add(self, obs: dict[str, Any], first: bool) -> dict[str, Any]:
        ft = np.asarray(obs[FT], np.float32)
        self._readings = ([ft] * HISTORY_STEPS if first
                          else [*self._readings[1:], ft])
        return {**obs, FT_HISTORY: np.concatenate(self._readings)}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, Any], dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        return self._add(obs, first=True), info

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._add(obs, first=False), reward, terminated, truncated, info


class TrueStateInObservation(gym.Wrapper):
    """Adds ``info["true_state"]`` to the dict observation (so vectorised environments,
    which return only observations on auto-reset, still carry it to the encoder)."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        _, info = env.reset(seed=0)  # probe the true-state size
        size = np.asarray(info[TRUE_STATE]).shape
        self.observation_space = spaces.Dict({
            **env.observation_space.spaces,
            TRUE_STATE: spaces.Box(-np.inf, np.inf, size, np.float32)})

    @staticmethod
    def _add(obs: dict[str, Any], info: dict[str, Any]) -> dict[str, Any]:
        return {**obs, TRUE_STATE: np.asarray(info[TRUE_STATE], np.float32)}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, Any], dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        return self._add(obs, info), info

    def step(self, action: Any) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._add(obs, info), reward, terminated, truncated, info


def make_raw_env(task: Task, seed: int | None = None,
                 modalities: Any = ("image", "ft", "proprio")) -> gym.Env:
    """:func:`agent_env` with ``true_state`` in the observation dict (the per-process part of
    a vectorised, batch-encoded environment)."""
    return TrueStateInObservation(agent_env(task, modalities, seed))


def batch_encoded_vec_env(venv: Any, task: Task, encoder: Encoder) -> Any:
    """Wrap an SB3 VecEnv of :func:`make_raw_env` environments so that all ``n_envs``
    observations of a step are encoded in one batch in this process (on the encoder's device:
    one GPU call per step instead of one per environment), terminal observations included."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class BatchEncodedVecEnv(VecEnvWrapper):
        """μ_z ⊕ robot state for a whole VecEnv step, in one ``encode`` call."""

        def __init__(self) -> None:
            self.features = ObservationEncoder(task, encoder)
            probe = venv.reset()
            dim = self.features.encode_batch(probe).shape[1]
            super().__init__(venv, observation_space=spaces.Box(-np.inf, np.inf, (dim,),
                                                                np.float32))

        def reset(self) -> np.ndarray:
            return self.features.encode_batch(self.venv.reset())

        def step_wait(self) -> Any:
            obs, rewards, dones, infos = self.venv.step_wait()
            features = self.features.encode_batch(obs)
            for info in infos:
                if "terminal_observation" in info:
                    term = {k: np.asarray(v)[None] for k, v in
                            info["terminal_observation"].items()}
                    info["terminal_observation"] = self.features.encode_batch(term)[0]
            return features, rewards, dones, infos

    return BatchEncodedVecEnv()
