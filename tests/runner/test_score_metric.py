"""`repbench score-metric` and the shipped latents format, on a toy reference run: the built-in
metrics computed from exported latents reproduce the run's metric records; a metric in a plain
file is scored beside them; damaged files are refused."""

from __future__ import annotations

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
from repbench.errors import DataError
from repbench.pipeline.latents_export import export_latents
from repbench.pipeline.runner import run_suite
from repbench.pipeline.score_metric import score_metric, score_metrics
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


def _score(root: Path, metric: str, **kw):  # type: ignore[no-untyped-def]
    return score_metric(metric, str(root / "toyscore.toml"), reference=root / "ref" / "records",
                        latents=root / "latents", workers=1, progress=False, n_bootstrap=200,
                        **kw)


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
    # the selection needs only its own task complete; the held-out test needs both
    incomplete = list(toy)
    incomplete[incomplete.index("--test-task") + 1] = "ToyUnmade-v0"
    assert search.main(["select", *incomplete]) == 0
    with pytest.raises(SystemExit, match="not complete on ToyReach-v0, ToyUnmade-v0"):
        search.main(["test", *incomplete, "--uncommitted-ok"])
    assert search.main(["select", *toy]) == 0
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
