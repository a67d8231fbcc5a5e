"""Linear probes on what the agent sees, z ⊕ robot state, evaluated on held-out episodes.

* ``task_probe`` — how linearly decodable the task-frame state (``Task.task_state``; for the
  peg-in-hole the tip − hole offset and the tip velocity) is from z ⊕ robot state: held-out R².
  Form-sensitive where mutual information is not: the same information in a tangled form
  scores lower, as it makes learning harder for the agent (FACTS.md: the offset as input takes
  SAC from 0 % to 100 % success; the same information as two absolute positions does not).
* ``action_probe`` — after Zhang et al. 2022 ("light-weight probing"): how well z ⊕ robot state
  linearly predicts the privileged (full-state) agent's action on the on-policy dataset,
  held-out R². The action is what the downstream agent must learn to output.

Both fit scikit-learn's ``RidgeCV`` on standardized inputs and targets of the training episodes
(``hidden`` non-empty switches to an MLP). Rows: ``task_probe`` uses every stored row (held-out
backwards exploration and on-policy); ``action_probe`` only the on-policy rows (the metric stage
selects them; elsewhere the actions are the exploration policy's).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from repbench.errors import DataError
from repbench.metric import MetricResult, metric
from repbench.metrics._common import (
    check_params,
    drop_constant,
    episode_bootstrap_replicates,
    seed_from,
)
from repbench.metrics.task_information import held_out_r2, r2_of

__all__ = ["action_probe", "probe_r2", "task_probe"]


def _probe_check(name: str) -> Any:
    """Range checks of probe metric ``name``'s parameters (the planner runs them too)."""
    def check(*, hidden: Any, test_fraction: float, max_iter: int, **_: Any) -> None:
        check_params(name, test_fraction=(0 < float(test_fraction) < 1, "must be in (0, 1)"),
                     max_iter=(int(max_iter) >= 1, "must be >= 1"),
                     hidden=(all(int(h) >= 1 for h in hidden), "must list layer sizes >= 1"))

    return check


def probe_r2(name: str, z: np.ndarray, robot_state: np.ndarray, target: np.ndarray,
             episode: np.ndarray, rng: np.random.Generator, *, hidden: tuple[int, ...],
             max_iter: int, test_fraction: float, n_bootstrap: int) -> MetricResult:
    """Held-out R² of ``target`` from z ⊕ robot state, beside the robot-state-only R²."""
    from repbench.dataset import episode_split

    _probe_check(name)(hidden=hidden, test_fraction=test_fraction, max_iter=max_iter)
    zv, dropped = drop_constant(z)
    rv, dropped_r = drop_constant(robot_state)
    tv = target[:, np.ptp(target, axis=0) > 0]
    if tv.shape[1] == 0:
        raise DataError(f"{name}: every column of the target is constant; nothing to predict")
    train, test = episode_split(episode, test_fraction, seed_from(rng))
    seed = seed_from(rng)
    hidden = tuple(int(h) for h in hidden)
    model = "mlp" if hidden else "ridge"
    err, dev = held_out_r2(np.hstack([zv, rv]), tv, train, test, model=model, hidden=hidden,
                           max_iter=max_iter, seed=seed)
    err_r, _ = held_out_r2(rv, tv, train, test, model=model, hidden=hidden, max_iter=max_iter,
                           seed=seed)
    value = r2_of(err, dev)
    if not math.isfinite(value):
        raise DataError(f"{name}: R² is not finite; the held-out target is constant")
    lo, hi, reps = episode_bootstrap_replicates(lambda rows: r2_of(err[rows], dev[rows]),
                                                episode[test], rng, n_bootstrap)
    extras: dict[str, Any] = {
        "r2_robot_only": r2_of(err_r, dev), "gain_over_robot": value - r2_of(err_r, dev),
        "model": model if not hidden else f"mlp{list(hidden)}",
        "dropped_constant_dims": dropped, "dropped_constant_robot_dims": dropped_r,
        "n_train": int(train.size), "n_test": int(test.size),
        "split": "whole episodes held out", "bootstrap_replicates": reps,
    }
    return MetricResult(value, True, lo, hi, extras=extras)


@metric("task_probe", higher_is_better=True, check=_probe_check("task_probe"),
        version=1,  # v1: episode resamples from resampling_stream, paired across encoders
        description="Held-out R² of a linear probe from z ⊕ robot state to the task-frame state")
def task_probe(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray, rng: np.random.Generator,
               *, robot_state: np.ndarray | None = None, task_state: np.ndarray | None = None,
               hidden: tuple[int, ...] = (), max_iter: int = 200, test_fraction: float = 0.3,
               n_bootstrap: int = 100) -> MetricResult:
    """Linear decodability of the task-frame state from z ⊕ robot state (held-out R², higher
    is better; 1 = exactly linear).

    Ridge regression (``RidgeCV``) from standardized z ⊕ r to the standardized task state on
    the training episodes; out-of-sample R² on the held-out episodes, pooled over the
    task-state columns. The robot state alone already decodes the columns it determines (for
    the peg-in-hole the tip velocity and height), so the value's floor is
    ``extras["r2_robot_only"]``; ``extras["gain_over_robot"]`` is the difference. CI: bootstrap
    over held-out episodes (model held fixed). ``z_true`` is not used.
    """
    if task_state is None or robot_state is None:
        raise DataError("task_probe: needs task_state= and robot_state= arrays (the latents "
                        "stage stores them; re-run it if the store predates them)")
    return probe_r2("task_probe", z, robot_state, task_state, episode, rng, hidden=hidden,
                    max_iter=max_iter, test_fraction=test_fraction, n_bootstrap=n_bootstrap)


@metric("action_probe", higher_is_better=True, rows="on_policy",
        check=_probe_check("action_probe"),
        version=1,  # v1: episode resamples from resampling_stream, paired across encoders
        description="Held-out R² of a linear probe from z ⊕ robot state to the expert's action")
def action_probe(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                 rng: np.random.Generator, *, robot_state: np.ndarray | None = None,
                 action: np.ndarray | None = None, hidden: tuple[int, ...] = (),
                 max_iter: int = 200, test_fraction: float = 0.3, n_bootstrap: int = 100
                 ) -> MetricResult:
    """Expert-action probe (Zhang et al. 2022): held-out R² of predicting the privileged
    agent's action from z ⊕ robot state (higher is better).

    Computed on the on-policy dataset's rows (the metric stage selects them), whose actions are
    the full-state agent's. Ridge regression on standardized inputs and actions of the training
    episodes, out-of-sample R² on held-out episodes pooled over action dimensions.
    ``extras["r2_robot_only"]`` is the robot state's own R². CI: bootstrap over held-out
    episodes. ``z_true`` is not used.
    """
    if action is None or robot_state is None:
        raise DataError("action_probe: needs action= and robot_state= arrays (the latents "
                        "stage stores them; re-run it if the store predates them)")
    return probe_r2("action_probe", z, robot_state, action, episode, rng, hidden=hidden,
                    max_iter=max_iter, test_fraction=test_fraction, n_bootstrap=n_bootstrap)
