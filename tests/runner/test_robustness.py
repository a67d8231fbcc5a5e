"""Known answers for the out-of-sample calibration and the agreement checks (issue 23)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from repbench.analysis.calibration import CANDIDATES, LEGACY, Method, half_width, predict_return
from repbench.analysis.robustness import (
    AGENT_THRESHOLD,
    best_metric_agreement,
    calibration_checks,
    check_results,
    choose_method,
    coverage_verdict,
    heldout_predictions,
    ranking_agreement,
    same_trainings,
    task_checks,
    trainings_of_detail,
)


def test_half_width_is_the_conformal_order_statistic() -> None:
    errors = np.arange(1.0, 10.0)  # n = 9
    assert half_width(errors, Method("a", 1, 0.8, "family")) == 8.0  # ceil(0.8 * 10) = 8th
    assert half_width(errors, Method("b", 1, 0.9, "family")) == 9.0
    assert half_width(errors, Method("c", 1, 0.95, "family")) == float("inf")  # 10th of 9
    assert half_width(np.array([3.0, np.nan, 1.0]), LEGACY) == 3.0


def test_coverage_verdict_rule() -> None:
    assert coverage_verdict(8, 10, 0.8, 100.0) == "holds"
    assert coverage_verdict(8, 10, 0.8, 151.0) == "holds, too wide"
    # P(X <= 3 | n=10, p=0.8) = 0.00086 < 0.05
    assert coverage_verdict(3, 10, 0.8, 10.0) == "does not hold"
    # P(X <= 6 | 10, 0.8) = 0.121: not enough evidence against 80 %
    assert coverage_verdict(6, 10, 0.8, 10.0) == "holds"
    assert coverage_verdict(0, 0, 0.8, 10.0) == "inconclusive"


def _line_data(n_fam: int = 5, per: int = 3, seed: int = 0) -> tuple[dict, np.ndarray, list]:
    rng = np.random.default_rng(seed)
    m = np.linspace(0, 10, n_fam * per)
    y = 50.0 * m + 100.0
    x = {"m": m, "noise": rng.normal(size=m.size)}
    fam = [f"f{i // per}" for i in range(m.size)]
    return x, y, fam


def test_heldout_predictions_exact_on_a_line() -> None:
    x, y, fam = _line_data()
    pred = heldout_predictions(x, y, fam, CANDIDATES[0])
    inside = pred["predicted"].notna()
    assert inside.sum() == len(y) - 0  # every family can be predicted from the others
    # the line is exact, but the clip to the *other* families' range bites at the ends
    interior = [f not in ("f0", "f4") for f in fam]
    assert np.allclose(pred.loc[interior, "predicted"], y[interior])
    assert (pred["predictor"] == "m").all()


def test_held_out_family_never_sets_its_own_width() -> None:
    x, y, fam = _line_data()
    y = y.copy()
    off = np.array([f == "f2" for f in fam])
    y[off] += 120.0  # f2 lies off the line the others share
    pred = heldout_predictions(x, y, fam, CANDIDATES[0])
    f2 = pred[off]
    assert (np.abs(f2["predicted"] - y[off]) > f2["half_width"]).all()  # not covered
    others = pred[~off]
    assert (others["half_width"] > 0).all()  # their folds include f2's miss


def test_calibration_checks_coverage_and_choice() -> None:
    rng = np.random.default_rng(1)
    n = 24
    m = rng.uniform(0, 10, n)
    values = {f"e{i}": {"m": float(m[i]), "noise": float(rng.normal())} for i in range(n)}
    returns = {f"e{i}": list(60.0 * m[i] + rng.normal(0, 20, 3)) for i in range(n)}
    families = {f"e{i}": f"f{i % 6}" for i in range(n)}
    checks, pred = calibration_checks(values, returns, families, list(values))
    names = [c.check for c in checks]
    assert names == [f"out-of-sample coverage ({m.name})" for m in (*CANDIDATES, LEGACY)]
    primary = checks[0]
    assert primary.ci_low <= primary.value <= primary.ci_high
    assert primary.value >= 0.6 and primary.verdict == "holds"  # noise σ/√3 ≈ 12 ≪ 150
    assert set(pred["method"]) == {c.name for c in (*CANDIDATES, LEGACY)}
    assert choose_method(checks)[0] == CANDIDATES[0] and choose_method(checks)[1] is None


def test_choose_method_falls_back_in_the_fixed_order() -> None:
    from repbench.analysis.robustness import Check

    def row(name: str, verdict: str) -> Check:
        return Check(f"out-of-sample coverage ({name}) T sac", "", 0.5, 0, 1, verdict)

    checks = [row(CANDIDATES[0].name, "does not hold"), row(CANDIDATES[1].name, "holds, too wide"),
              row(CANDIDATES[2].name, "holds")]
    assert choose_method(checks)[0] == CANDIDATES[2]
    checks[2] = row(CANDIDATES[2].name, "does not hold")
    method, warning = choose_method(checks)
    assert method == CANDIDATES[1] and "wider" in warning
    method, warning = choose_method(checks[:1])
    assert method == CANDIDATES[0] and "optimistic" in warning


def _runs(means: list[float], noise: float = 5.0, seed: int = 0) -> dict[str, list[float]]:
    rng = np.random.default_rng(seed)
    return {f"e{i}": list(mu + rng.normal(0, noise, 3)) for i, mu in enumerate(means)}


def test_ranking_agreement_known_answers() -> None:
    means = [100.0 * i for i in range(10)]
    same = ranking_agreement(_runs(means), _runs(means, seed=1), check="c", kind="kendall",
                             threshold=0.4)
    assert same.value == pytest.approx(1.0) and same.verdict == "holds"
    rev = ranking_agreement(_runs(means), _runs(means[::-1], seed=1), check="c",
                            kind="spearman", threshold=AGENT_THRESHOLD)
    assert rev.value == pytest.approx(-1.0) and rev.verdict == "does not hold"
    few = ranking_agreement(_runs(means[:3]), _runs(means[:3]), check="c", kind="spearman",
                            threshold=0.5)
    assert few.verdict == "inconclusive" and np.isnan(few.value)
    with pytest.raises(ValueError, match="kind must be"):
        ranking_agreement({}, {}, check="c", kind="pearson", threshold=0.5)


def _board(rows: list[tuple[str, float, float, float]]) -> pd.DataFrame:
    return pd.DataFrame(rows, columns=["metric", "spearman_learned", "spearman_learned_ci_low",
                                       "spearman_learned_ci_high"])


def test_best_metric_agreement_rule() -> None:
    a = _board([("x", 0.9, 0.7, 0.97), ("y", 0.3, -0.2, 0.6)])
    same = best_metric_agreement(a, a, check="c", first_label="A", second_label="B")
    assert same.verdict == "holds" and same.value == pytest.approx(0.9)
    b_close = _board([("x", 0.7, 0.4, 0.85), ("y", 0.8, 0.6, 0.9)])
    assert best_metric_agreement(a, b_close, check="c", first_label="A",
                                 second_label="B").verdict == "holds"  # 0.85 >= 0.8
    b_far = _board([("x", 0.1, -0.3, 0.5), ("y", 0.8, 0.6, 0.9)])
    far = best_metric_agreement(a, b_far, check="c", first_label="A", second_label="B")
    assert far.verdict == "does not hold" and "best under B: y" in far.detail
    assert "not shown to predict" not in same.detail  # its interval is above 0
    # nothing predicts under B: x is not told apart from y, yet its interval includes 0: the
    # verdict says "inconclusive", not "holds" beside a caveat that contradicts it
    b_none = _board([("x", 0.14, -0.35, 0.68), ("y", 0.29, -0.38, 0.70)])
    none = best_metric_agreement(a, b_none, check="c", first_label="A", second_label="B")
    assert none.verdict == "inconclusive" and none.detail.endswith(
        "; not told apart from the best there, but not shown to predict return under B: its "
        "interval [-0.35, 0.68] includes 0")
    weak = _board([("x", 0.37, -0.71, 0.97), ("y", 0.1, -0.5, 0.6)])  # x is still the best
    weak_check = best_metric_agreement(a, weak, check="c", first_label="A", second_label="B")
    assert weak_check.verdict == "inconclusive" and weak_check.detail.endswith(
        "; the best there too, but not shown to predict return under B: its "
        "interval [-0.71, 0.97] includes 0")


def _linear_board(seed: int, agents: tuple[str, ...], n: int = 12
                  ) -> tuple[list[dict], list[dict]]:
    """One metric m rising from 0 to 1 over n encoders, and 3 seeds of each agent's return
    500 m + noise: (metric rows, RL rows; each RL row names its encoder's weights)."""
    rng = np.random.default_rng(seed)
    m = np.linspace(0, 1, n)
    metric_rows = [{"task": "T", "encoder": f"e{i}", "metric": "m", "value": float(m[i])}
                   for i in range(n)]
    rl = [{"task": "T", "encoder": f"e{i}", "agent": a, "seed": s, "train_steps": 10_000,
           "encoder_weights": f"w{i}", "eval_return": float(500 * m[i] + rng.normal(0, 10))}
          for i in range(n) for a in agents for s in range(3)]
    return metric_rows, rl


def test_check_results_adds_agent_and_budget_rows() -> None:
    n = 12
    metric_rows, rl = _linear_board(2, ("sac", "ddpg"), n)
    longer = [dict(r, train_steps=30_000, eval_return=r["eval_return"] + 50)
              for r in rl if r["agent"] == "sac"]
    families = {f"e{i}": f"f{i % 4}" for i in range(n)}
    checks, pred = check_results(metric_rows, rl, families, longer=longer)
    by = {c.check: c for c in checks}
    assert by["SAC vs DDPG ranking T"].verdict == "holds"
    assert by["SAC 10k vs 30k ranking T"].verdict == "holds"
    assert by["out-of-sample coverage (family_cv_1metric_80) T sac"].verdict == "holds"
    assert {"task", "agent", "predicted", "half_width", "covered"} <= set(pred.columns)


def test_agreement_rows_say_when_the_other_runs_are_of_other_trainings() -> None:
    n = 12
    metric_rows, sac = _linear_board(3, ("sac",), n)
    # DDPG ran the same trainings of e0..e7, another training of e8..e9; e10, e11 predate the
    # field. The 30k runs all name the board's weights.
    ddpg = [dict(r, agent="ddpg", encoder_weights=(
        r["encoder_weights"] if int(r["encoder"][1:]) < 8 else
        "other" if int(r["encoder"][1:]) < 10 else None)) for r in sac]
    longer = [dict(r, train_steps=30_000) for r in sac]
    checks, _ = check_results(metric_rows, sac + ddpg, {f"e{i}": f"f{i % 4}" for i in range(n)},
                              longer=longer)
    by = {c.check: c for c in checks}
    clause = ("its runs are of the board's trained encoders for 8 of 12 encoders (2 of another "
              "training, 2 of a training not recorded")
    assert clause in by["SAC vs DDPG ranking T"].detail
    assert trainings_of_detail(by["SAC vs DDPG ranking T"].detail) == "8 of 12 encoders"
    assert trainings_of_detail(by["SAC 10k vs 30k ranking T"].detail) == ""
    assert "trained encoders" not in by["SAC 10k vs 30k ranking T"].detail
    assert same_trainings(sac, longer, "T") is None
    assert same_trainings([dict(r, encoder_weights=None) for r in sac],
                          [dict(r, encoder_weights=None) for r in ddpg], "T") is None


def test_task_checks_rank_every_pair_and_carry_the_first_tasks_best_metric() -> None:
    rng = np.random.default_rng(3)
    n = 10
    m = np.linspace(0, 1, n)
    sign = {"A": 1.0, "B": 1.0, "C": -1.0}  # B ranks the encoders as A does, C reverses them
    rl = [{"task": t, "encoder": f"e{i}", "agent": "sac", "seed": s, "train_steps": 10_000,
           "eval_return": float(100 + 400 * sign[t] * m[i] + rng.normal(0, 5))}
          for t in ("A", "B", "C") for i in range(n) for s in range(3)]
    ranking = pd.concat([_board([("x", 0.9, 0.7, 0.97), ("y", 0.3, -0.2, 0.6)]).assign(task=t,
                                                                                       agent="sac")
                         for t in ("A", "B")]
                        + [_board([("x", 0.1, -0.3, 0.5), ("y", 0.8, 0.6, 0.9)]).assign(
                            task="C", agent="sac")], ignore_index=True)
    by = {c.check: c for c in task_checks(rl, ranking)}
    assert set(by) == {"SAC ranking A vs B", "SAC ranking A vs C", "SAC ranking B vs C",
                       "A's best metric on B (SAC)", "A's best metric on C (SAC)"}
    assert by["SAC ranking A vs B"].verdict == "holds" and by["SAC ranking A vs B"].value > 0.9
    assert by["SAC ranking A vs C"].verdict == "does not hold"
    assert by["SAC ranking B vs C"].verdict == "does not hold"
    assert by["SAC ranking B vs C"].value < 0
    assert by["A's best metric on B (SAC)"].verdict == "holds"
    assert by["A's best metric on C (SAC)"].verdict == "does not hold"
    assert task_checks([r for r in rl if r["task"] == "A"], ranking) == []  # one task: none


def test_predict_return_states_its_method() -> None:
    metrics = {f"e{i}": {"m": float(i)} for i in range(8)}
    returns = {f"e{i}": 10.0 * i for i in range(8)}
    fam = {f"e{i}": f"f{i // 2}" for i in range(8)}
    pred = predict_return(metrics, returns, {"m": 20.0}, fam)
    assert pred["method_name"] == CANDIDATES[0].name and pred["coverage"] == 0.8
    assert pred["predicted_return"] == pytest.approx(70.0)  # clipped to the reference range


def test_the_answer_shows_why_a_same_best_metric_check_is_inconclusive() -> None:
    from repbench.report.answer import _caveat

    a = _board([("x", 0.9, 0.7, 0.97), ("y", 0.3, -0.2, 0.6)])
    b_none = _board([("x", 0.14, -0.35, 0.68), ("y", 0.29, -0.38, 0.70)])
    none = best_metric_agreement(a, b_none, check="c", first_label="A", second_label="B")
    assert _caveat(none.detail) == ("<br><span class='ci'>not told apart from the best there, "
                                    "but not shown to predict</span>")
    same = best_metric_agreement(a, a, check="c", first_label="A", second_label="B")
    assert _caveat(same.detail) == ""
