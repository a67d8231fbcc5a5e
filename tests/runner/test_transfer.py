"""Cross-task predictions (repbench.analysis.transfer): known answers on synthetic rows."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from repbench.analysis.calibration import DEFAULT_METHOD
from repbench.analysis.robustness import FAILS, HOLDS, validated_method
from repbench.analysis.transfer import (
    COLUMNS,
    predict_task,
    privileged_return,
    read_prediction,
    score_predictions,
)
from repbench.errors import ConfigError, DataError
from repbench.pipeline.runner import load_predictions

SOURCE, TARGET, AGENT = "Source-v0", "Target-v0", "sac"
# 3 families of 3 learned encoders + 2 baselines; the source return is 100 + 50 m exactly and
# the distractor metric is unrelated to it
ENCODERS = {f"{fam}{i}": fam for fam in ("a", "b", "c") for i in range(3)}
ENCODERS.update(base0="baselines", base1="baselines")


def _source(m: dict[str, float]) -> tuple[list[dict], list[dict]]:
    rng = np.random.default_rng(0)
    metric_rows, rl_rows = [], []
    for e, v in m.items():
        metric_rows.append({"task": SOURCE, "encoder": e, "metric": "good", "value": v})
        metric_rows.append({"task": SOURCE, "encoder": e, "metric": "noise",
                            "value": float(rng.normal())})
        rl_rows += [{"task": SOURCE, "agent": AGENT, "encoder": e, "eval_return": 100 + 50 * v}
                    for _ in range(3)]
    return metric_rows, rl_rows


def _target(m: dict[str, float]) -> list[dict]:
    return [{"task": TARGET, "encoder": e, "metric": k, "value": v}
            for e, val in m.items() for k, v in (("good", val), ("noise", 0.0))]


def _default(*_):
    return DEFAULT_METHOD, None, None, float("nan")


# the smallest and largest values in two families each, so that no held-out family's
# prediction is clipped to the rest's return range
SOURCE_M = dict(zip(ENCODERS, [0.0, 5, 10, 0, 6, 10, 2, 7, 8, 3, 4], strict=True))


def _predict(target_m: dict[str, float], ceiling_target: float = 1.0, choose=None,
             task: str = TARGET):
    """The source's calibration (SOURCE_M, privileged return 1) applied to ``target_m`` on
    ``task`` (privileged return ``ceiling_target``)."""
    m_rows, rl_rows = _source(SOURCE_M)
    return predict_task(m_rows, rl_rows, [dict(r, task=task) for r in _target(target_m)],
                        source_task=SOURCE, target_task=task, agent=AGENT, families=ENCODERS,
                        ceiling_source=1.0, ceiling_target=ceiling_target,
                        choose=choose or _default)


def test_predictions_use_the_source_line_in_ceiling_units():
    target_m = {e: 0.5 * i for i, e in enumerate(ENCODERS)}
    pred = _predict(target_m, ceiling_target=0.5)
    assert tuple(pred.columns) == COLUMNS
    assert set(pred["metric"]) == {"good"}  # chosen on the source, not refitted
    p = pred.set_index("encoder")
    for e, v in target_m.items():
        # the source line is exact, so its leave-one-family-out errors are 0 and the interval
        # has no width; predictions are in half the source's units (ceilings 0.5 / 1)
        assert p.loc[e, "predicted_return"] == pytest.approx((100 + 50 * v) * 0.5)
        assert p.loc[e, "ci_high"] - p.loc[e, "ci_low"] == pytest.approx(0.0, abs=1e-6)
    assert p.loc["base0", "family"] == "baselines"


def test_clipped_predictions_rank_by_the_unclipped_line():
    target_m = {e: 20.0 + i for i, e in enumerate(ENCODERS)}  # all beyond the source's range
    pred = _predict(target_m)
    top = 100 + 50 * max(SOURCE_M.values())
    assert np.allclose(pred["predicted_return"], top)  # clipped to the source's range
    assert np.all(np.diff(pred.set_index("encoder").loc[list(ENCODERS),
                                                         "predicted_unclipped"]) > 0)


def _actual(order: dict[str, float]) -> list[dict]:
    rng = np.random.default_rng(1)
    return [{"task": TARGET, "agent": AGENT, "encoder": e, "eval_return": r + rng.normal(0, 1)}
            for e, r in order.items() for _ in range(3)]


def test_score_holds_when_actual_follows_the_prediction_and_fails_when_reversed():
    target_m = {e: 0.5 * i for i, e in enumerate(ENCODERS)}
    pred = _predict(target_m, choose=validated_method)
    same = {e: 10.0 * v for e, v in target_m.items()}
    check, table = score_predictions(pred, _actual(same), n_bootstrap=300)
    assert check.verdict == HOLDS and check.value == pytest.approx(1.0)
    assert "9 encoders" in check.detail  # learned only: the 2 baselines are out
    reverse = {e: -10.0 * v for e, v in target_m.items()}
    check, table = score_predictions(pred, _actual(reverse), n_bootstrap=300)
    assert check.verdict == FAILS and check.value == pytest.approx(-1.0)
    assert table["n_seeds"].eq(3).all()
    assert f"{int(table['inside'].sum())}/11 actual returns inside" in check.detail


def test_no_privileged_record_is_a_one_line_error():
    with pytest.raises(DataError, match="no privileged-agent record of Target-v0"):
        privileged_return([{"kind": "full_state_agent", "task": {"name": SOURCE},
                            "values": {"eval_return": 1.0}}], TARGET)
    assert privileged_return([{"kind": "full_state_agent", "task": {"name": TARGET},
                               "values": {"eval_return": 7.0}}], TARGET) == 7.0


def test_target_without_metrics_is_a_one_line_error():
    m_rows, rl_rows = _source(SOURCE_M)
    with pytest.raises(DataError, match="no metric values of Target-v0"):
        predict_task(m_rows, rl_rows, [], source_task=SOURCE, target_task=TARGET, agent=AGENT,
                     families=ENCODERS, ceiling_source=1.0, ceiling_target=1.0,
                     choose=_default)


def test_load_predictions_errors_and_task_filter(tmp_path: Path) -> None:
    res = SimpleNamespace(metric_rows=[{"task": TARGET}])
    with pytest.raises(ConfigError, match=r"no <task id>\.csv files"):
        load_predictions(tmp_path, res)
    (tmp_path / "bad.csv").write_text("task,encoder\nTarget-v0,a\n")
    with pytest.raises(ConfigError, match=r"bad\.csv is not a prediction table"):
        load_predictions(tmp_path, res)
    (tmp_path / "bad.csv").unlink()
    for task in (TARGET, "Other-v0"):
        pred = _predict(SOURCE_M, task=task)
        pred.to_csv(tmp_path / f"{task}.csv", index=False)
    (only,) = load_predictions(tmp_path, res)  # Other-v0 is not a task of the results
    assert set(only["task"]) == {TARGET}


def test_a_note_beside_the_prediction_reaches_the_scored_detail(tmp_path: Path) -> None:
    """``<task>.note`` qualifies the score on the page without touching the committed CSV."""
    res = SimpleNamespace(metric_rows=[{"task": TARGET}])
    target_m = {e: 0.5 * i for i, e in enumerate(ENCODERS)}
    _predict(target_m).to_csv(tmp_path / f"{TARGET}.csv", index=False)
    actual = _actual({e: 10.0 * v for e, v in target_m.items()})
    (plain,) = load_predictions(tmp_path, res)
    assert "note" not in score_predictions(plain, actual, n_bootstrap=50)[0].detail
    (tmp_path / f"{TARGET}.note").write_text("agents read\n  retrained encoders\n")
    (noted,) = load_predictions(tmp_path, res)
    check, _ = score_predictions(noted, actual, n_bootstrap=50)
    assert check.detail.endswith("; note: agents read retrained encoders")
    assert read_prediction(tmp_path / f"{TARGET}.csv").attrs["note"] == \
        "agents read retrained encoders"


def test_a_within_task_prediction_is_scored_beside_a_cross_task_one_of_the_same_task() -> None:
    """The zoo's prediction (the target task's own calibration applied to encoders added after
    it) and a cross-task prediction of the same task × agent are two checks, each with its
    scored table: neither replaces the other, and the names say which is which."""
    import pandas as pd

    from repbench.analysis.transfer import prediction_check_name
    from repbench.report.leaderboard import robustness_checks

    target_m = {e: 0.5 * i for i, e in enumerate(ENCODERS)}
    across = _predict(target_m)
    within = across.assign(source_task=TARGET)
    assert prediction_check_name(across) == f"{SOURCE} calibration predicts {TARGET} {AGENT}"
    assert prediction_check_name(within) == \
        f"{TARGET} calibration predicts new encoders on {TARGET} {AGENT}"
    rl_rows = [dict(r, train_steps=10) for r in _actual({e: 10.0 * v
                                                         for e, v in target_m.items()})]
    res = SimpleNamespace(metric_rows=[dict(r, agent=AGENT) for r in _target(target_m)],
                          rl_rows=rl_rows, encoder_rows=[], provenance={})
    # a prediction none of whose encoders has an RL row yet is not scored (no empty check)
    unrun = within.assign(encoder="new_" + within["encoder"], source_task="Third-v0")
    table = robustness_checks(res, pd.DataFrame(), predictions=[across, within, unrun])
    names = set(table["check"])
    assert {prediction_check_name(across), prediction_check_name(within)} <= names
    assert prediction_check_name(unrun) not in names
    assert set(res.robustness["predictions"]) == {prediction_check_name(across),
                                                 prediction_check_name(within)}
