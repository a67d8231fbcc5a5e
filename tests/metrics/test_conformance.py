"""The public conformance kit run over every registered metric."""

from __future__ import annotations

import pytest

from repbench.registry import metrics
from repbench.testing import check_metric

# Small MINE budget so the default test run stays fast; the paper's settings are exercised in
# the slow sanity test and the benchmark.
PARAMS = {"mine": {"steps": 600, "learning_rate": 1e-3, "eval_every": 100}}


@pytest.mark.parametrize("name", metrics.names())
def test_check_metric(name: str) -> None:
    check_metric(name, **PARAMS.get(name, {}))


def test_check_metric_catches_wrong_direction() -> None:
    from repbench.metric import MetricResult, metric

    @metric("_inverted", higher_is_better=True, register=False)
    def inverted(z, z_true, episode, rng, n_bootstrap=0):  # random beats truth
        return MetricResult(float(-abs(z - z_true).sum()) * -1.0, True)

    with pytest.raises(AssertionError, match="does not beat a random map"):
        check_metric(inverted)
