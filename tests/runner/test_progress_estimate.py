"""The time-left estimate of ``run_stages``' progress line (:mod:`repbench.pipeline.executors`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from repbench.pipeline import executors
from repbench.pipeline.executors import StageTimes, _status, run_stages
from repbench.pipeline.stages import DATASET, ENCODER, METRIC, RL, StageSpec
from repbench.pipeline.store import Store


def test_stage_times_prefer_this_run_then_the_store_then_every_kind() -> None:
    times = StageTimes()
    assert times.expected(RL) == 10.0  # nothing known at all
    for s in (100.0, 500.0, 520.0):
        times.add_earlier(RL, s)
    times.add_earlier(RL, None)  # a record without a wall time is ignored
    assert times.expected(RL) == 500.0  # the store's median
    assert times.expected(DATASET) == pytest.approx((100 + 500 + 520) / 3)  # every kind's mean
    times.add(RL, 300.0)
    times.add(RL, 400.0)
    assert times.expected(RL) == 350.0  # this run's stages win over earlier runs'


def test_a_stage_is_estimated_from_its_cost_group_before_its_kind() -> None:
    """RL that renders the wrist image takes longer than RL that does not: a waiting stage is
    estimated from the finished stages of its own group, even an earlier run's, over this
    run's stages of its kind."""
    times = StageTimes()
    times.add(RL, 240.0, "T sac 20000 steps, no image")
    times.add(RL, 380.0, "T sac 20000 steps, image")
    times.add(RL, 400.0, "T sac 20000 steps, image")
    assert times.expected(RL, "T sac 20000 steps, image") == 390.0
    assert times.expected(RL, "T sac 20000 steps, no image") == 240.0
    assert times.expected(RL, "U sac 10000 steps, image") == pytest.approx(1020 / 3)  # kind
    assert times.expected(RL) == pytest.approx(1020 / 3)
    times.add_earlier(RL, 700.0, "U sac 10000 steps, image")
    assert times.expected(RL, "U sac 10000 steps, image") == 700.0
    assert times.expected(DATASET) == pytest.approx((240 + 380 + 400 + 700) / 4)  # not doubled


def test_the_plan_groups_rl_by_rendering_and_metrics_by_name() -> None:
    from repbench.pipeline.plan import build_plan
    from repbench.pipeline.suite import load_suite

    (tp,) = build_plan(load_suite("smoke")).tasks
    groups = {enc: spec.cost_group for (enc, agent, _), spec in tp.rl.items() if agent == "sac"}
    assert groups["pca"] == "PegInHole-v0 sac 300 steps, image"
    assert groups["oracle"] == "PegInHole-v0 sac 300 steps, no image"
    assert tp.metrics[("pca", "ksg")].cost_group == tp.metrics[("oracle", "ksg")].cost_group \
        != tp.metrics[("oracle", "mine")].cost_group


def test_status_counts_what_is_left_of_the_running_stages(monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    specs = {f"rl{i}": StageSpec(RL, {"i": i}, label=f"rl{i}") for i in range(4)}
    times = StageTimes()
    times.add(RL, 600.0)
    monkeypatch.setattr(executors.time, "time", lambda: 1000.0)
    running = {"h0": "rl0", "h1": "rl1"}
    started = {"rl0": 1000.0 - 200.0, "rl1": 1000.0 - 700.0}  # rl1 overran: 0 s left, not < 0
    line = _status(running, specs, ["rl2", "rl3"], times, 2, started)
    # (600 + 600 waiting + 400 + 0 left of the running) / 2 workers = 800 s
    assert line == "running: rl0, rl1 | ~13 min left"
    times.add(RL, 600.0 * 20)  # mean 6300 s: (6300 * 2 + 6100 + 5600) / 2 = 12150 s
    assert _status(running, specs, ["rl2", "rl3"], times, 2, started).endswith(
        "| ~3 h 22 min left")
    assert _status({}, specs, [], times, 2, {}) == "running: - | ~0 s left"


def test_a_resumed_run_estimates_from_the_stores_wall_times(tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    store = Store(tmp_path / "s")
    done, todo = StageSpec(RL, {"i": 0}, label="rl0"), StageSpec(RL, {"i": 1}, label="rl1")
    with store.write(RL, done.key, config=done.config) as w:
        w.write_json({"ok": True})
        w.extra_meta["wall_time_s"] = 480.0  # as a finished RL stage records it
    seen: list[float] = []

    def spy(running: object, by_id: object, waiting: object, times: StageTimes,
            *rest: object) -> str:
        seen.append(times.expected(RL))
        return ""

    monkeypatch.setattr(executors, "_status", spy)
    report = run_stages([done, todo], store, _OneAtATime(), progress=False, echo=lambda _: None)
    assert report.cached == [f"{RL}/{done.key}"]
    assert seen[0] == 480.0  # before any stage of this run ended: the store's wall time


def test_stage_times_fall_back_to_the_stores_other_stages_before_every_kind() -> None:
    """A resumed run whose finished stages are all encoders must not estimate a 2 s metric at
    an encoder's 600 s: the store's stages of other suites know the metric's time."""
    times = StageTimes()
    times.add_earlier(ENCODER, 600.0)
    assert times.expected(METRIC, "T ksg") == 600.0  # only every kind's mean to go on
    times.add_elsewhere(METRIC, 2.0, "T ksg")
    times.add_elsewhere(METRIC, 4.0, "T ksg")
    times.add_elsewhere(METRIC, 90.0, "T mine")
    times.add_elsewhere(METRIC, "?", "T mine")  # not a time: ignored
    assert times.expected(METRIC, "T ksg") == 3.0  # its group's median elsewhere
    assert times.expected(METRIC, "T mine") == 90.0
    assert times.expected(METRIC, "T regression") == 4.0  # the kind's median elsewhere
    times.add_earlier(METRIC, 10.0, "T mine")
    assert times.expected(METRIC, "T mine") == 10.0  # this plan's own stages first
    times.add(METRIC, 1.0)
    assert times.expected(METRIC, "T ksg") == 3.0  # a group known elsewhere beats the kind now
    assert times.expected(METRIC, "T regression") == 1.0


def test_a_resumed_run_estimates_a_kind_it_has_not_run_from_the_stores_other_suites(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The DDPG row's resume said ~10 h for ~3 h of work: its 110 metric stages were each
    estimated at an encoder's length. With another suite's metric stages in the store (their
    meta carries the cost group), a metric is estimated at a metric's length."""
    store = Store(tmp_path / "s")

    def stored(spec: StageSpec, wall: float) -> None:
        with store.write(spec.kind, spec.key, config=spec.config) as w:
            w.write_json({"ok": True})
            w.extra_meta["wall_time_s"] = wall
            if spec.cost_group:
                w.extra_meta["cost_group"] = spec.cost_group

    encoder = StageSpec(ENCODER, {"e": 0}, label="enc")
    stored(encoder, 600.0)
    stored(StageSpec(METRIC, {"other suite": 1}, cost_group="T ksg"), 2.0)
    (tmp_path / "s" / METRIC / "junk").mkdir()  # a folder without a meta.json: skipped
    todo = [StageSpec(METRIC, {"m": i}, label=f"m{i}", cost_group="T ksg") for i in range(3)]
    seen: list[float] = []

    def spy(running: object, by_id: object, waiting: object, times: StageTimes,
            *rest: object) -> str:
        seen.append(times.expected(METRIC, "T ksg"))
        return ""

    monkeypatch.setattr(executors, "_status", spy)
    run_stages([encoder, *todo], store, _OneAtATime(), progress=False, echo=lambda _: None)
    assert seen[0] == 2.0


def test_a_computed_stage_records_its_cost_group_for_later_estimates(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from repbench.pipeline import stages

    monkeypatch.setitem(stages._IMPLEMENTATIONS, METRIC,
                        lambda spec, store, w: w.write_json({"value": 1.0}))
    spec = StageSpec(METRIC, {"m": 0}, label="T ksg × pca", cost_group="T ksg")
    store = Store(tmp_path / "s")
    assert stages.execute(spec, str(store.root))["status"] == "done"
    (meta,) = store.metas(METRIC)
    assert meta["cost_group"] == "T ksg"
    assert meta["wall_time_s"] >= 0


class _OneAtATime:
    """An executor that runs nothing: each submitted stage is reported done at once."""

    capacity = 1

    def submit(self, spec: StageSpec) -> str:
        return spec.label

    def wait_any(self, handles: list[str]) -> list[tuple[str, dict[str, object]]]:
        return [(handles[0], {"status": "done"})]

    def shutdown(self) -> None:
        pass

    def abort(self) -> None:
        pass
