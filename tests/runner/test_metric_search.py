"""The metric search's selection rule (repbench.analysis.metric_search): known answers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from repbench.analysis.metric_search import compare_on, loo_rank_model, nested_selection


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
