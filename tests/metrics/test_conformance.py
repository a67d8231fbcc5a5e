"""The public conformance kit run over every registered metric."""

from __future__ import annotations

import pytest

from repbench.registry import metrics
from repbench.testing import check_metric

# Small MINE budget so the default test run stays fast; the paper's settings are exercised in
# the slow sanity test and the benchmark.
PARAMS = {"mine": {"steps": 600, "learning_rate": 1e-3, "eval_every": 100},
          # on the kit's 10 episodes (7 training holes) no probe reaches ε = 0.2, so the true
          # state and a random map tie at log2(2 · 4096); 20 episodes let the true state reach
          # it at 64 rows (measured L(64) = 0.12). The metric keeps its registered defaults.
          "task_eps_samples": {"n_episodes": 20},
          # the return-to-go is one value per step of an episode's tail: on 7 training
          # episodes the ridge probe overfits (the true state's held-out R² about -1); 20 give
          # it enough. The metrics keep their registered defaults.
          "value_probe": {"n_episodes": 20}, "value_probe_gain": {"n_episodes": 20}}


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
