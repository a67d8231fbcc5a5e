"""The paper's claims, checked on synthetic records whose answers are known by construction."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from repbench.analysis.claims import KL_PAIRS, check_claims, verdict
from repbench.analysis.correlation import metric_leaderboard


@pytest.mark.parametrize(("value", "lo", "hi", "sign", "p", "expected"), [
    (0.5, 0.2, 0.8, +1, None, "reproduced"),
    (0.5, 0.2, 0.8, +1, 0.2, "inconclusive"),      # significant interval, corrected p is not
    (0.5, -0.1, 0.8, +1, None, "inconclusive"),
    (-0.5, -0.8, -0.2, +1, None, "not reproduced"),
    (-0.5, -0.8, -0.2, -1, 0.01, "reproduced"),     # a claimed negative effect
    (0.1, -0.3, 0.4, -1, None, "not reproduced"),
    (float("nan"), 0.0, 0.0, +1, None, "inconclusive"),
])
def test_verdict_rule(value: float, lo: float, hi: float, sign: int, p: float | None,
                      expected: str) -> None:
    assert verdict(value, lo, hi, sign, p) == expected


def _records(n_seeds: int = 3) -> tuple[list[dict], list[dict], dict[str, str]]:
    """10 learned encoders (the paper's 5 KL pairs) + 2 baselines. Return rises with MINE and
    falls with regression error; smoothness_objective is unrelated noise; low KL has higher MI
    but a *lower* return than standard KL; the smoothing loss lowers the smoothness ratio."""
    rng = np.random.default_rng(0)
    metric_rows, rl_rows = [], []
    encoders = [e for pair in KL_PAIRS for e in pair] + ["oracle", "random"]
    families = {"oracle": "baseline", "random": "baseline"}
    for i, enc in enumerate(encoders):
        lowkl = enc.endswith("_lowkl")
        quality = i // 2 + (0.0 if lowkl else 0.5)  # distinct, low KL a half-step below
        ret = 100.0 * quality
        mi_pair = 1.0 + 0.1 * i + (1.0 if lowkl else 0.0)  # KSG: low KL clearly higher
        smooth = 1.0 - (0.5 if enc.startswith("smooth") else 0.0) + 0.01 * i
        values = {"mine": quality, "ksg": mi_pair, "regression": -quality,
                  "smoothness_objective": float(rng.normal()), "smoothness": smooth}
        for metric, v in values.items():
            metric_rows.append({"task": "T", "encoder": enc, "metric": metric, "value": v,
                                "time_s": 1.0,
                                "extras": {"bootstrap_replicates": list(
                                    v + 0.01 * rng.normal(size=50))}})
        for s in range(n_seeds):
            rl_rows.append({"task": "T", "encoder": enc, "agent": "sac", "seed": s,
                            "eval_return": ret + 5.0 * (s - 1)})
    return metric_rows, rl_rows, families


DIRECTIONS = {"mine": True, "ksg": True, "regression": False, "smoothness_objective": True,
              "smoothness": False}


def _claims() -> dict[str, object]:
    metric_rows, rl_rows, families = _records()
    rows, _ = metric_leaderboard(metric_rows, rl_rows, families, DIRECTIONS, n_bootstrap=300)
    claims = check_claims(metric_rows, rl_rows, pd.DataFrame(rows), families, DIRECTIONS,
                          task="T", n_bootstrap=300)
    return {c.claim: c for c in claims}


def test_claims_follow_the_constructed_answers() -> None:
    claims = _claims()
    mine = claims["MI between latent and true state (mine) correlates positively with return"]
    assert mine.value == pytest.approx(1.0) and mine.verdict == "reproduced"
    reg = claims["Regression error latent → true state correlates negatively with return"]
    assert reg.value == pytest.approx(-1.0) and reg.ci_high < 0  # the paper's sign convention
    assert reg.verdict == "reproduced"
    ksg_pairs = claims["Low-KL encoders have higher MI (ksg) than their standard-KL twins"]
    assert ksg_pairs.value == pytest.approx(1.1)  # +1 per pair plus 0.1 for the index step
    assert ksg_pairs.verdict == "reproduced" and ksg_pairs.detail.startswith("5 of 5 pairs")
    ret_pairs = claims["Low-KL encoders reach a higher RL return than their standard-KL twins"]
    # a pair shares i // 2; low KL is half a quality step (50 return) below its twin
    assert ret_pairs.value == pytest.approx(-50.0)
    assert ret_pairs.verdict == "not reproduced"
    smooth = claims["The smoothing loss lowers ‖Δz‖/‖Δz°‖"]
    assert smooth.value < -0.4 and smooth.verdict == "reproduced"
    weaker = claims["H(z) − E ln|J_g| relates to return more weakly than MI (mine)"]
    assert weaker.value > 0.3  # |ρ_MINE| = 1 vs a noise metric
    best = claims["Which metric predicts return best (learned encoders)?"]
    assert "mine" in best.statistic or "regression" in best.statistic  # both ρ = 1


def test_claims_without_their_encoders_are_left_out() -> None:
    metric_rows, rl_rows, families = _records()
    keep = {"vae", "success", "pred_z", "oracle", "random"}  # no low-KL twin, no smooth*
    metric_rows = [r for r in metric_rows if r["encoder"] in keep]
    rl_rows = [r for r in rl_rows if r["encoder"] in keep]
    rows, _ = metric_leaderboard(metric_rows, rl_rows, families, DIRECTIONS, n_bootstrap=100)
    claims = check_claims(metric_rows, rl_rows, pd.DataFrame(rows), families, DIRECTIONS,
                          task="T", n_bootstrap=100)
    assert not any("Low-KL" in c.claim for c in claims)
    assert not any("smoothing loss" in c.claim for c in claims)
    assert any("(mine) correlates" in c.claim for c in claims)


def test_claims_without_rl_correlations_still_compare_the_pairs() -> None:
    metric_rows, rl_rows, families = _records()
    claims = check_claims(metric_rows, rl_rows, pd.DataFrame(), families, DIRECTIONS, task="T",
                          n_bootstrap=100)
    assert not any("correlates" in c.claim or "Which metric" in c.claim for c in claims)
    assert any(c.claim.startswith("Low-KL encoders have higher MI (ksg)") for c in claims)


def test_pair_intervals_keep_replicates_paired_across_encoders() -> None:
    """Replicate b of every encoder comes from the same resample of held-out episodes, so a
    shift common to all encoders in replicate b cancels in a pair's difference."""
    shift = np.random.default_rng(1).normal(size=100)  # large next to the 0.2 nats difference
    metric_rows, rl_rows = [], []
    for standard, low in KL_PAIRS:
        for enc, v in ((low, 1.2), (standard, 1.0)):
            metric_rows.append({"task": "T", "encoder": enc, "metric": "ksg", "value": v,
                                "time_s": 1.0,
                                "extras": {"bootstrap_replicates": list(v + shift)}})
            rl_rows += [{"task": "T", "encoder": enc, "agent": "sac", "seed": s,
                         "eval_return": 1.0 + s} for s in range(3)]
    claims = check_claims(metric_rows, rl_rows, pd.DataFrame(), {}, {"ksg": True}, task="T",
                          n_bootstrap=200)
    ksg = next(c for c in claims if c.claim.startswith("Low-KL encoders have higher MI (ksg)"))
    assert ksg.value == pytest.approx(0.2)
    assert ksg.ci_low == pytest.approx(0.2) and ksg.ci_high == pytest.approx(0.2)
    assert ksg.verdict == "reproduced"


@pytest.mark.parametrize("stage_cpu_s", [7.0, None])
def test_best_metric_claim_quotes_cpu_seconds_where_recorded(stage_cpu_s: float | None) -> None:
    """Wall time is inflated by a paused run, so the claim quotes the stage's CPU seconds;
    records without them fall back to wall seconds, labelled as such."""
    metric_rows, rl_rows, families = _records()
    if stage_cpu_s is not None:
        metric_rows = [{**r, "stage_cpu_s": stage_cpu_s} for r in metric_rows]
    rows, _ = metric_leaderboard(metric_rows, rl_rows, families, DIRECTIONS, n_bootstrap=100)
    claims = check_claims(metric_rows, rl_rows, pd.DataFrame(rows), families, DIRECTIONS,
                          task="T", n_bootstrap=100)
    best = {c.claim: c for c in claims}["Which metric predicts return best (learned encoders)?"]
    expected = "cost 7 CPU-s per encoder" if stage_cpu_s else "cost 1 s (wall) per encoder"
    assert expected in best.detail
