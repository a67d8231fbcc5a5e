"""Speed at the paper's size (n = 7500, 16 + 16 dims). Run with
``pytest --benchmark-only -m "slow or not slow" tests/metrics``."""

from __future__ import annotations

import numpy as np
import pytest

from repbench.metrics.mutual_information import ksg_mi
from repbench.registry import metrics
from repbench.testing.metric import synthetic_extra_inputs, synthetic_true_state

from ._reference import ksg_mi_reference


@pytest.fixture(scope="module")
def paper_size() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    z_true, episode = synthetic_true_state(25, 300, dynamic_dims=14, static_dims=2, seed=0)
    w = np.random.default_rng(0).standard_normal((16, 16)) / 4
    return np.tanh(z_true @ w), z_true, episode


def _once(benchmark, fn, *args, **kw):
    return benchmark.pedantic(fn, args=args, kwargs=kw, rounds=1, iterations=1)


@pytest.mark.slow
def test_bench_ksg_kdtree(benchmark, paper_size) -> None:
    z, zt, _ = paper_size
    _once(benchmark, ksg_mi, z, zt)


@pytest.mark.slow
def test_bench_ksg_per_point_reference(benchmark, paper_size) -> None:
    z, zt, _ = paper_size
    _once(benchmark, ksg_mi_reference, z, zt)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["mine", "regression", "coherence", "smoothness_objective",
                                  "task_cmi", "task_r2_gain", "task_probe", "action_probe"])
def test_bench_metric(benchmark, paper_size, name: str) -> None:
    z, zt, ep = paper_size
    fn = metrics.get(name)
    extra = synthetic_extra_inputs(zt, ep)
    kw = {k: extra[k] for k in fn.extra_inputs}
    res = _once(benchmark, fn, z, zt, ep, 0, n_bootstrap=100, **kw)
    benchmark.extra_info["value"] = res.value
    if name == "mine":
        benchmark.extra_info["steps"] = res.extras["steps"]
        benchmark.extra_info["curve"] = res.extras["held_out_curve"]
