"""The metric API: pure functions of arrays returning a :class:`MetricResult`.

A metric is a function ``fn(z, z_true, episode, rng, **params) -> MetricResult`` where

* ``z`` — float ``[N, D]`` latents (μ_z), rows ordered by (episode, step);
* ``z_true`` — float ``[N, S]`` true state z°;
* ``episode`` — int ``[N]`` episode ids (consecutive rows of one episode are consecutive steps);
* ``rng`` — a ``numpy.random.Generator``; a fixed seed gives a reproducible value.

Register it with the decorator, which also validates inputs before the function runs::

    @repbench.metric("my_metric", higher_is_better=True, description="...")
    def my_metric(z, z_true, episode, rng, *, k=5) -> MetricResult: ...

Extra arrays. A metric that needs more than ``(z, z_true, episode)`` declares keyword-only
parameters named after the arrays the latents stage stores (:data:`EXTRA_INPUTS`):
``robot_state`` (float ``[N, R]``: what the agent sees beside z, ``Task.robot_state``),
``task_state`` (float ``[N, K]``: ``Task.task_state``, e.g. the peg tip's offset from the hole),
``reward`` (float ``[N]``: the reward received for that action), ``action`` (float ``[N, A]``:
the dataset's action at each step; on the on-policy dataset the
privileged agent's) and ``source`` (int ``[N]``: which dataset a row came from). The metric stage
passes exactly the ones the function's signature names; the wrapper checks their shape and values.

Rows. ``rows="on_policy"`` in the decorator makes the metric stage compute the metric on the
on-policy dataset's rows only (the paper's choice for smoothness and latent distances; needed for
the expert-action probe); the default ``"all"`` uses every row the latents stage stored (the
held-out backwards-exploration episodes and the on-policy episodes).
"""

from __future__ import annotations

from collections.abc import Callable

from repbench.metric_types import (
    EXTRA_INPUTS,
    ROWS,
    Metric,
    MetricResult,
    check_extra_input,
    check_metric_inputs,
)
from repbench.registry import metrics

__all__ = ["EXTRA_INPUTS", "ROWS", "Metric", "MetricResult", "check_extra_input",
           "check_metric_inputs", "metric"]


def metric(name: str, *, higher_is_better: bool, description: str = "", min_samples: int = 10,
           register: bool = True, version: int = 0, rows: str = "all", group: str = "privileged",
           check: Callable[..., None] | None = None
           ) -> Callable[[Callable[..., MetricResult]], Metric]:
    """Decorator turning a function into a :class:`Metric` (and registering it by default).

    ``rows`` (``"all"`` or ``"on_policy"``) says which rows of the stored latents the metric
    stage computes it on (module docstring).

    ``group``: ``"observable"`` for a metric that reads only what a real robot logs (z, robot
    state, action, reward, episodes; it ignores ``z_true`` and never asks for ``task_state``),
    ``"privileged"`` (the default) for one that reads the simulator's state. The board says
    which (``metrics.csv``'s ``group``); an observable metric that asks for ``task_state`` is
    refused here.

    ``check``: the metric's range checks, ``check(**params)`` with every tunable parameter
    (defaults filled in), raising :class:`~repbench.errors.ConfigError`. The planner runs it
    (after checking names and annotated types, :meth:`Metric.check_params`) so a bad value in
    a suite file fails before any stage; call it from the metric too.

    ``version``: bump it when a change alters the metric's values; stored results of the older
    version then show as stale instead of being reused (:mod:`repbench.pipeline.records`).
    """

    def wrap(fn: Callable[..., MetricResult]) -> Metric:
        m = Metric(fn, name, higher_is_better, description, min_samples, version=version,
                   rows=rows, check=check, group=group)
        if group == "observable" and "task_state" in m.extra_inputs:
            raise ValueError(f"metric {name!r} is declared observable but reads task_state, "
                             "the simulator's state; declare it group='privileged'")
        if register:
            metrics.register(name, m)
        return m

    return wrap
