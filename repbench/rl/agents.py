"""SAC and DDPG on ``task env ∘ frozen encoder``, built on Stable-Baselines3 (paper §IV).

The agent observes ``μ_z ⊕ robot state`` (:mod:`repbench.rl.wrappers`). Hyperparameters follow
the paper's appendix (two hidden layers of 96/128, Adam 1e-3/3e-3, replay 3e6, batch 256,
τ = 0.005, SAC with automatic entropy tuning, DDPG with constant Gaussian exploration noise of
0.25 × the maximum action); the ``paper`` suite passes exactly those keys.

A training run reads top to bottom in :meth:`SB3Agent.train_model`:

1. build the encoded training environment(s) (``n_envs`` > 1: one process each);
2. measure the features' mean and standard deviation on a short random-action rollout and
   build the SB3 model, which standardizes its input with them (``device="auto"`` → CUDA
   when present);
3. ``model.learn`` with a callback that samples the learning curve on fixed episodes;
4. evaluate the final policy on the fixed evaluation episodes (seeds ``10_000 + i``), the same
   hole positions and initial states for every encoder. The learning curve's last point is read
   from this evaluation (the curve's episodes are a subset of the evaluation episodes and the
   policy is the same), not stepped a second time.

``backend`` picks the implementation of the same algorithm: ``"sb3"`` (Stable-Baselines3,
torch; the default) or ``"sbx"`` (SBX, Stable-Baselines3's JAX port with the same API and the
same SAC/DDPG update, ~2.4× faster per gradient step on one CPU core here:
``tests/rl/test_benchmarks.py::test_sac_update_sb3_vs_sbx``; ``pip install 'repbench[sbx]'``).
With ``"sbx"`` the fixed standardization runs on the observations
(:func:`repbench.rl.normalization.standardized_vec_env`) instead of inside the torch policy.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from repbench.agent import Agent, AgentResult
from repbench.devices import jax_single_thread, resolve_device, torch_threads
from repbench.encoder import Encoder
from repbench.errors import ConfigError, TrainingDivergedError
from repbench.rl.wrappers import (
    batch_encoded_vec_env,
    check_encoder_ready,
    encoder_label,
    make_encoded_env,
    make_raw_env,
)
from repbench.task import Task

#: Evaluation episode ``i`` resets with seed ``EVAL_SEED_BASE + i`` for every encoder and agent.
EVAL_SEED_BASE = 10_000
#: The random-action rollout that measures feature statistics resets with seeds from here on
#: (``+ 1000 * training seed``), apart from the evaluation episodes.
NORMALIZE_SEED_BASE = 20_000


def eval_seeds(n: int) -> list[int]:
    """The fixed reset seeds of ``n`` evaluation episodes."""
    return [EVAL_SEED_BASE + i for i in range(n)]


def evaluation_resets(task: Task, n: int) -> list[dict[str, Any]]:
    """The ``env.reset`` keyword arguments of the task's ``n`` fixed evaluation episodes
    (:meth:`repbench.Task.evaluation_resets`; every grid hole and off-grid holes for the
    peg-in-hole), the same for every encoder and agent."""
    resets = getattr(task, "evaluation_resets", None)
    return list(resets(n)) if callable(resets) else [{"seed": s} for s in eval_seeds(n)]


#: The implementations an agent can train with (the ``backend`` parameter).
BACKENDS = ("sb3", "sbx")


def algorithm_module(backend: str) -> Any:
    """The module holding the SAC/DDPG classes of ``backend`` (``stable_baselines3`` or
    ``sbx``); ConfigError naming the install when SBX is missing."""
    if backend == "sbx":
        try:
            import sbx
        except ImportError as exc:
            raise ConfigError(f"agent backend 'sbx' needs SBX and JAX ({exc}): pip install "
                              "'repbench[sbx]', or set backend = 'sb3' in "
                              "[agent_params.<agent>]") from None
        return sbx
    import stable_baselines3

    return stable_baselines3


def is_jax_model(model: Any) -> bool:
    """Whether ``model`` is an SBX (JAX) model rather than a torch SB3 one."""
    return type(model).__module__.split(".")[0] == "sbx"


def policy_snapshot(model: Any) -> Any:
    """A copy of the policy's weights, to put back with :func:`restore_policy`."""
    if is_jax_model(model):
        # flax train states are immutable pytrees: keeping a reference is a snapshot
        return {k: getattr(model.policy, k) for k in ("actor_state", "qf_state")}
    return copy.deepcopy(model.policy.state_dict())


def restore_policy(model: Any, snapshot: Any) -> None:
    """Put back weights taken with :func:`policy_snapshot`."""
    if is_jax_model(model):
        for k, v in snapshot.items():
            setattr(model.policy, k, v)
    else:
        model.policy.load_state_dict(snapshot)


def first_non_finite(model: Any) -> str | None:
    """The name of a policy weight that is NaN or inf, or None when all are finite."""
    if is_jax_model(model):
        import jax

        for k in ("actor_state", "qf_state"):
            leaves = jax.tree_util.tree_leaves_with_path(getattr(model.policy, k).params)
            for path, leaf in leaves:
                if not bool(np.isfinite(np.asarray(leaf)).all()):
                    return f"{k}{jax.tree_util.keystr(path)}"
        return None
    for name, p in model.policy.named_parameters():
        if not bool(p.detach().isfinite().all()):
            return name
    return None


def model_device(model: Any) -> str:
    """Where the model computes: its torch device, or JAX's default device for SBX."""
    if is_jax_model(model):
        import jax

        return str(jax.devices()[0])
    return str(model.device)


def spread(items: Sequence[Any], k: int) -> list[Any]:
    """``k`` items spread evenly over ``items`` (all of them when ``k >= len(items)``)."""
    if k >= len(items):
        return list(items)
    return [items[int(i)] for i in np.linspace(0, len(items) - 1, k).round()]


def evaluate(model: Any, env: Any, resets: Sequence[int | Mapping[str, Any]], *,
             deterministic: bool = True) -> tuple[list[float], list[bool]]:
    """Run one episode per reset (a seed, or ``env.reset`` keyword arguments); return
    per-episode returns and successes.

    An episode counts as a success if ``info["is_success"]`` was true at any step.
    """
    returns, successes = [], []
    for reset in resets:
        kwargs = dict(reset) if isinstance(reset, Mapping) else {"seed": int(reset)}
        obs, info = env.reset(**kwargs)
        total, success, done = 0.0, bool(info.get("is_success", False)), False
        while not done:
            action, _ = model.predict(obs, deterministic=deterministic)
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            success = success or bool(info.get("is_success", False))
            done = terminated or truncated
        returns.append(total)
        successes.append(success)
    return returns, successes


def _make_curve_callback(agent_name: str, encoder_name: str, eval_env: Any,
                         resets: list[dict[str, Any]], points: list[int], total: int,
                         progress: bool, keep_best: bool) -> Any:
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm.auto import tqdm

    class CurveCallback(BaseCallback):
        """Samples the learning curve at ``points`` (env steps) on fixed episodes; with
        ``keep_best``, keeps a copy of the policy at the best point (success, then return)."""

        def __init__(self) -> None:
            super().__init__()
            self.steps: list[int] = []
            self.returns: list[float] = []
            self.success: list[float] = []
            self.best: tuple[float, float] | None = None
            self.best_step: int | None = None
            self.best_state: Any = None
            self._next = 0
            self._bar: Any = None

        def _on_training_start(self) -> None:
            self._bar = tqdm(total=total, desc=f"{agent_name} on {encoder_name}",
                             disable=not progress, unit="step")

        def _on_step(self) -> bool:
            self._bar.update(self.training_env.num_envs)
            while self._next < len(points) and self.num_timesteps >= points[self._next]:
                self._check_finite()
                rets, succ = evaluate(self.model, eval_env, resets)
                self.steps.append(int(self.num_timesteps))
                self.returns.append(float(np.mean(rets)))
                self.success.append(float(np.mean(succ)))
                score = (self.success[-1], self.returns[-1])
                if keep_best and (self.best is None or score > self.best):
                    self.best, self.best_step = score, int(self.num_timesteps)
                    self.best_state = policy_snapshot(self.model)
                self._bar.set_postfix(ret=f"{self.returns[-1]:.2f}",
                                      succ=f"{self.success[-1]:.2f}")
                self._next += 1
            return True

        def _on_training_end(self) -> None:
            self._bar.close()

        def _check_finite(self) -> None:
            name = first_non_finite(self.model)
            if name is not None:
                raise TrainingDivergedError(
                    f"{agent_name} on encoder {encoder_name} diverged at step "
                    f"{self.num_timesteps} (non-finite weights in {name}); lower "
                    "learning_rate or check the encoder's latent scale"
                )

    return CurveCallback()


class SB3Agent(Agent):
    """Shared machinery of the Stable-Baselines3 agents (see :class:`SACAgent`)."""

    name: ClassVar[str] = "sb3"
    #: 1: evaluation on the task's fixed resets (every grid hole, then off-grid holes), curve
    #: episodes spread over them, ``keep_best``. 2: the curve's last point read from the final
    #: evaluation (after the last update, not one update before it).
    version: ClassVar[int] = 2
    #: SB3 algorithm name (``stable_baselines3.<ALGO>``).
    algorithm: ClassVar[str] = ""

    def __init__(self, hidden_sizes: Sequence[int] = (128, 128), learning_rate: float = 1e-3,
                 buffer_size: int = 3_000_000, batch_size: int = 256, tau: float = 0.005,
                 learning_starts: int = 1000, gamma: float = 0.99, gradient_steps: int = -1,
                 curve_episodes: int = 5, normalize_steps: int = 500, device: str = "auto",
                 n_envs: int = 1, torch_threads: int | None = 1, keep_best: bool = False,
                 progress: bool = True, backend: str = "sb3") -> None:
        self.hidden_sizes = hidden_sizes
        self.learning_rate = learning_rate
        self.buffer_size = buffer_size
        self.batch_size = batch_size
        self.tau = tau
        self.learning_starts = learning_starts
        self.gamma = gamma
        self.gradient_steps = gradient_steps
        self.curve_episodes = curve_episodes
        self.normalize_steps = normalize_steps
        self.device = device
        self.n_envs = n_envs
        self.torch_threads = torch_threads
        self.keep_best = keep_best
        self.progress = progress
        self.backend = backend

    # -- parameters ----------------------------------------------------------------------------
    def get_params(self) -> dict[str, Any]:
        """Constructor arguments (rebuild with ``type(a)(**a.get_params())``)."""
        import inspect

        sig = inspect.signature(type(self).__init__)
        return {p: getattr(self, p) for p in sig.parameters if p != "self"}

    def _fail(self, field: str, why: str) -> ConfigError:
        return ConfigError(f"agent {self.name!r}: parameter {field}={getattr(self, field)!r} "
                           f"{why}")

    def validate(self, train_steps: int) -> None:
        """Raise ConfigError naming the agent and the bad parameter."""
        hs = self.hidden_sizes
        if (not isinstance(hs, (list, tuple)) or not hs
                or not all(isinstance(h, int) and h > 0 for h in hs)):
            raise self._fail("hidden_sizes", "must be a non-empty list of positive ints")
        if not (isinstance(self.learning_rate, (int, float)) and self.learning_rate > 0):
            raise self._fail("learning_rate", "must be > 0")
        if self.torch_threads is not None and not (
                isinstance(self.torch_threads, int) and self.torch_threads > 0):
            raise self._fail("torch_threads", "must be a positive int or None")
        for f in ("buffer_size", "batch_size", "n_envs", "curve_episodes"):
            if not (isinstance(getattr(self, f), int) and getattr(self, f) > 0):
                raise self._fail(f, "must be a positive int")
        if not 0.0 < self.tau <= 1.0:
            raise self._fail("tau", "must be in (0, 1]")
        if not 0.0 <= self.gamma <= 1.0:
            raise self._fail("gamma", "must be in [0, 1]")
        if not isinstance(self.normalize_steps, int) or self.normalize_steps < 0 or (
                self.normalize_steps == 1):
            raise self._fail("normalize_steps", "must be 0 (no standardization) or an int >= 2")
        if not isinstance(self.learning_starts, int) or self.learning_starts < 0:
            raise self._fail("learning_starts", "must be an int >= 0")
        if self.learning_starts >= train_steps:
            raise self._fail("learning_starts", f"must be below train_steps={train_steps}, or "
                                                "the agent never learns")
        if self.gradient_steps == 0 or self.gradient_steps < -1:
            raise self._fail("gradient_steps", "must be -1 (one per env step) or >= 1")
        if self.device not in ("auto", "cpu", "cuda") and not str(self.device).startswith(
                "cuda:"):
            raise self._fail("device", "must be 'auto', 'cpu' or 'cuda[:i]'")
        if self.backend not in BACKENDS:
            raise self._fail("backend", f"must be one of {', '.join(map(repr, BACKENDS))}")

    # -- to specialise -------------------------------------------------------------------------
    def _algorithm_kwargs(self, env: Any) -> dict[str, Any]:
        """Algorithm-specific keyword arguments (entropy, exploration noise)."""
        return {}

    # -- training ------------------------------------------------------------------------------
    def _make_vec_env(self, task: Task, encoder: Encoder, seed: int,
                      stats: tuple[np.ndarray, np.ndarray] | None = None) -> Any:
        """One environment: the gymnasium wrapper. ``n_envs`` > 1: raw environments in worker
        processes (multi-core), their observations encoded in one batch here. ``stats``
        (the SBX backend): observations standardized with them."""
        from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

        if self.n_envs == 1:
            venv = DummyVecEnv([lambda: make_encoded_env(task, encoder, seed=seed)])
        else:
            def factory(rank: int) -> Any:
                return lambda: make_raw_env(task, seed=seed + rank,
                                            modalities=encoder.required_modalities)

            venv = batch_encoded_vec_env(SubprocVecEnv([factory(i) for i in range(self.n_envs)]),
                                         task, encoder)
        if stats is not None:
            from repbench.rl.normalization import standardized_vec_env

            venv = standardized_vec_env(venv, *stats)
        return venv

    def build_model(self, env: Any, seed: int, buffer_size: int | None = None,
                    feature_stats: tuple[np.ndarray, np.ndarray] | None = None) -> Any:
        """The SB3 model for ``env`` (a flat-Box environment or VecEnv).

        ``feature_stats`` (mean, std): standardize the observations inside the policy
        (:class:`repbench.rl.normalization.StandardizedFeatures`; backend ``"sb3"`` only: the
        SBX backend's environments standardize them, :meth:`train_model`).
        """
        from stable_baselines3.common.logger import Logger

        if self.backend == "sbx" and self.torch_threads == 1:
            jax_single_thread()
        cls = getattr(algorithm_module(self.backend), self.algorithm)
        policy_kwargs: dict[str, Any] = {"net_arch": [int(h) for h in self.hidden_sizes]}
        if self.backend == "sbx":
            feature_stats = None
        if feature_stats is not None:
            from repbench.rl.normalization import StandardizedFeatures

            mean, std = feature_stats
            policy_kwargs["features_extractor_class"] = StandardizedFeatures
            policy_kwargs["features_extractor_kwargs"] = {
                "mean": [float(x) for x in mean], "std": [float(x) for x in std]}
        model = cls(
            "MlpPolicy", env,
            learning_rate=float(self.learning_rate),
            buffer_size=int(self.buffer_size if buffer_size is None else buffer_size),
            learning_starts=int(self.learning_starts),
            batch_size=int(self.batch_size),
            tau=float(self.tau),
            gamma=float(self.gamma),
            train_freq=1,
            gradient_steps=int(self.gradient_steps),
            policy_kwargs=policy_kwargs,
            seed=seed,
            device=resolve_device(self.device) if self.backend == "sb3" else "auto",
            verbose=0,
            **self._algorithm_kwargs(env),
        )
        # a logger with no outputs: SB3's default makes an empty /tmp/SB3-<date> folder per run
        model.set_logger(Logger(folder=None, output_formats=[]))
        return model

    def train(self, task: Task, encoder: Encoder, *, train_steps: int, seed: int,
              eval_episodes: int, curve_points: int = 5, progress: bool = True
              ) -> AgentResult:
        """Train on ``task`` seen through frozen ``encoder`` and evaluate on fixed episodes.

        The trained SB3 model is kept as ``self.model_`` (save it with
        :func:`repbench.rl.save_policy`).
        """
        model, result = self.train_model(task, encoder, train_steps=train_steps, seed=seed,
                                         eval_episodes=eval_episodes, curve_points=curve_points,
                                         progress=progress)
        self.model_ = model
        return result

    def train_model(self, task: Task, encoder: Encoder, *, train_steps: int, seed: int,
                    eval_episodes: int, curve_points: int = 5, progress: bool = True
                    ) -> tuple[Any, AgentResult]:
        """Like :meth:`train`, also returning the trained SB3 model."""
        with torch_threads(self.torch_threads):
            return self._train_model(task, encoder, train_steps=train_steps, seed=seed,
                                     eval_episodes=eval_episodes, curve_points=curve_points,
                                     progress=progress)

    def _train_model(self, task: Task, encoder: Encoder, *, train_steps: int, seed: int,
                     eval_episodes: int, curve_points: int, progress: bool
                     ) -> tuple[Any, AgentResult]:
        import torch

        if not isinstance(train_steps, int) or train_steps <= 0:
            raise ConfigError(f"agent {self.name!r}: train_steps must be a positive int, "
                              f"got {train_steps!r}")
        if not isinstance(eval_episodes, int) or eval_episodes <= 0:
            raise ConfigError(f"agent {self.name!r}: eval_episodes must be a positive int, "
                              f"got {eval_episodes!r}")
        if not isinstance(curve_points, int) or curve_points <= 0:
            raise ConfigError(f"agent {self.name!r}: curve_points must be a positive int, "
                              f"got {curve_points!r}")
        self.validate(train_steps)
        check_encoder_ready(encoder)
        progress = progress and self.progress
        enc_name = encoder_label(encoder)
        start = time.perf_counter()

        # 1. evaluation environment (fixed reset seeds), the feature statistics measured on
        #    it, the training environment(s) (vectorised)
        eval_env = make_encoded_env(task, encoder, seed=EVAL_SEED_BASE)
        expected = int(eval_env.observation_space.shape[0])
        stats = None
        if self.normalize_steps:
            from repbench.rl.normalization import feature_statistics

            stats = feature_statistics(eval_env, self.normalize_steps,
                                       NORMALIZE_SEED_BASE + 1000 * seed)
        env_stats = stats if self.backend == "sbx" else None  # SBX: standardized by the envs
        if env_stats is not None:
            from repbench.rl.normalization import StandardizedObservation

            eval_env = StandardizedObservation(eval_env, *env_stats)
        env = self._make_vec_env(task, encoder, seed, env_stats)
        try:
            # 2. model; the replay buffer never needs more than the run's transitions
            buffer = min(self.buffer_size, train_steps + self.n_envs)
            model = self.build_model(env, seed, buffer_size=buffer, feature_stats=stats)
            model.repbench_feature_stats = env_stats  # saved beside an SBX model (save_policy)
            # 3. learn, sampling the learning curve at its points
            #    before the end; its last point comes from the final evaluation (step 4)
            resets = evaluation_resets(task, eval_episodes)
            curve_index = spread(list(range(len(resets))), self.curve_episodes)
            curve_resets = [resets[i] for i in curve_index]
            points = sorted({max(1, math.ceil(train_steps * (k + 1) / curve_points))
                             for k in range(curve_points)})
            callback = _make_curve_callback(self.name, enc_name, eval_env, curve_resets,
                                            points[:-1], train_steps, progress, self.keep_best)
            t0 = time.perf_counter()
            model.learn(total_timesteps=train_steps, callback=callback, progress_bar=False)
            train_time = time.perf_counter() - t0
        finally:
            env.close()
        # 4. final evaluation on the fixed episodes; the curve's last point is its curve episodes
        callback._check_finite()
        rets, succ = evaluate(model, eval_env, resets)
        last = (float(np.mean([succ[i] for i in curve_index])),
                float(np.mean([rets[i] for i in curve_index])))
        callback.steps.append(int(model.num_timesteps))
        callback.success.append(last[0])
        callback.returns.append(last[1])
        if self.keep_best:
            if callback.best is None or last > callback.best:
                callback.best_step = int(model.num_timesteps)
            else:  # an earlier point was better: the result is that policy's evaluation
                restore_policy(model, callback.best_state)
                rets, succ = evaluate(model, eval_env, resets)
        eval_env.close()
        if not np.isfinite(rets).all():
            raise TrainingDivergedError(f"{self.name} on encoder {enc_name}: evaluation "
                                        "returns are not finite")
        result = AgentResult(
            curve_steps=list(callback.steps),
            curve_return=list(callback.returns),
            curve_success=list(callback.success),
            eval_return=float(np.mean(rets)),
            eval_success_rate=float(np.mean(succ)),
            eval_episode_returns=[float(r) for r in rets],
            train_steps=int(model.num_timesteps),
            wall_time_s=float(time.perf_counter() - start),
            steps_per_s=float(model.num_timesteps / max(train_time, 1e-9)),
            extras={
                "agent": self.name,
                "encoder": enc_name,
                "task": getattr(task, "task_id", type(task).__name__),
                "seed": seed,
                "params": {k: (list(v) if isinstance(v, tuple) else v)
                           for k, v in self.get_params().items()},
                "effective_buffer_size": buffer,
                "device": model_device(model),
                "observation_dim": expected,
                "latent_dim": int(encoder.latent_dim),
                "eval_resets": resets,
                "eval_episode_success": [bool(s) for s in succ],
                "curve_episodes": len(curve_resets),
                "kept_step": callback.best_step if self.keep_best else None,
                "backend": self.backend,
                "train_time_s": float(train_time),
                "torch_threads": torch.get_num_threads(),
            },
        )
        return model, result


class SACAgent(SB3Agent):
    """Soft actor-critic (Stable-Baselines3) with automatic entropy tuning (paper §IV).

    Args:
        hidden_sizes: hidden layers of actor and critic (paper: two of 96 or 128).
        learning_rate: Adam learning rate (paper: 3e-3 or 1e-3).
        buffer_size: replay buffer capacity (paper: 3e6; capped at the run's length).
        batch_size: minibatch size (paper: 256).
        tau: soft target update coefficient (paper: 0.005).
        ent_coef: entropy coefficient; ``"auto"`` (or ``"auto_<init>"``) tunes it.
        learning_starts: uniformly random steps before learning starts.
        gamma: discount factor.
        gradient_steps: gradient steps per env step (-1: as many as transitions collected).
        curve_episodes: fixed episodes per learning-curve point.
        normalize_steps: random-action steps that measure each feature's mean and standard
            deviation before training; the policy standardizes its input with them (fixed,
            saved with the model). 0 feeds raw features.
        device: ``"auto"`` (CUDA when present), ``"cpu"`` or ``"cuda"``.
        n_envs: training environments; > 1 runs each in its own process (multi-core).
        torch_threads: torch intra-op threads while training (restored afterwards); 1 is
            fastest for these small MLPs on CPU (parallelise over seeds instead); ``None``
            leaves torch's setting alone.
        keep_best: end with the policy of the best learning-curve point (evaluation success,
            then return) instead of the last one (the privileged agent does).
        progress: show a progress bar.
        backend: ``"sb3"`` (Stable-Baselines3, torch; uses a GPU when torch sees one) or
            ``"sbx"`` (SBX, the same algorithm in JAX: ~2.4× faster updates on one CPU core;
            uses a GPU when JAX has one; ``pip install 'repbench[sbx]'``). ``torch_threads=1``
            also keeps JAX on one CPU thread.
    """

    name = "sac"
    algorithm = "SAC"

    def __init__(self, hidden_sizes: Sequence[int] = (128, 128), learning_rate: float = 1e-3,
                 buffer_size: int = 3_000_000, batch_size: int = 256, tau: float = 0.005,
                 ent_coef: str | float = "auto", learning_starts: int = 1000,
                 gamma: float = 0.99, gradient_steps: int = -1, curve_episodes: int = 5,
                 normalize_steps: int = 500, device: str = "auto", n_envs: int = 1,
                 torch_threads: int | None = 1, keep_best: bool = False,
                 progress: bool = True, backend: str = "sb3") -> None:
        super().__init__(hidden_sizes=hidden_sizes, learning_rate=learning_rate,
                         buffer_size=buffer_size, batch_size=batch_size, tau=tau,
                         learning_starts=learning_starts, gamma=gamma,
                         gradient_steps=gradient_steps, curve_episodes=curve_episodes,
                         normalize_steps=normalize_steps, device=device, n_envs=n_envs,
                         torch_threads=torch_threads, keep_best=keep_best, progress=progress,
                         backend=backend)
        self.ent_coef = ent_coef

    def validate(self, train_steps: int) -> None:
        super().validate(train_steps)
        ec = self.ent_coef
        ok = (isinstance(ec, (int, float)) and ec > 0) or (
            isinstance(ec, str) and (ec == "auto" or ec.startswith("auto_")))
        if not ok:
            raise self._fail("ent_coef", "must be 'auto', 'auto_<init>' or a float > 0")

    def _algorithm_kwargs(self, env: Any) -> dict[str, Any]:
        return {"ent_coef": self.ent_coef}


class DDPGAgent(SB3Agent):
    """DDPG (Stable-Baselines3) with constant Gaussian exploration noise (paper §IV).

    Args:
        action_noise: exploration noise standard deviation as a fraction of the maximum
            action (paper: 0.25), constant over training.
        (the others as in :class:`SACAgent`)
    """

    name = "ddpg"
    algorithm = "DDPG"

    def __init__(self, hidden_sizes: Sequence[int] = (128, 128), learning_rate: float = 1e-3,
                 buffer_size: int = 3_000_000, batch_size: int = 256, tau: float = 0.005,
                 action_noise: float = 0.25, learning_starts: int = 1000,
                 gamma: float = 0.99, gradient_steps: int = -1, curve_episodes: int = 5,
                 normalize_steps: int = 500, device: str = "auto", n_envs: int = 1,
                 torch_threads: int | None = 1, keep_best: bool = False,
                 progress: bool = True, backend: str = "sb3") -> None:
        super().__init__(hidden_sizes=hidden_sizes, learning_rate=learning_rate,
                         buffer_size=buffer_size, batch_size=batch_size, tau=tau,
                         learning_starts=learning_starts, gamma=gamma,
                         gradient_steps=gradient_steps, curve_episodes=curve_episodes,
                         normalize_steps=normalize_steps, device=device, n_envs=n_envs,
                         torch_threads=torch_threads, keep_best=keep_best, progress=progress,
                         backend=backend)
        self.action_noise = action_noise

    def validate(self, train_steps: int) -> None:
        super().validate(train_steps)
        if not (isinstance(self.action_noise, (int, float)) and self.action_noise >= 0):
            raise self._fail("action_noise", "must be a float >= 0")

    def _algorithm_kwargs(self, env: Any) -> dict[str, Any]:
        from stable_baselines3.common.noise import NormalActionNoise

        high = np.abs(np.asarray(env.action_space.high, np.float64))
        sigma = float(self.action_noise) * high
        return {"action_noise": NormalActionNoise(mean=np.zeros_like(sigma), sigma=sigma)}
