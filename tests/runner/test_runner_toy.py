"""The runner on the fast toy task, in-process: plan, run, resume, isolate failures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from repbench.analysis.results import build_results, load_records
from repbench.analysis.robustness import validated_method
from repbench.analysis.transfer import predict_task
from repbench.errors import ConfigError
from repbench.metric import MetricResult, metric
from repbench.pipeline.runner import rebuild_leaderboards, run_suite
from repbench.registry import metrics
from repbench.report.families import encoder_families
from repbench.report.leaderboard import write_leaderboards

SUITE = """
name = "toy"
tasks = ["ToyReach-v0"]
encoders = ["oracle", "pca", "proprio_only"]
metrics = ["ksg", "regression", "coherence"]
agents = ["sac"]
seeds = [0, 1]
[dataset]
random_episodes = 4
random_steps = 25
on_policy_episodes = 2
on_policy_steps = 25
[encoder_training]
latent_dim = 4
epochs = 1
[rl]
train_steps = 150
eval_episodes = 2
curve_points = 2
full_state_train_steps = 150
[metric_settings]
bootstrap = 20
[task_params."ToyReach-v0"]
horizon = 25
[agent_params.sac]
learning_starts = 50
batch_size = 32
"""


@pytest.fixture
def suite_file(tmp_path: Path) -> Path:
    p = tmp_path / "toy.toml"
    p.write_text(SUITE)
    return p


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One store for the module: later tests reuse the stages the first one computed."""
    return tmp_path_factory.mktemp("toy") / "store"


def test_run_then_resume_recomputes_nothing(suite_file: Path, tmp_path: Path,
                                            store: Path) -> None:
    first = run_suite(suite_file, store=store, out=tmp_path / "lb", workers=1,
                      progress=False)
    assert not first.report.failed and not first.report.skipped
    # 1 random + 1 full-state + 1 on-policy + diagnostics + 3 × (encoder, latents, 3 metrics,
    # 2 RL seeds)
    assert len(first.report.done) == 4 + 3 * (2 + 3 + 2)
    enc = pd.read_csv(tmp_path / "lb" / "encoders.csv")
    assert sorted(enc["encoder"]) == ["oracle", "pca", "proprio_only"]
    assert (enc["sac_seeds"] == 2).all() and enc["ksg"].notna().all()
    met = pd.read_csv(tmp_path / "lb" / "metrics.csv")
    assert set(met["metric"]) == {"ksg", "regression", "coherence"}
    second = run_suite(suite_file, store=store, out=tmp_path / "lb2", workers=1,
                       progress=False)
    assert second.report.done == {} and len(second.report.cached) == len(first.report.done)
    pd.testing.assert_frame_equal(enc, pd.read_csv(tmp_path / "lb2" / "encoders.csv"))
    rebuild_leaderboards(suite_file, store=store, out=tmp_path / "lb3")
    pd.testing.assert_frame_equal(met, pd.read_csv(tmp_path / "lb3" / "metrics.csv"))


def test_run_on_one_task_reuses_the_whole_suites_stages_and_writes_beside_its_board(
        suite_file: Path, tmp_path: Path, store: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``repbench run --task``: the task's stages are the whole suite's (all reused here), and
    the default board is ``leaderboards/<suite>-<task>``, not the whole suite's folder; a task
    the suite does not have is refused before any work."""
    monkeypatch.chdir(tmp_path)
    whole = run_suite(suite_file, store=store, out=tmp_path / "whole", workers=1,
                      progress=False)
    one = run_suite(suite_file, store=store, workers=1, progress=False, tasks=["ToyReach-v0"])
    assert one.report.done == {} and sorted(one.report.cached) == sorted(
        [*whole.report.cached, *whole.report.done])
    assert one.out_dir == Path("leaderboards/toy-ToyReach-v0")
    assert (tmp_path / "leaderboards" / "toy-ToyReach-v0" / "encoders.csv").is_file()
    assert not (tmp_path / "leaderboards" / "toy").exists()
    with pytest.raises(ConfigError, match=r"^--task PegInHole-v0 is not a task of suite toy "
                       r"\(ToyReach-v0\); pass one of those$"):
        run_suite(suite_file, store=tmp_path / "empty", workers=1, progress=False,
                  tasks=["PegInHole-v0"])
    assert not (tmp_path / "empty").exists()


def test_two_tasks_get_the_across_tasks_rows_figures_and_section(store: Path,
                                                                  tmp_path: Path) -> None:
    """The toy run's records and a copy of them as a second task (returns reversed): the
    cross-task rows, the prediction scored, the three figures and the page section (the copy
    sorts after the first task: without a suite, tasks are in name order)."""
    recs = load_records(store)
    assert recs, "the module's first test fills the store"
    second = []
    for r in recs:
        c = json.loads(json.dumps(r))
        c["task"]["name"] = "ToyReach-v1"
        if c["kind"] == "rl":
            c["values"]["eval_return"] = -float(c["values"]["eval_return"])
        second.append(c)
    res = build_results(recs + second)
    pred = predict_task(res.metric_rows, res.rl_rows,
                        [m for m in res.metric_rows if m["task"] == "ToyReach-v1"],
                        source_task="ToyReach-v0", target_task="ToyReach-v1", agent="sac",
                        families=encoder_families(res), ceiling_source=1.0,
                        ceiling_target=1.0, choose=validated_method)
    out = write_leaderboards(res, tmp_path / "lb", predictions=[pred])
    checks = pd.read_csv(out / "robustness.csv").set_index("check")
    # 3 toy encoders: too few for a ranking statistic (known answers: test_robustness.py)
    assert checks.loc["SAC ranking ToyReach-v0 vs ToyReach-v1", "verdict"] == "inconclusive"
    assert "3 encoders in both" in checks.loc["SAC ranking ToyReach-v0 vs ToyReach-v1", "detail"]
    assert "ToyReach-v0's best metric on ToyReach-v1 (SAC)" in checks.index
    assert "ToyReach-v0 calibration predicts ToyReach-v1 sac" in checks.index
    for stem in ("cross_task_metrics", "task_agreement", "cross_task_predictions"):
        assert (out / "figures" / f"{stem}.png").stat().st_size > 2_000  # palette PNGs
    page = (out / "index.html").read_text()
    assert "id='across-tasks'" in page and "id='ablations'" in page


def test_no_rl_runs_everything_but_rl_then_a_full_run_adds_only_rl(tmp_path: Path) -> None:
    suite_file = tmp_path / "toy.toml"
    suite_file.write_text(SUITE.replace('"oracle", "pca", "proprio_only"', '"pca"'))
    store = tmp_path / "store"
    first = run_suite(suite_file, store=store, out=tmp_path / "lb", workers=1, progress=False,
                      no_rl=True)
    assert not first.report.failed
    # 1 random + 1 full-state + 1 on-policy + diagnostics + encoder, latents, 3 metrics
    assert len(first.report.done) == 4 + 2 + 3
    assert load_records(store, kinds=("rl",)) == []
    enc = pd.read_csv(tmp_path / "lb" / "encoders.csv")
    assert enc["ksg"].notna().all() and "sac_return" not in enc.columns
    second = run_suite(suite_file, store=store, out=tmp_path / "lb2", workers=1,
                       progress=False)
    assert len(second.report.done) == 2 and len(second.report.cached) == 4 + 2 + 3
    assert len(load_records(store, kinds=("rl",))) == 2
    assert (pd.read_csv(tmp_path / "lb2" / "encoders.csv")["sac_seeds"] == 2).all()


def test_a_failing_stage_is_isolated(suite_file: Path, tmp_path: Path, store: Path) -> None:
    @metric("always_fails_test", higher_is_better=True)
    def always_fails(z: np.ndarray, z_true: np.ndarray, episode: np.ndarray,
                     rng: np.random.Generator, n_bootstrap: int = 10) -> MetricResult:
        raise RuntimeError("this metric is broken on purpose")

    text = suite_file.read_text().replace('"coherence"]', '"coherence", "always_fails_test"]')
    suite_file.write_text(text)
    try:
        res = run_suite(suite_file, store=store, out=tmp_path / "lb", workers=1,
                        progress=False)
    finally:
        metrics.unregister("always_fails_test")
    assert len(res.report.failed) == 3  # one per encoder
    assert len(res.report.done) == 0  # everything else was already in the store
    assert all("broken on purpose" in e for e in res.report.failed.values())
    enc = pd.read_csv(tmp_path / "lb" / "encoders.csv")
    assert enc["ksg"].notna().all() and enc["sac_return"].notna().all()
    assert "always_fails_test" in (tmp_path / "lb" / "index.html").read_text()  # as missing


def test_bad_parameter_fails_before_any_work(suite_file: Path, tmp_path: Path) -> None:
    suite_file.write_text(SUITE + '\n[encoder_params.pca]\nn_componentz = 3\n')
    with pytest.raises(ConfigError, match=r"encoder_params\.pca: unknown parameter"):
        run_suite(suite_file, store=tmp_path / "s", out=tmp_path / "lb", workers=1,
                  progress=False)
    assert not (tmp_path / "s" / "dataset").exists()


def test_longer_budget_rows_join_robustness_csv(suite_file: Path, tmp_path: Path,
                                                store: Path) -> None:
    run_suite(suite_file, store=store, out=tmp_path / "lb", workers=1, progress=False)
    longer_file = tmp_path / "toy_longer.toml"
    longer_file.write_text(SUITE.replace('name = "toy"', 'name = "toy_longer"')
                           .replace("train_steps = 150\n", "train_steps = 300\n", 1))
    run_suite(longer_file, store=store, out=tmp_path / "longer", workers=1, progress=False)

    out = rebuild_leaderboards(suite_file, store=store, out=tmp_path / "joined",
                               longer=tmp_path / "longer")
    rows = pd.read_csv(out / "robustness.csv").set_index("check")
    row = rows.loc["SAC 150 vs 300 ranking ToyReach-v0"]
    assert row["statistic"] == "Kendall τ of per-encoder mean returns"
    assert row["verdict"] == "inconclusive"  # 3 encoders: at least 4 needed
    assert "10k best metric" not in " ".join(rows.index)
    assert "150 best metric at 300 ToyReach-v0 sac" in rows.index
    assert (out / "figures" / "budget_agreement.png").is_file()
    assert not (tmp_path / "lb" / "figures" / "budget_agreement.png").exists()
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["longer"]["train_steps"] == [300]
    assert prov["longer"]["suite"] == "toy_longer"

    # the same budget is not a longer one; a folder without RL records is not a run
    with pytest.raises(ConfigError, match="not longer than this suite's 150"):
        rebuild_leaderboards(suite_file, store=store, out=tmp_path / "x", longer=tmp_path / "lb")
    (tmp_path / "empty" / "records").mkdir(parents=True)
    with pytest.raises(ConfigError, match="no RL records there"):
        rebuild_leaderboards(suite_file, store=store, out=tmp_path / "x",
                             longer=tmp_path / "empty")


def test_rebuild_from_shipped_records_keeps_store_figures(tmp_path: Path) -> None:
    """A shipped leaderboard rebuilt in place from its own records/ (no store) keeps the
    training curves and reconstructions it once copied from the store: it cannot redraw them."""
    import shutil

    shipped = Path(__file__).resolve().parents[2] / "leaderboards" / "smoke"
    out = shutil.copytree(shipped, tmp_path / "smoke")
    before = {p.name: p.read_bytes() for p in (out / "figures").glob("loss_curves_*.png")}
    assert before, "the shipped smoke leaderboard has training curves"
    rebuild_leaderboards("smoke", store=tmp_path / "no-store", out=out, records=out / "records")
    after = {p.name: p.read_bytes() for p in (out / "figures").glob("loss_curves_*.png")}
    assert after == before
    assert "Training curves" in (out / "index.html").read_text(encoding="utf-8")


def test_two_task_board_keeps_each_tasks_store_figures(tmp_path: Path) -> None:
    """Records of two tasks, each from its own one-task leaderboard: every encoder figure is
    named by encoder and task and taken from its own task's leaderboard."""
    import shutil

    shipped = Path(__file__).resolve().parents[2] / "leaderboards" / "smoke"
    first = shutil.copytree(shipped, tmp_path / "first")
    other = shutil.copytree(shipped, tmp_path / "other")
    recs = load_records(first / "records")
    copies = []
    for r in load_records(other / "records"):
        r["task"]["name"] = "Zeta-v0"
        copies.append(r)
    res = build_results(recs + copies)
    named = {k: v for k, v in res.figures_from_store.items() if k.startswith("loss_curves")}
    assert named and all(k.endswith((" PegInHole-v0", " Zeta-v0")) for k in named)
    for key, path in named.items():
        assert path.is_relative_to(first if key.endswith("PegInHole-v0") else other)
    assert {k.rsplit(" ", 1)[0] for k in named if k.endswith("Zeta-v0")} == \
        {k.rsplit(" ", 1)[0] for k in named if k.endswith("PegInHole-v0")}


def test_agent_run_rows_join_robustness_csv(suite_file: Path, tmp_path: Path,
                                            store: Path) -> None:
    """``--agent-run``: DDPG trained in its own run joins SAC's board as the SAC-vs-DDPG rows."""
    run_suite(suite_file, store=store, out=tmp_path / "lb", workers=1, progress=False)
    ddpg_suite = (SUITE.replace('name = "toy"', 'name = "toy_ddpg"')
                  .replace('agents = ["sac"]', 'agents = ["ddpg"]')
                  .replace("[agent_params.sac]", "[agent_params.ddpg]")
                  .replace("full_state_train_steps = 150\n", "full_state_train_steps = 150\n"
                           "privileged_params = { learning_starts = 50, batch_size = 32 }\n"))
    ddpg_file = tmp_path / "toy_ddpg.toml"
    ddpg_file.write_text(ddpg_suite)
    run_suite(ddpg_file, store=store, out=tmp_path / "ddpg", workers=1, progress=False)

    out = rebuild_leaderboards(suite_file, store=store, out=tmp_path / "joined",
                               agent_run=tmp_path / "ddpg")
    rows = pd.read_csv(out / "robustness.csv").set_index("check")
    row = rows.loc["SAC vs DDPG ranking ToyReach-v0"]
    assert row["statistic"] == "Spearman ρ of per-encoder mean returns"
    assert row["verdict"] == "inconclusive"  # 3 encoders: at least 4 needed
    assert "SAC's best metric under DDPG ToyReach-v0" in rows.index
    assert (out / "figures" / "agent_agreement.png").is_file()
    assert not (tmp_path / "lb" / "figures" / "agent_agreement.png").exists()
    assert not any("(" in c and "ddpg" in c for c in rows.index)  # no DDPG calibration rows
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["agent_run"]["agents"] == ["ddpg"]
    assert prov["agent_run"]["suite"] == "toy_ddpg"

    assert not rows.loc["SAC vs DDPG ranking ToyReach-v0", "detail"].startswith("SAC at")

    # SAC again is not another agent
    with pytest.raises(ConfigError, match="which this suite already trains"):
        rebuild_leaderboards(suite_file, store=store, out=tmp_path / "x",
                             agent_run=tmp_path / "lb")
    # DDPG at its own budget (where it learns): the row says which budgets it compares
    ddpg_file.write_text(ddpg_suite.replace("train_steps = 150\n", "train_steps = 200\n", 1))
    run_suite(ddpg_file, store=store, out=tmp_path / "ddpg200", workers=1, progress=False)
    out = rebuild_leaderboards(suite_file, store=store, out=tmp_path / "at200",
                               agent_run=tmp_path / "ddpg200")
    detail = pd.read_csv(out / "robustness.csv").set_index("check").loc[
        "SAC vs DDPG ranking ToyReach-v0", "detail"]
    assert detail.startswith("SAC at 150 steps, DDPG at 200 steps; 3 encoders")
