"""Issue 56, data safety: repbench never deletes or overwrites what is not its own, and never
publishes a number its record contradicts. Each test failed on the code before its fix."""

from __future__ import annotations

import json
import logging
import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import repbench
from repbench.errors import ConfigError, DataError
from repbench.pipeline.evaluate import evaluate_encoder
from repbench.pipeline.plan import build_plan
from repbench.pipeline.records import CHECKSUM, record_checksum
from repbench.pipeline.runner import rebuild_leaderboards, run_suite
from repbench.pipeline.stages import metric_rows
from repbench.pipeline.suite import load_suite
from repbench.registry import metrics

from ..runner.tiny_toy_suite import tiny_toy_suite
from .test_bad_input import _cli, no_stage_runs  # noqa: F401  (a fixture)

ROOT = Path(__file__).resolve().parents[2]
TOY = tiny_toy_suite("toy56", ["oracle", "pca"])
#: The fewest bootstrap resamples a suite may ask for (the smoke suite's).
MIN_BOOTSTRAP = 20


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(suite file, leaderboard folder) of one finished tiny run (a few seconds)."""
    base = tmp_path_factory.mktemp("issue56")
    suite = base / "toy56.toml"
    suite.write_text(TOY)
    result = run_suite(suite, store=base / "store", out=base / "lb", workers=1, progress=False)
    assert not result.report.failed
    return suite, base / "lb"


def _metric_record(folder: Path, encoder: str, metric: str) -> Path:
    for path in sorted(folder.rglob("*.json")):
        r = json.loads(path.read_text())
        if r.get("kind") == "metric" and r["encoder"]["name"] == encoder \
                and r["metric"]["name"] == metric:
            return path
    raise AssertionError(f"no {metric} record of {encoder} in {folder}")


def _edit_value(path: Path, value: float | None) -> None:
    """Set a metric record's value and recompute its checksum (a careful editor)."""
    r = json.loads(path.read_text())
    r["values"]["value"] = value
    r[CHECKSUM] = record_checksum(r)
    path.write_text(json.dumps(r, indent=1, sort_keys=True))


def _warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]


# -- 1. `repbench leaderboard --out DIR` deletes only its own records ----------------------------

def test_leaderboard_out_leaves_files_that_are_not_its_records(finished: tuple[Path, Path],
                                                               tmp_path: Path) -> None:
    suite, lb = finished
    board = tmp_path / "board"
    shutil.copytree(lb, board)
    own = sorted((board / "records").rglob("*.json"))
    foreign = {board / "records" / "notes.json": '{"mine": true}',
               board / "records" / "metric" / "my_analysis.json": "[1, 2, 3]",
               board / "records" / "deep" / "er" / "config.json": "not even JSON"}
    for path, text in foreign.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    stale = own[0].with_name("stale-record.json")  # a record of an earlier write: replaced
    shutil.copy(own[0], stale)
    rebuild_leaderboards(suite, records=lb / "records", out=board)
    for path, text in foreign.items():
        assert path.read_text() == text, f"{path} was deleted or changed"
    assert not stale.exists()
    assert sorted((board / "records").rglob("*.json")) == sorted([*own, *foreign])


# -- 2. `repbench evaluate --out` the reference board itself --------------------------------------

@pytest.mark.usefixtures("no_stage_runs")
@pytest.mark.parametrize("suite, out", [
    ("smoke", "leaderboards/smoke"), ("smoke", "leaderboards/smoke/records"),
    ("smoke", "leaderboards/smoke/records/metric"), ("quick", "leaderboards/quick"),
    ("quick", "leaderboards/quick/door"), ("smoke", "leaderboards")])
def test_evaluate_refuses_to_write_over_the_reference_board(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, suite: str, out: str) -> None:
    folder = ROOT / out
    before = sorted(p.relative_to(folder) for p in folder.rglob("*"))
    err = _cli(capsys, "evaluate", "oracle", "--suite", suite, "--out", str(folder),
               "--store", str(tmp_path / "store"))
    assert f"--out {folder}" in err and "reference" in err and "choose another --out" in err
    assert sorted(p.relative_to(folder) for p in folder.rglob("*")) == before


# -- 3. a metric whose value is NaN or infinite ----------------------------------------------------

@pytest.fixture(params=[math.nan, math.inf])
def bad_metric(request: pytest.FixtureRequest):
    value = request.param

    @repbench.metric("bad56", higher_is_better=True, register=False)
    def bad56(z, z_true, episode, rng, *, n_bootstrap: int = 100):  # type: ignore[no-untyped-def]
        return repbench.MetricResult(value, True, 0.1, 0.2)

    metrics.register("bad56", bad56, replace=True)
    yield value
    metrics.unregister("bad56")


def test_a_metric_that_returns_nan_fails_its_stage(bad_metric: float, tmp_path: Path) -> None:
    suite = tmp_path / "toynan.toml"
    suite.write_text(tiny_toy_suite("toynan", ["oracle"]).replace(
        'metrics = ["ksg", "regression"]', 'metrics = ["ksg", "bad56"]'))
    result = run_suite(suite, store=tmp_path / "store", out=tmp_path / "lb", workers=1,
                       progress=False, no_rl=True)
    failed = {result.report.labels[i]: err for i, err in result.report.failed.items()}
    assert list(failed) == ["ToyReach-v0 bad56 × oracle"]
    err = failed["ToyReach-v0 bad56 × oracle"]
    assert "metric 'bad56'" in err and "encoder 'oracle'" in err and str(bad_metric) in err
    assert "\n" not in err
    stored = [json.loads(p.read_text()) for p in (tmp_path / "store").glob("metric/*/record.json")]
    assert [r["metric"]["name"] for r in stored] == ["ksg"]  # the failed stage is not committed


def test_a_record_whose_value_is_null_is_left_off_the_board(
        finished: tuple[Path, Path], tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    suite, lb = finished
    folder = tmp_path / "records"
    shutil.copytree(lb / "records", folder)
    nulled = _metric_record(folder, "pca", "ksg")
    _edit_value(nulled, None)  # as an older repbench stored a NaN
    with caplog.at_level(logging.WARNING):
        rebuild_leaderboards(suite, records=folder, out=tmp_path / "out")
    said = [w for w in _warnings(caplog) if str(nulled) in w]
    assert len(said) == 1 and "no finite value" in said[0] and "left out" in said[0]
    enc = pd.read_csv(tmp_path / "out" / "encoders.csv").set_index("encoder")
    before = pd.read_csv(lb / "encoders.csv").set_index("encoder")
    assert pd.isna(enc.loc["pca", "ksg"])
    assert enc.loc["oracle", "ksg"] == before.loc["oracle", "ksg"]
    assert str(nulled.name) in (tmp_path / "out" / "index.html").read_text()


# -- 4. too few bootstrap resamples ----------------------------------------------------------------

@pytest.mark.parametrize("old, new, field", [
    ("bootstrap = 20", "bootstrap = 1", "metric_settings.bootstrap"),
    ("bootstrap = 20", f"bootstrap = {MIN_BOOTSTRAP - 1}", "metric_settings.bootstrap"),
    ("[task_params", "[metric_params.ksg]\nn_bootstrap = 2\n[task_params",
     "metric_params.ksg.n_bootstrap")])
def test_too_few_bootstrap_resamples_are_refused(tmp_path: Path, old: str, new: str,
                                                 field: str) -> None:
    path = tmp_path / "few.toml"
    path.write_text(TOY.replace(old, new))
    with pytest.raises(ConfigError) as info:
        load_suite(path)
    msg = str(info.value)
    assert str(path) in msg and field in msg and f"at least {MIN_BOOTSTRAP}" in msg
    assert "\n" not in msg


def test_the_bootstrap_minimum_admits_every_shipped_suite() -> None:
    for name in ("smoke", "quick", "paper"):
        assert load_suite(name).metric_settings.bootstrap >= MIN_BOOTSTRAP
    for path in sorted((ROOT / "leaderboards").rglob("*.toml")):
        if "[metric_settings]" in path.read_text():
            load_suite(path)


# -- 5. an on-policy metric without on-policy rows -------------------------------------------------

@pytest.mark.parametrize("metric", ["action_probe", "smoothness", "smoothness_objective"])
def test_on_policy_metrics_without_on_policy_data_are_refused(tmp_path: Path,
                                                              metric: str) -> None:
    path = tmp_path / "nopolicy.toml"
    path.write_text(TOY.replace('metrics = ["ksg", "regression"]', f'metrics = ["{metric}"]')
                    .replace('["oracle", "pca"]', '["oracle"]'))
    with pytest.raises(ConfigError) as info:
        build_plan(load_suite(path))
    msg = str(info.value)
    assert metric in msg and "on_policy_episodes = 0" in msg and "ToyReach-v0" in msg
    assert "\n" not in msg


def test_the_metric_stage_never_falls_back_from_on_policy_rows() -> None:
    source = np.zeros(30, dtype=np.int64)
    with pytest.raises(DataError) as info:
        metric_rows("on_policy", source, ["heldout"])
    assert "on_policy" in str(info.value) and "\n" not in str(info.value)
    idx, what = metric_rows("all", source, ["heldout"])
    assert idx.size == 30 and what == "all: heldout"


# -- 6. a value outside its own interval ----------------------------------------------------------

def test_a_value_outside_its_own_interval_is_left_off_by_name(
        finished: tuple[Path, Path], tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    suite, lb = finished
    folder = tmp_path / "records"
    shutil.copytree(lb / "records", folder)
    edited = _metric_record(folder, "pca", "regression")
    r = json.loads(edited.read_text())
    _edit_value(edited, r["values"]["ci_low"] - 0.5)
    with caplog.at_level(logging.WARNING):
        rebuild_leaderboards(suite, records=folder, out=tmp_path / "out")
    said = [w for w in _warnings(caplog) if str(edited) in w]
    assert len(said) == 1 and "outside its own interval" in said[0] and "left out" in said[0]
    enc = pd.read_csv(tmp_path / "out" / "encoders.csv").set_index("encoder")
    before = pd.read_csv(lb / "encoders.csv").set_index("encoder")
    assert pd.isna(enc.loc["pca", "regression"])
    assert enc.loc["pca", "ksg"] == before.loc["pca", "ksg"]
    assert edited.name in (tmp_path / "out" / "index.html").read_text()
    # ... and the board's own records do not carry it on
    assert len(list((tmp_path / "out" / "records").rglob("*.json"))) == 12 - 1


def test_evaluate_shows_a_reference_record_it_left_out(finished: tuple[Path, Path],
                                                       tmp_path: Path) -> None:
    suite, lb = finished
    folder = tmp_path / "reference"
    shutil.copytree(lb / "records", folder)
    edited = _metric_record(folder, "oracle", "ksg")
    r = json.loads(edited.read_text())
    _edit_value(edited, r["values"]["ci_high"] + 1.0)
    result = evaluate_encoder("proprio_only", suite, store=tmp_path / "store",
                              out=tmp_path / "out", reference=folder, workers=1, progress=False)
    said = [w for w in result.results.warnings if str(edited) in w]
    assert len(said) == 1 and "outside its own interval" in said[0]
    assert edited.name in (tmp_path / "out" / "index.html").read_text()
