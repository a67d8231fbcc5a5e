"""The privileged agent and the ``on_policy`` dataset it collects (paper §IV).

"A second dataset collects representation trajectories produced by a trained full-state SAC
agent." Here the full-state agent is *privileged*: SAC on the ``oracle_task`` encoder (the
task-frame state: for the peg-in-hole, the tip's offset from the hole and the tip velocity)
⊕ robot state, trained once per task, keeping its best checkpoint by evaluation success. The
paper's z° holds the same information but in a form SAC does not learn from in a short budget
(FACTS.md: 0 % vs 100 % insertion), and on-policy data of an agent that never inserts is not
on-policy data of a competent agent. Saved in the runner's artifact store with
:func:`save_policy`, reloaded with :func:`load_policy` as a :data:`repbench.task.Policy`, and
passed to ``task.collect("on_policy", policy=...)``.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from repbench.agent import AgentResult
from repbench.dataset import IMAGE, TRUE_STATE, Dataset
from repbench.encoder import Encoder
from repbench.errors import ConfigError, DataError
from repbench.rl.wrappers import ObservationEncoder, encoder_label
from repbench.task import Task

_ALGORITHMS = ("SAC", "DDPG")


class EncodedPolicy:
    """A trained SB3 model + frozen encoder as a :data:`repbench.task.Policy`.

    Called on one step's observation dict (with ``true_state``) it returns the deterministic
    action, float32 ``[A]``; on a batch of one (leading axis) it returns ``[1, A]``.
    """

    def __init__(self, model: Any, task: Task, encoder: Encoder) -> None:
        expected = int(model.observation_space.shape[0])
        self.model = model
        self.task = task
        self.encoder = encoder
        self.features = ObservationEncoder(task, encoder, expected_dim=expected)
        if encoder.latent_dim > expected:
            raise ConfigError(
                f"encoder {encoder_label(encoder)} has latent_dim {encoder.latent_dim} but the "
                f"policy was trained on {expected} features: use the encoder it was trained with"
            )

    def __call__(self, observation: Mapping[str, np.ndarray]) -> np.ndarray:
        if TRUE_STATE not in observation:
            raise DataError("the policy needs the observation dict with 'true_state' (add "
                            "info['true_state'] to it)")
        batched = np.asarray(observation[IMAGE]).ndim == 4
        if batched:
            if np.asarray(observation[IMAGE]).shape[0] != 1:
                raise DataError("the policy takes one step's observation (batch of one)")
            observation = {k: np.asarray(v)[0] for k, v in observation.items()}
        obs = {k: v for k, v in observation.items() if k != TRUE_STATE}
        features = self.features(obs, np.asarray(observation[TRUE_STATE]))
        action, _ = self.model.predict(features, deterministic=True)
        action = np.asarray(action, np.float32)
        return action[None] if batched else action


def save_policy(model: Any, path: str | os.PathLike[str]) -> Path:
    """Save an SB3 or SBX SAC/DDPG model to ``path`` (a ``.zip``), atomically, with the
    feature statistics an SBX model reads its observations through."""
    path = Path(path)
    if isinstance(model, StandardizedModel):
        model = model.model
    algo = type(model).__name__
    if algo not in _ALGORITHMS:
        raise ConfigError(f"save_policy: expected an SB3 SAC or DDPG model, got {algo}")
    from repbench.rl.agents import is_jax_model

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp{os.getpid()}.zip")
    model.save(tmp)
    meta: dict[str, Any] = {"algorithm": algo,
                            "backend": "sbx" if is_jax_model(model) else "sb3"}
    stats = getattr(model, "repbench_feature_stats", None)
    if stats is not None:  # the SBX backend standardizes outside the model
        meta["feature_mean"] = [float(x) for x in stats[0]]
        meta["feature_std"] = [float(x) for x in stats[1]]
    with zipfile.ZipFile(tmp, "a") as zf:
        zf.writestr("repbench_policy.json", json.dumps(meta))
    os.replace(tmp, path)
    return path


class StandardizedModel:
    """A model trained on standardized observations (the SBX backend), predicting from raw
    ones: ``predict(x)`` is ``model.predict(standardize(x))``; other attributes pass through."""

    def __init__(self, model: Any, mean: Any, std: Any) -> None:
        from repbench.rl.normalization import check_statistics

        self.model = model
        size = int(np.prod(model.observation_space.shape))
        self.mean, self.std = check_statistics(mean, std, size)

    def predict(self, observation: Any, **kwargs: Any) -> Any:
        from repbench.rl.normalization import standardize

        return self.model.predict(standardize(observation, self.mean, self.std), **kwargs)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.model, name)


def load_model(path: str | os.PathLike[str], device: str = "cpu") -> Any:
    """Load a model written by :func:`save_policy` (SB3 or SBX; an SBX model with its feature
    statistics comes back as a :class:`StandardizedModel`)."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"policy file {path} does not exist; train the full-state agent again")
    try:
        with zipfile.ZipFile(path) as zf:
            meta = json.loads(zf.read("repbench_policy.json"))
        algo = meta["algorithm"]
    except (zipfile.BadZipFile, KeyError, OSError, ValueError) as exc:
        raise DataError(f"policy file {path} is damaged or not a repbench policy ({exc}); "
                        "train it again") from None
    if algo not in _ALGORITHMS:
        raise DataError(f"policy file {path} holds unknown algorithm {algo!r}")
    from repbench.rl.agents import algorithm_module, resolve_device

    backend = meta.get("backend", "sb3")
    if backend == "sbx":
        from repbench.devices import jax_single_thread

        jax_single_thread()
        model = getattr(algorithm_module("sbx"), algo).load(path)
    else:
        model = getattr(algorithm_module("sb3"), algo).load(path,
                                                            device=resolve_device(device))
    if "feature_mean" in meta:
        return StandardizedModel(model, meta["feature_mean"], meta["feature_std"])
    return model


def load_policy(path: str | os.PathLike[str], task: Task, encoder: Encoder,
                device: str = "cpu") -> EncodedPolicy:
    """A :data:`repbench.task.Policy` from a saved model and the (fitted) encoder it used."""
    return EncodedPolicy(load_model(path, device=device), task, encoder)


#: The encoder of the privileged agent and the SAC settings it learns the peg-in-hole with
#: (chosen by measurement: see ``repbench/suites/quick.toml``); suites override them.
PRIVILEGED_ENCODER = "oracle_task"
PRIVILEGED_AGENT_PARAMS: dict[str, Any] = {
    "learning_rate": 3e-4, "hidden_sizes": [256, 256], "keep_best": True,
    "curve_episodes": 25}


def fitted_privileged_encoder(task: Task, dataset: Dataset | None = None, seed: int = 0,
                              name: str = PRIVILEGED_ENCODER) -> Encoder:
    """The registered privileged encoder (``oracle_task``), fitted on ``dataset`` (or a tiny
    random dataset of ``task``)."""
    from repbench.registry import encoders

    encoder = encoders.get(name)()
    if dataset is None:
        dataset = task.collect("random", n_episodes=1, steps_per_episode=3, seed=seed,
                               progress=False)
    return encoder.fit(dataset)


def train_full_state_agent(task: Task, *, train_steps: int, seed: int,
                           encoder: Encoder | None = None, dataset: Dataset | None = None,
                           eval_episodes: int = 10, curve_points: int = 5,
                           progress: bool = True, **agent_params: Any
                           ) -> tuple[EncodedPolicy, AgentResult]:
    """Train the privileged SAC agent (task-frame state ⊕ robot state).

    Args:
        task: the task.
        train_steps: environment steps.
        seed: training seed.
        encoder: a fitted privileged encoder; default: the registered ``oracle_task``
            fitted on ``dataset`` (the task's random dataset) or a tiny random dataset.
        eval_episodes, curve_points, progress: as in :meth:`repbench.Agent.train`.
        agent_params: :class:`repbench.rl.agents.SACAgent` keyword arguments over
            :data:`PRIVILEGED_AGENT_PARAMS`.

    Returns:
        The policy (``policy.model`` is the SB3 model; save it with :func:`save_policy`) and
        the training result.
    """
    from repbench.rl.agents import SACAgent

    if encoder is None:
        encoder = fitted_privileged_encoder(task, dataset, seed)
    agent = SACAgent(**{**PRIVILEGED_AGENT_PARAMS, **agent_params})
    model, result = agent.train_model(task, encoder, train_steps=train_steps, seed=seed,
                                      eval_episodes=eval_episodes, curve_points=curve_points,
                                      progress=progress)
    result.extras["role"] = "privileged"
    stats = getattr(model, "repbench_feature_stats", None)
    if stats is not None:  # SBX: the model reads standardized features
        model = StandardizedModel(model, *stats)
    return EncodedPolicy(model, task, encoder), result


def collect_on_policy(task: Task, policy: Any, *, n_episodes: int, steps_per_episode: int,
                      seed: int, progress: bool = True) -> Dataset:
    """The ``on_policy`` dataset: ``task.collect("on_policy", policy=policy, ...)``."""
    if not callable(policy):
        raise ConfigError(f"collect_on_policy needs a callable policy, got {type(policy)!r}")
    ds = task.collect("on_policy", n_episodes=n_episodes, steps_per_episode=steps_per_episode,
                      seed=seed, policy=policy, progress=progress)
    ds.metadata.setdefault("policy", "privileged_sac")
    return ds
