"""Metrics on held-out data: the plan, the stored arrays and the rows each metric uses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from repbench.errors import DataError
from repbench.pipeline.plan import build_plan
from repbench.pipeline.runner import run_suite
from repbench.pipeline.stages import metric_rows
from repbench.pipeline.store import Store
from repbench.pipeline.suite import load_suite

from .test_runner_toy import SUITE

HELDOUT = (SUITE.replace('metrics = ["ksg", "regression", "coherence"]',
                         'metrics = ["task_cmi", "task_probe", "action_probe", "smoothness"]')
           .replace("[encoder_training]", "heldout_episodes = 3\nheldout_seed = 7\n"
                                          "[encoder_training]")
           .replace('encoders = ["oracle", "pca", "proprio_only"]',
                    'encoders = ["oracle", "proprio_only"]'))


def test_metric_rows_selects_on_policy_and_never_falls_back() -> None:
    source = np.array([0, 0, 1, 1, 1])
    idx, what = metric_rows("on_policy", source, ["heldout", "on_policy"])
    assert idx.tolist() == [2, 3, 4] and what == "on_policy"
    idx, what = metric_rows("all", source, ["heldout", "on_policy"])
    assert idx.tolist() == [0, 1, 2, 3, 4] and what == "all: heldout + on_policy"
    # without on-policy rows the metric is refused, not computed on the others (issue 56)
    with pytest.raises(DataError, match="no on_policy rows"):
        metric_rows("on_policy", np.zeros(3, int), ["random"])


def test_plan_encodes_heldout_and_on_policy_data_only(tmp_path: Path) -> None:
    p = tmp_path / "s.toml"
    p.write_text(HELDOUT)
    tp = build_plan(load_suite(p)).tasks[0]
    assert tp.heldout_dataset is not None
    assert tp.heldout_dataset.config["seed"] == 7
    lat = tp.latents["oracle"]
    assert set(lat.inputs) == {"encoder", "heldout", "on_policy"}
    assert lat.inputs["heldout"][1] == tp.heldout_dataset.key
    assert tp.encoders["oracle"].inputs["dataset"][1] == tp.random_dataset.key
    assert tp.metrics[("oracle", "smoothness")].config["rows"] == "on_policy"
    assert tp.metrics[("oracle", "task_cmi")].config["rows"] == "all"


def test_unknown_heldout_task_param_fails_early(tmp_path: Path) -> None:
    from repbench.errors import ConfigError

    p = tmp_path / "s.toml"
    p.write_text(HELDOUT + '\n[heldout_task_params."ToyReach-v0"]\nhole_samplin = "uniform"\n')
    with pytest.raises(ConfigError, match=r"heldout_task_params\.ToyReach-v0"):
        build_plan(load_suite(p))


def test_run_stores_extra_arrays_and_rows(tmp_path: Path) -> None:
    p = tmp_path / "s.toml"
    p.write_text(HELDOUT)
    res = run_suite(p, store=tmp_path / "store", out=tmp_path / "lb", workers=1, progress=False)
    assert not res.report.failed, res.report.failed
    store = Store(tmp_path / "store")
    tp = build_plan(load_suite(p)).tasks[0]
    art = store.get("latents", tp.latents["oracle"].key)
    with np.load(art.file("latents.npz")) as f:
        assert {"robot_state", "task_state", "action", "source", "source_names"} <= set(f.files)
        assert [str(s) for s in f["source_names"]] == ["heldout", "on_policy"]
        n_on = int((f["source"] == 1).sum())
        assert len(f["z"]) == 3 * 25 + n_on and n_on == 2 * 25  # no training rows
    for m, rows in (("smoothness", "on_policy"), ("action_probe", "on_policy"),
                    ("task_cmi", "all: heldout + on_policy")):
        out = store.get("metric", tp.metrics[("oracle", m)].key).read_json()
        assert out["rows"] == rows
        assert out["n_rows"] == (50 if rows == "on_policy" else 125)
        assert len(out["extras"]["bootstrap_replicates"]) > 0
    html = (tmp_path / "lb" / "index.html").read_text()
    assert html.index("Metric leaderboard") < html.index("Which metric predicts")
    import pandas as pd

    met = pd.read_csv(tmp_path / "lb" / "metrics.csv")
    for col in ("spearman_learned", "spearman_all_p_holm", "spearman_learned_p_bh", "loo_rmse",
                "cost_s"):
        assert col in met.columns
    assert (met["cost_s"] > 0).all() and (met["n_learned"] == 0).all()  # two baselines only
