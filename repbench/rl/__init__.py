"""Downstream RL on frozen encoders: SAC and DDPG through Stable-Baselines3 (paper §IV).

* :class:`SACAgent`, :class:`DDPGAgent` — the ``sac`` and ``ddpg`` agents of the registry;
* :class:`FrozenEncoderObservation` — the gymnasium wrapper (μ_z ⊕ robot state);
* :func:`train_full_state_agent`, :func:`collect_on_policy`, :func:`save_policy`,
  :func:`load_policy` — the full-state agent and the ``on_policy`` dataset.

SB3 is imported lazily, so ``import repbench.rl`` stays cheap.
"""

from repbench.rl.agents import (
    EVAL_SEED_BASE,
    DDPGAgent,
    SACAgent,
    SB3Agent,
    eval_seeds,
    evaluate,
    resolve_device,
)
from repbench.rl.full_state import (
    EncodedPolicy,
    collect_on_policy,
    load_model,
    load_policy,
    save_policy,
    train_full_state_agent,
)
from repbench.rl.wrappers import FrozenEncoderObservation, ObservationEncoder, make_encoded_env

__all__ = [
    "EVAL_SEED_BASE", "DDPGAgent", "EncodedPolicy", "FrozenEncoderObservation",
    "ObservationEncoder", "SACAgent", "SB3Agent", "collect_on_policy", "eval_seeds", "evaluate",
    "load_model", "load_policy", "make_encoded_env", "resolve_device", "save_policy",
    "train_full_state_agent",
]
