"""The metric search's selection rule (repbench.analysis.metric_search): known answers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from repbench.analysis.metric_search import (
    compare_on,
    loo_rank_model,
    loo_rmse,
    nested_selection,
    reference_gaps,
    transfer_model,
)


def _table(n: int = 24, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    return pd.DataFrame(rng.normal(size=(n, 4)), columns=["a", "b", "noise1", "noise2"],
                        index=[f"e{i}" for i in range(n)])


def test_a_return_made_of_two_metrics_selects_that_pair():
    values = _table()
    y = stats.rankdata(values["a"]) + stats.rankdata(values["b"])
    sel = nested_selection(values, dict(zip(values.index, y, strict=True)))
    assert sel.model == ("a", "b")
    assert sel.single in ("a", "b") and sel.single_rho < 0.85
    assert sel.nested_rho > 0.9 > sel.single_rho  # the pair ranks better than either alone


def test_a_return_made_of_one_metric_selects_it_alone():
    values = _table(seed=1)
    y = 3.0 * values["b"].to_numpy() + 1.0
    sel = nested_selection(values, dict(zip(values.index, y, strict=True)))
    assert sel.single == "b" and sel.single_rho == pytest.approx(1.0)
    assert sel.model == ("b",) and sel.nested_rho > 0.95


def test_noise_metrics_get_no_honest_credit():
    values = _table(seed=2)[["noise1", "noise2"]]
    rng = np.random.default_rng(5)
    y = rng.normal(size=len(values))
    sel = nested_selection(values, dict(zip(values.index, y, strict=True)))
    assert sel.nested_rho < 0.5  # the choice redone inside each fold: no selection bonus


def test_loo_of_a_monotone_metric_ranks_perfectly():
    x = np.arange(10.0)[:, None]
    pred = loo_rank_model(x, 2 * np.arange(10.0))
    assert stats.spearmanr(pred, np.arange(10)).statistic == pytest.approx(1.0)


def test_paired_comparison_separates_a_perfect_metric_from_noise():
    values = _table(n=30, seed=3)
    rng = np.random.default_rng(4)
    per_seed = {e: list(values.loc[e, "a"] + 0.1 * rng.normal(size=3)) for e in values.index}
    out = compare_on(values, per_seed, "a", "noise1", n_bootstrap=300)
    assert out["rho_selected"] > 0.95 and out["difference_ci"][0] > 0.3
    same = compare_on(values, per_seed, "a", "a", n_bootstrap=100)
    assert same["difference_ci"] == (0.0, 0.0)


def test_a_model_fitted_on_one_task_ranks_another_by_ranks_not_scales():
    rng = np.random.default_rng(6)
    train = rng.normal(size=(20, 2))
    y = 2 * stats.rankdata(train[:, 0]) + stats.rankdata(train[:, 1])
    test = np.column_stack([1000 + 50 * rng.normal(size=15), -3 + 0.01 * rng.normal(size=15)])
    pred = transfer_model(train, y, test)  # other scales: only the ranks carry over
    truth = 2 * stats.rankdata(test[:, 0]) + stats.rankdata(test[:, 1])
    assert np.corrcoef(pred, truth)[0, 1] == pytest.approx(1.0)  # linear in the test ranks
    one = transfer_model(train[:, 0], y, test[:, 0])  # one column, as a 1-D array
    assert stats.spearmanr(one, test[:, 0]).statistic == pytest.approx(1.0)


def test_loo_rmse_of_a_return_linear_in_the_ranks_is_under_one_rank_step_and_grows_with_noise():
    x = np.arange(30.0)
    exact = loo_rmse(x, 5 * x + 2)  # a held-out encoder is placed among the other 29: its
    assert 0 < exact < 5  # prediction is off by less than one rank step (5)
    noisy = loo_rmse(np.random.default_rng(0).permutation(x), 5 * x + 2)
    assert noisy > 5 * exact


def _record(task, enc, seed, weights):
    return {"kind": "rl", "task": {"name": task}, "encoder": {"name": enc},
            "agent": {"name": "sac"}, "seed": seed, "encoder_weights": weights}


def test_reference_gaps_name_missing_latents_and_seeds_of_other_weights():
    sets = [{"task": "T", "encoder": "a", "encoder_weights": "w1"},
            {"task": "T", "encoder": "b", "encoder_weights": "w2"}]
    rl = ([_record("T", "a", s, "w1") for s in range(3)]
          + [_record("T", "b", 0, "w2"), _record("T", "b", 1, "old"), _record("T", "b", 2, "old")])
    learned = {"T": ["a", "b", "c"]}
    assert reference_gaps(sets, rl, learned) == [
        "T b: 1 of 3 sac seeds of the shipped weights (2 of other weights)",
        "T c: no shipped latents"]
    rl += [_record("T", "b", s, "w2") for s in (1, 2)]
    sets.append({"task": "T", "encoder": "c", "encoder_weights": "w3"})
    rl += [_record("T", "c", s, "w3") for s in range(3)]
    assert reference_gaps(sets, rl, learned) == []
