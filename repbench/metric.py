"""The metric API: pure functions of arrays returning a :class:`MetricResult`.

A metric is a function ``fn(z, z_true, episode, rng, **params) -> MetricResult`` where

* ``z`` — float ``[N, D]`` latents (μ_z), rows ordered by (episode, step);
* ``z_true`` — float ``[N, S]`` true state z°;
* ``episode`` — int ``[N]`` episode ids (consecutive rows of one episode are consecutive steps);
* ``rng`` — a ``numpy.random.Generator``; a fixed seed gives a reproducible value.

Register it with the decorator, which also validates inputs before the function runs::

    @repbench.metric("my_metric", higher_is_better=True, description="...")
    def my_metric(z, z_true, episode, rng, *, k=5) -> MetricResult: ...
"""

from __future__ import annotations

from collections.abc import Callable

from repbench.metric_types import Metric, MetricResult, check_metric_inputs
from repbench.registry import metrics

__all__ = ["Metric", "MetricResult", "check_metric_inputs", "metric"]


def metric(name: str, *, higher_is_better: bool, description: str = "", min_samples: int = 10,
           register: bool = True, version: int = 0
           ) -> Callable[[Callable[..., MetricResult]], Metric]:
    """Decorator turning a function into a :class:`Metric` (and registering it by default).

    ``version``: bump it when a change alters the metric's values; stored results of the older
    version then show as stale instead of being reused (:mod:`repbench.records`).
    """

    def wrap(fn: Callable[..., MetricResult]) -> Metric:
        m = Metric(fn, name, higher_is_better, description, min_samples, version=version)
        if register:
            metrics.register(name, m)
        return m

    return wrap
