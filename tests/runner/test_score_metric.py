"""`repbench score-metric` and the shipped latents format, on a toy reference run: the built-in
metrics computed from exported latents reproduce the run's metric records; a metric in a plain
file is scored beside them; damaged files are refused."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import repbench
from repbench.analysis.latent_sets import MANIFEST, read_latent_sets
from repbench.analysis.results import load_records
from repbench.errors import ConfigError, DataError
from repbench.pipeline.latents_export import export_latents
from repbench.pipeline.runner import rebuild_leaderboards, run_suite
from repbench.pipeline.score_metric import read_scores, score_metric, score_metrics
from repbench.registry import encoders

from .tiny_toy_suite import tiny_toy_suite


class _ProprioPart(repbench.Encoder):
    """The first ``width`` proprioception values (learned family, for the within-learned ρ)."""

    required_modalities = ("proprio",)
    family = "probe_test"
    width = 1

    def __init__(self) -> None:
        pass

    def fit(self, dataset: repbench.Dataset) -> _ProprioPart:
        self.fitted_ = True
        return self

    def encode(self, observations):  # type: ignore[no-untyped-def]
        self.check_is_fitted()
        p = self.check_observations(observations)["proprio"]
        return p[:, : self.width].astype(np.float32)

    @property
    def latent_dim(self) -> int:
        return self.width


class Part1(_ProprioPart):
    width = 1


class Part2(_ProprioPart):
    width = 2


class Part3(_ProprioPart):
    width = 3


class Part4(_ProprioPart):
    width = 4


PARTS = {"part1": Part1, "part2": Part2, "part3": Part3, "part4": Part4}
SUITE = tiny_toy_suite("toyscore", ["oracle", "random", *PARTS]).replace(
    "seeds = [0]", "seeds = [0, 1]")

FILE_METRIC = '''
import numpy as np


def spread(z, z_true, episode, rng):
    """Total variance of z (a plain function returning a number)."""
    return float(np.var(z, axis=0).sum())
'''


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("score")
    for name, cls in PARTS.items():
        encoders.register(name, cls, replace=True)
    (root / "toyscore.toml").write_text(SUITE)
    run_suite(root / "toyscore.toml", store=root / "store", out=root / "ref", workers=1,
              progress=False)
    export_latents(root / "toyscore.toml", store=root / "store", out=root / "latents")
    yield root
    for name in PARTS:
        encoders.unregister(name)


def _score(root: Path, metric: str, n_bootstrap: int = 200, **kw):  # type: ignore[no-untyped-def]
    return score_metric(metric, str(root / "toyscore.toml"), reference=root / "ref" / "records",
                        latents=root / "latents", workers=1, progress=False,
                        n_bootstrap=n_bootstrap, **kw)


def test_every_encoder_is_exported_once_with_the_task_data_stored_once(reference: Path):
    manifest = json.loads((reference / "latents" / MANIFEST).read_text())
    assert sorted(e["encoder"] for e in manifest["sets"]) == sorted(
        ["oracle", "random", *PARTS])
    assert len(manifest["data"]) == 1  # z°, episodes, actions ... once for the task
    records = {r["encoder"]["name"]: r for r in load_records(reference / "ref" / "records",
                                                              kinds=("latents",))}
    for entry in manifest["sets"]:
        record = records[entry["encoder"]]
        assert entry["latents_identity"] == record["identity"]
        assert entry["encoder_weights"] == record["encoder_weights"]
        assert entry["file"].endswith(f"-{record['identity'][:8]}.npz")
    sets = read_latent_sets(reference / "latents")
    z = sets[0].arrays()["z"]
    assert z.dtype == np.float32 and z.shape[1] == sets[0].entry["latent_dim"]


def test_exporting_again_changes_no_byte(reference: Path, tmp_path: Path):
    before = {p.name: p.read_bytes() for p in (reference / "latents").rglob("*.npz")}
    export_latents(reference / "toyscore.toml", store=reference / "store",
                   out=reference / "latents")
    after = {p.name: p.read_bytes() for p in (reference / "latents").rglob("*.npz")}
    assert before == after


def test_builtin_metrics_from_the_shipped_latents_reproduce_the_records_exactly(
        reference: Path):
    records = load_records(reference / "ref" / "records", kinds=("metric",))
    scored = score_metrics(["ksg", "regression"], str(reference / "toyscore.toml"),
                           reference=reference / "ref" / "records", latents=reference / "latents",
                           workers=1, progress=False, n_bootstrap=200)  # both in one ranking
    assert sorted(scored.row["metric"]) == ["ksg", "regression"]
    for metric in ("ksg", "regression"):
        shipped = {r["encoder"]["name"]: r["values"] for r in records
                   if r["metric"]["name"] == metric}
        mine = scored.values[scored.values["metric"] == metric]
        values = dict(zip(mine["encoder"], mine["value"], strict=True))
        assert set(values) == set(shipped)
        for enc, v in values.items():
            assert v == shipped[enc]["value"], (metric, enc)


def test_a_plain_file_metric_is_scored_beside_the_reference_metrics(reference: Path,
                                                                    tmp_path: Path):
    (tmp_path / "my_metric.py").write_text(FILE_METRIC)
    out = tmp_path / "scored"
    result = _score(reference, f"{tmp_path / 'my_metric.py'}:spread", out=out, observable=True)
    row = result.row.iloc[0]
    assert row["group"] == "observable"
    assert set(result.ranking.loc[result.ranking["metric"] != "spread", "group"]) == {
        "privileged"}
    assert result.metric == "spread" and len(result.row) == 1
    assert row["n_learned"] == 4 and row["n_all"] == 6
    assert set(result.ranking["metric"]) == {"ksg", "regression", "spread"}
    assert 1 <= row["rank"] <= row["n_metrics"] == 3
    for col in ("spearman_learned_ci_low", "spearman_learned_p_holm", "noise_ceiling",
                "of_ceiling"):
        assert col in result.row.columns
    # wider parts of the state have more variance: the metric's values order the parts
    v = dict(zip(result.values["encoder"], result.values["value"], strict=True))
    assert v["part1"] < v["part4"]
    assert (out / "spread.csv").is_file() and (out / "metrics.csv").is_file()
    assert (out / "figures" / "spread_vs_return.png").stat().st_size > 1000
    assert pd.read_csv(out / "spread.csv")["metric"].tolist() == ["spread"]


def test_the_command_line_scores_a_file_metric(reference: Path, tmp_path: Path):
    (tmp_path / "my_metric.py").write_text(FILE_METRIC)
    proc = subprocess.run(
        [sys.executable, "-m", "repbench.cli", "score-metric", "my_metric.py:spread",
         "--suite", str(reference / "toyscore.toml"), "--reference",
         str(reference / "ref" / "records"), "--latents", str(reference / "latents"),
         "--out", "scored", "--workers", "1"],
        cwd=tmp_path, capture_output=True, text=True, timeout=300)
    # the toy encoders are registered in this process only: the subprocess cannot build them,
    # but score-metric needs no encoder, only the shipped files
    assert proc.returncode == 0, proc.stderr
    assert "ToyReach-v0 sac: spread within-learned ρ" in proc.stdout
    assert "noise ceiling" in proc.stdout
    assert (tmp_path / "scored" / "spread.csv").is_file()


def test_a_damaged_latents_file_is_refused_by_name(reference: Path, tmp_path: Path):
    import shutil

    copy = tmp_path / "latents"
    shutil.copytree(reference / "latents", copy)
    victim = next(copy.rglob("*part2*.npz"))
    data = bytearray(victim.read_bytes())
    data[-30] ^= 0xFF
    victim.write_bytes(bytes(data))
    with pytest.raises(DataError, match=f"{victim.name}.*checksum"):
        score_metric("ksg", str(reference / "toyscore.toml"),
                     reference=reference / "ref" / "records", latents=copy, workers=1,
                     progress=False, n_bootstrap=50)


def _board(root: Path, out: Path, scores: list[Path]) -> Path:
    """The toy reference's board rebuilt from its records with the metrics scored in
    ``scores``."""
    return rebuild_leaderboards(str(root / "toyscore.toml"), records=root / "ref" / "records",
                                out=out, copy_records=False, scores=scores)


@pytest.fixture(scope="module")
def scored_board(reference: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A registered metric (rankme) and a plain-file one (spread, observable) scored into
    ``scores/`` with the board's 1000 resamples, and the toy board rebuilt from its records
    with them by the command line (``board/``): one board for the tests below."""
    from typer.testing import CliRunner

    from repbench.cli import app

    root = tmp_path_factory.mktemp("scored_board")
    (root / "my_metric.py").write_text(FILE_METRIC)
    scored = score_metrics(["rankme", f"{root / 'my_metric.py'}:spread"],
                           str(reference / "toyscore.toml"),
                           reference=reference / "ref" / "records", latents=reference / "latents",
                           workers=1, progress=False, n_bootstrap=1000, observable=True,
                           out=root / "scores")
    got = CliRunner().invoke(app, [
        "leaderboard", "--suite", str(reference / "toyscore.toml"), "--records",
        str(reference / "ref" / "records"), "--no-copy-records", "--out", str(root / "board"),
        "--scores", str(root / "scores")])
    assert got.exit_code == 0, got.output
    assert scored.results is not None
    (root / "rows.json").write_text(json.dumps(  # the rows score-metric ranked
        [r for r in scored.results.metric_rows if r["metric"] in ("rankme", "spread")]))
    return root


def test_scored_metrics_join_the_board_ranked_exactly_as_score_metric_ranked_them(
        reference: Path, scored_board: Path):
    from repbench.analysis.correlation import adjust_pvalues
    from repbench.analysis.results import build_results
    from repbench.report.leaderboard import metric_ranking

    # the folder gives back every digit of the rows score-metric ranked, replicates included
    ranked_rows = json.loads((scored_board / "rows.json").read_text())
    read = read_scores(scored_board / "scores").rows
    assert len(read) == len(ranked_rows) == 12
    for mine, theirs in zip(read, ranked_rows, strict=True):
        for k in ("task", "encoder", "metric", "value", "ci_low", "ci_high", "time_s"):
            assert mine[k] == theirs[k], (k, mine, theirs)
        reps = theirs["extras"].get("bootstrap_replicates")
        assert mine["extras"].get("bootstrap_replicates") == reps
        assert bool(reps) == (theirs["metric"] == "rankme")
    board = scored_board / "board"
    met = pd.read_csv(board / "metrics.csv")
    # score-metric's ranking of every metric (rankme and spread with the records' ksg and
    # regression): the board ranks the same rows with the same bootstrap, so every number
    # agrees (cost_cpu_s aside: the board counts a scored metric's time_s as its CPU seconds)
    ranked = pd.read_csv(scored_board / "scores" / "metrics.csv")
    cols = [c for c in ranked.columns if c not in ("rank", "n_metrics", "cost_cpu_s")]
    assert {"spearman_learned", "spearman_learned_ci_low", "spearman_learned_ci_high",
            "spearman_learned_p_holm", "n_learned", "group", "noise_ceiling"} <= set(cols)
    key = ["task", "agent", "metric"]
    pd.testing.assert_frame_equal(met[cols].sort_values(key).reset_index(drop=True),
                                  ranked[cols].sort_values(key).reset_index(drop=True))
    row = met[met["metric"] == "rankme"].iloc[0]
    assert row["group"] == "observable" and row["n_learned"] == 4
    assert np.isfinite(row["spearman_learned_ci_low"])
    # Holm over every metric of the task: the records' 2 and the 2 scored
    alone, _ = metric_ranking(build_results(load_records(reference / "ref" / "records")),
                              n_bootstrap=20)
    assert alone.groupby(["task", "agent"]).size().tolist() == [2]
    assert met.groupby(["task", "agent"]).size().tolist() == [4]
    holm = adjust_pvalues(met["spearman_learned_p"].tolist(), "holm")
    np.testing.assert_allclose(met["spearman_learned_p_holm"], holm, rtol=1e-4)
    before = dict(zip(alone["metric"], alone["spearman_learned_p_holm"], strict=True))
    for metric, p in zip(met["metric"], met["spearman_learned_p_holm"], strict=True):
        if metric in before:
            assert p >= before[metric] - 1e-6
    prov = json.loads((board / "provenance.json").read_text())
    assert prov["scores"] == [{"folder": "../scores", "metrics": ["rankme", "spread"],
                               "rows": 12, "rows_off_board": 0,
                               "bootstrap_replicates": True, "manifest": True}]
    assert prov["directions"]["rankme"] is True and prov["directions"]["spread"] is True
    page = (board / "index.html").read_text(encoding="utf-8")
    assert "rankme" in page and "spread" in page
    assert (board / "figures" / "metric_vs_return.png").stat().st_size > 1000


def test_a_plain_file_metric_on_the_board_is_observable(scored_board: Path):
    manifest = json.loads((scored_board / "scores" / "scored.json").read_text())
    assert (manifest["format"], manifest["version"]) == ("repbench.scores", 1)
    assert [(m["name"], m["reference"], m["higher_is_better"], m["group"])
            for m in manifest["metrics"]] == [
        ("rankme", "rankme", True, "observable"),
        ("spread", f"{scored_board / 'my_metric.py'}:spread", True, "observable")]
    met = pd.read_csv(scored_board / "board" / "metrics.csv")
    groups = dict(zip(met["metric"], met["group"], strict=True))
    assert groups == {"spread": "observable", "rankme": "observable", "ksg": "privileged",
                      "regression": "privileged"}
    prov = json.loads((scored_board / "board" / "provenance.json").read_text())
    assert prov["groups"] == {"rankme": "observable", "spread": "observable"}


def _legacy(folder: Path, metric: str, task: str = "ToyReach-v0") -> Path:
    """A score-metric folder as written before scored.json: ``<metric>.csv`` and
    ``<metric>_values.csv`` of the toy encoders."""
    folder.mkdir(parents=True)
    encs = ["oracle", "random", *PARTS]
    pd.DataFrame({"task": task, "encoder": encs, "value": np.arange(len(encs), dtype=float),
                  "ci_low": np.nan, "ci_high": np.nan, "time_s": 0.01}).to_csv(
        folder / f"{metric}_values.csv", index=False)
    pd.DataFrame({"task": [task], "agent": ["sac"], "metric": [metric]}).to_csv(
        folder / f"{metric}.csv", index=False)
    pd.DataFrame({"task": [task], "agent": ["sac"], "metric": ["ksg"]}).to_csv(
        folder / "metrics.csv", index=False)  # the board's own metrics: not scored here
    return folder


def test_bad_scores_folders_are_refused_in_one_line_naming_the_thing(reference: Path,
                                                                     tmp_path: Path):
    legacy = read_scores(_legacy(tmp_path / "old", "rankme"))  # direction, group: registry
    assert (legacy.directions, legacy.groups) == ({"rankme": True}, {"rankme": "observable"})
    assert not legacy.manifest  # the board says its intervals lack the metric's own noise
    assert [r["stage_cpu_s"] for r in legacy.rows] == [0.01] * 6
    assert {r["ci_low"] for r in legacy.rows} == {None}
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "metrics.csv").write_text("task,agent,metric\n")
    cases = [
        ([tmp_path / "empty"], r"--scores .*empty: no <metric>_values\.csv there"),
        ([_legacy(tmp_path / "clash", "ksg")],
         r"metric ksg is both in the records and in --scores .*clash"),
        ([tmp_path / "old", _legacy(tmp_path / "again", "rankme")],
         r"metric rankme is in --scores .*old and in --scores .*again"),
        ([_legacy(tmp_path / "unknown", "spread")],
         r"metric spread is not registered here .*rescore it with `repbench score-metric"),
        ([_legacy(tmp_path / "elsewhere", "nesum", task="OtherTask-v0")],
         r"--scores .*elsewhere has no rows of this board's tasks"),
    ]
    for scores, message in cases:
        with pytest.raises(ConfigError, match=message) as info:
            _board(reference, tmp_path / "board", scores)
        assert "\n" not in str(info.value)
    assert not (tmp_path / "board").exists()  # refused before writing anything


def _search():  # type: ignore[no-untyped-def]
    """studies/metric_search/search.py, the pre-registered search's steps, as a module."""
    import importlib.util

    path = Path(__file__).parents[2] / "studies" / "metric_search" / "search.py"
    spec = importlib.util.spec_from_file_location("metric_search_steps", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_metric_searchs_steps_run_in_order_on_a_toy_reference(
        reference: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    search = _search()
    toy = ["--suite", str(reference / "toyscore.toml"), "--latents", str(reference / "latents"),
           "--reference", str(reference / "ref" / "records"), "--select-task", "ToyReach-v0",
           "--test-task", "ToyReach-v0", "--out", str(tmp_path / "search")]
    assert search.main(["check", *toy]) == 1  # 2 SAC seeds where the pre-registration wants 3
    assert "part1: 2 of 3 sac seeds of the shipped weights" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="the reference is not complete"):
        search.main(["select", *toy])
    toy += ["--n-seeds", "2", "--candidates", "rankme", "nesum", "--no-progress",
            "--baseline", "ksg"]  # the toy suite has no task_cmi
    assert search.main(["check", *toy]) == 0
    assert search.main(["select", *toy]) == 0
    # the selection needs only its own task complete; the held-out test needs both
    incomplete = list(toy)
    incomplete[incomplete.index("--test-task") + 1] = "ToyUnmade-v0"
    with pytest.raises(SystemExit, match="not complete on ToyReach-v0, ToyUnmade-v0"):
        search.main(["test", *incomplete, "--uncommitted-ok"])
    args = argparse.Namespace(suite=str(reference / "toyscore.toml"),
                              latents=str(reference / "latents"),
                              reference=[str(reference / "ref" / "records")], n_seeds=2)
    search._refuse_partial(args, ("ToyReach-v0",))  # select's check: passes
    with pytest.raises(SystemExit, match="not complete on ToyUnmade-v0"):
        search._refuse_partial(args, ("ToyUnmade-v0",))
    sel = json.loads((tmp_path / "search" / "selection.json").read_text())
    assert sel["n_learned"] == 4 and sel["candidates"] == ["rankme", "nesum"]
    assert {r["metric"] for r in sel["ranking"]} == {"ksg", "regression", "rankme", "nesum"}
    assert sel["single"] in sel["metrics"] and set(sel["model"]) <= set(sel["metrics"])
    assert sel["best_observable"] in ("rankme", "nesum")
    with pytest.raises(SystemExit, match="is not committed"):  # tmp_path is no git checkout
        search.main(["test", *toy])
    assert search.main(["test", *toy, "--uncommitted-ok"]) == 0
    test = json.loads((tmp_path / "search" / "test.json").read_text())
    assert set(test["checks"]) == {"single", "model", "best_observable"}
    for check in test["checks"].values():
        assert check["verdict"] in ("beats ksg", "holds", "does not hold", "inconclusive")
        assert check["baseline"] == "ksg" and check["n"] == 4
    assert test["evaluate_switches_to"] in (None, sel["single"], " + ".join(sel["model"]))


def test_scored_metrics_are_ranked_but_not_calibrated_on() -> None:
    """`repbench evaluate` calibrates on the board's own metrics; a metric joined from
    --scores (here a perfect one) must not become the board's calibration predictor, so the
    coverage rows stay those evaluate states."""
    from repbench.analysis.results import Results
    from repbench.report.leaderboard import metric_ranking, robustness_checks

    rng = np.random.default_rng(0)
    m = np.linspace(0, 1, 12)
    res = Results(suite="toy")
    res.metric_rows = [{"task": "T", "encoder": f"e{i}", "metric": name, "value": float(v),
                        "ci_low": None, "ci_high": None}
                       for i in range(12)
                       for name, v in (("own", m[i] + rng.normal(0, 0.5)), ("scored", m[i]))]
    res.rl_rows = [{"task": "T", "encoder": f"e{i}", "agent": "sac", "seed": s,
                    "train_steps": 10_000, "eval_return": float(500 * m[i] + rng.normal(0, 10))}
                   for i in range(12) for s in range(3)]
    ranking, _ = metric_ranking(res, n_bootstrap=50)
    assert ranking.iloc[0]["metric"] == "scored"  # ranked: the best on the board
    robustness_checks(res, ranking)
    assert "scored" in set(res.robustness["heldout"]["predictor"].str.split(" ").sum())
    res.provenance["scores"] = [{"metrics": ["scored"]}]
    robustness_checks(res, ranking)
    predictors = set(res.robustness["heldout"]["predictor"])
    assert predictors and all("scored" not in p for p in predictors), predictors
