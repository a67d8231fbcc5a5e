"""Aggregation of RL returns over seeds (rliable: mean, IQM, stratified bootstrap)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from repbench.errors import ConfigError
from repbench.rl.aggregate import aggregate_seeds


def test_point_estimates_are_mean_and_interquartile_mean() -> None:
    scores = [10.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 700.0]
    out = aggregate_seeds({"a": scores}, reps=200)["a"]
    assert out["mean"] == pytest.approx(np.mean(scores))
    # IQM drops the lowest and highest quarter: mean of 3, 4, 5, 6 ... of the sorted middle
    assert out["iqm"] == pytest.approx(np.mean(sorted(scores)[2:6]))
    assert out["iqm"] == pytest.approx(stats.trim_mean(scores, 0.25))
    assert out["n_seeds"] == 8


def test_intervals_contain_the_point_and_match_a_percentile_bootstrap() -> None:
    rng = np.random.default_rng(0)
    scores = rng.normal(100, 20, size=10)
    out = aggregate_seeds({"a": scores}, reps=4000, seed=1)["a"]
    for stat in ("mean", "iqm"):
        assert out[f"{stat}_ci_low"] <= out[stat] <= out[f"{stat}_ci_high"]
    ref = stats.bootstrap((scores,), np.mean, n_resamples=4000, method="percentile",
                          random_state=2).confidence_interval
    # two independent 4000-resample percentile bootstraps agree to ~1 point on this data
    assert out["mean_ci_low"] == pytest.approx(ref.low, abs=2.0)
    assert out["mean_ci_high"] == pytest.approx(ref.high, abs=2.0)


def test_separated_encoders_get_disjoint_intervals_and_one_seed_collapses() -> None:
    out = aggregate_seeds({"good": [900, 880, 910], "bad": [60, 80, 70], "one": [5.0]},
                          reps=500)
    assert out["good"]["mean_ci_low"] > out["bad"]["mean_ci_high"]
    assert out["one"]["mean_ci_low"] == out["one"]["mean_ci_high"] == 5.0
    assert aggregate_seeds({"none": []}) == {}


def test_deterministic_in_its_seed() -> None:
    a = aggregate_seeds({"x": [1.0, 5.0, 2.0, 8.0]}, reps=300, seed=3)
    assert a == aggregate_seeds({"x": [1.0, 5.0, 2.0, 8.0]}, reps=300, seed=3)


@pytest.mark.parametrize("bad", [{"x": [1.0, np.nan]}, {"x": [np.inf]}])
def test_non_finite_scores_are_refused(bad) -> None:
    with pytest.raises(ConfigError, match="'x'"):
        aggregate_seeds(bad)


def test_bad_reps_is_refused() -> None:
    with pytest.raises(ConfigError, match="reps"):
        aggregate_seeds({"x": [1.0]}, reps=0)


def test_leaves_numpy_global_random_state_alone() -> None:
    np.random.seed(5)
    expected = np.random.rand()
    np.random.seed(5)
    aggregate_seeds({"x": [1.0, 2.0, 4.0]}, reps=100, seed=9)
    assert np.random.rand() == expected
