"""Conformance checks for metrics: run the same checks on your metric that repbench runs on its own.

Example::

    from repbench.testing import check_metric
    check_metric("ksg")                      # a registered name
    check_metric(my_metric, steps=300)       # a Metric object, with metric parameters
"""

from __future__ import annotations

from typing import Any

import numpy as np

from repbench.errors import DataError
from repbench.metric import Metric, MetricResult

__all__ = ["check_metric", "synthetic_extra_inputs", "synthetic_true_state"]


def synthetic_true_state(n_episodes: int = 10, steps: int = 60, dynamic_dims: int = 6,
                         static_dims: int = 2, seed: int = 0
                         ) -> tuple[np.ndarray, np.ndarray]:
    """A standardized synthetic true state shaped like the peg-in-hole data.

    ``dynamic_dims`` random-walk dimensions (robot state) and ``static_dims`` dimensions
    constant within an episode (the hole position). Returns ``(z_true, episode)`` with rows
    ordered by (episode, step).
    """
    rng = np.random.default_rng(seed)
    episode = np.repeat(np.arange(n_episodes), steps)
    walks = [np.cumsum(0.1 * rng.standard_normal((steps, dynamic_dims)), axis=0)
             + rng.standard_normal(dynamic_dims) for _ in range(n_episodes)]
    hole = np.repeat(rng.uniform(-1, 1, (n_episodes, static_dims)), steps, axis=0)
    z_true = np.hstack([np.concatenate(walks), hole])
    return (z_true - z_true.mean(0)) / z_true.std(0), episode


def synthetic_extra_inputs(z_true: np.ndarray, episode: np.ndarray, static_dims: int = 2,
                           seed: int = 0) -> dict[str, np.ndarray]:
    """Extra metric inputs consistent with :func:`synthetic_true_state`'s ``z_true``.

    ``robot_state``: the random-walk (dynamic) dimensions; ``task_state``: the first
    ``static_dims`` dynamic dimensions minus the static "hole" dimensions, then the next
    ``static_dims`` dynamic dimensions (a velocity-like part the robot state determines);
    ``action``: a clipped pull towards the hole plus noise; ``reward``: minus the sum of the
    offset's components (linear in the task state, so a probe of it has a known answer);
    ``source``: all zeros.
    """
    rng = np.random.default_rng(seed)
    robot = z_true[:, :-static_dims]
    hole = z_true[:, -static_dims:]
    offset = robot[:, :static_dims] - hole
    task = np.hstack([offset, robot[:, static_dims:2 * static_dims]])
    action = np.clip(-offset + 0.1 * rng.standard_normal(offset.shape), -1.0, 1.0)
    return {"robot_state": robot, "task_state": task, "action": action,
            "reward": -offset.sum(axis=1), "source": np.zeros(len(z_true), dtype=np.int64)}


def _expect_data_error(m: Metric, what: str, *args: Any, **params: Any) -> None:
    try:
        m(*args, **params)
    except DataError as exc:
        msg = str(exc)
        assert msg and "\n" not in msg, f"{m.name}: DataError for {what} is not one line: {msg!r}"
        return
    except Exception as exc:  # a crash deep inside is not an actionable error
        raise AssertionError(
            f"{m.name}: {what} raised {type(exc).__name__} ({exc}) instead of DataError"
        ) from exc
    raise AssertionError(f"{m.name}: {what} was accepted; it must raise DataError")


def check_metric(metric_or_name: Metric | str, *, n_episodes: int = 10, episode_steps: int = 60,
                 seed: int = 0, **params: Any) -> MetricResult:
    """Check a metric against the repbench metric contract; raise AssertionError on failure.

    Checks: it returns a :class:`MetricResult` with the registered direction and a finite
    value; a fixed seed reproduces value and CI; the CI is either None on both ends or
    brackets the value (``ci_low <= value <= ci_high``); NaN, misaligned rows, a 1-D ``z``
    and too few samples raise :class:`DataError` with a one-line message; the true state as
    ``z`` scores better than a random map (independent noise), respecting the direction —
    except for a label-free metric (:attr:`Metric.label_free`: it reads nothing but z, e.g.
    RankMe), which cannot know which z is the true state.
    ``params`` are passed to the metric (e.g. ``steps=300`` for a slow estimator); a metric
    that asks for extra arrays (``robot_state``, ``task_state``, ``action``, ``source``) gets
    the synthetic ones of :func:`synthetic_extra_inputs` unless ``params`` gives them. Returns
    the true-state result.
    """
    if isinstance(metric_or_name, str):
        from repbench.registry import metrics

        m = metrics.get(metric_or_name)
    else:
        m = metric_or_name
    assert isinstance(m, Metric), f"{m!r} is not a repbench.Metric; decorate it with @metric"
    params.setdefault("n_bootstrap", 20)
    z_true, episode = synthetic_true_state(n_episodes, episode_steps, seed=seed)
    extra = synthetic_extra_inputs(z_true, episode, seed=seed)
    for key in m.extra_inputs:  # the arrays the metric asks for (repbench.metric.EXTRA_INPUTS)
        params.setdefault(key, extra[key])
    rng = np.random.default_rng(seed + 1)
    z_random = rng.standard_normal(z_true.shape)

    res = m(z_true, z_true, episode, seed, **params)
    assert isinstance(res, MetricResult), f"{m.name}: returned {type(res)}, not MetricResult"
    assert res.higher_is_better == m.higher_is_better, f"{m.name}: direction mismatch"
    assert np.isfinite(res.value), f"{m.name}: value {res.value} is not finite"
    again = m(z_true, z_true, episode, seed, **params)
    assert (again.value, again.ci_low, again.ci_high) == (res.value, res.ci_low, res.ci_high), (
        f"{m.name}: not reproducible with a fixed seed: {res.value} then {again.value}"
    )
    assert (res.ci_low is None) == (res.ci_high is None), f"{m.name}: half a CI"
    if res.ci_low is not None and res.ci_high is not None:
        tol = 1e-9 * max(1.0, abs(res.value))
        assert res.ci_low - tol <= res.value <= res.ci_high + tol, (
            f"{m.name}: CI [{res.ci_low}, {res.ci_high}] does not bracket {res.value}"
        )
    res.to_dict()  # extras must be serializable

    bad = z_true.copy()
    bad[3, 1] = np.nan
    _expect_data_error(m, "NaN in z", bad, z_true, episode, seed, **params)
    _expect_data_error(m, "NaN in z_true", z_true, bad, episode, seed, **params)
    _expect_data_error(m, "misaligned rows", z_true[:-5], z_true, episode, seed, **params)
    _expect_data_error(m, "1-D z", z_true[:, 0], z_true, episode, seed, **params)
    _expect_data_error(m, "too few samples", z_true[:3], z_true[:3], episode[:3], seed, **params)
    _expect_data_error(m, "misaligned episode ids", z_true, z_true, episode[:-1], seed, **params)

    if m.label_free:  # it reads nothing but z: it cannot know which z is the true state
        return res
    rand = m(z_random, z_true, episode, seed, **params)
    better = rand.value < res.value if m.higher_is_better else rand.value > res.value
    assert better, (
        f"{m.name}: true state as z ({res.value:.4g}) does not beat a random map "
        f"({rand.value:.4g}); higher_is_better={m.higher_is_better}"
    )
    return res
