"""Known answers for the noise ceiling (:mod:`repbench.analysis.noise_ceiling`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from repbench.analysis.noise_ceiling import noise_ceiling, spearman_brown


def _simulated(n_encoders: int, n_seeds: int, noise: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    quality = rng.normal(size=n_encoders)
    returns = quality[:, None] + noise * rng.normal(size=(n_encoders, n_seeds))
    per_encoder = {f"e{i}": {s: float(returns[i, s]) for s in range(n_seeds)}
                   for i in range(n_encoders)}
    return quality, returns, per_encoder


def test_spearman_brown_of_the_committed_reliability():
    # FACTS.md: r1 = 0.79 with three seeds gives reliability 0.92 and ceiling 0.96
    assert spearman_brown(0.79, 3) == pytest.approx(3 * 0.79 / (1 + 2 * 0.79))
    assert math.sqrt(spearman_brown(0.79, 3)) == pytest.approx(0.958, abs=1e-3)
    assert spearman_brown(1.0, 5) == 1.0 and spearman_brown(0.0, 5) == 0.0


def test_seed_to_seed_spearman_matches_the_bivariate_normal_value():
    # returns = quality + N(0, 0.7²): Pearson between seeds 1/(1+0.49); Spearman of a
    # bivariate normal (6/π)·asin(ρ/2)
    _, _, per_encoder = _simulated(2000, 3, 0.7)
    out = noise_ceiling(per_encoder, n_bootstrap=50)
    pearson = 1.0 / (1.0 + 0.49)
    assert out["r1"] == pytest.approx(6 / math.pi * math.asin(pearson / 2), abs=0.03)
    assert out["n_encoders"] == 2000 and out["n_seeds"] == 3
    assert out["r1_ci_low"] < out["r1"] < out["r1_ci_high"]


def test_a_perfect_metric_reaches_the_ceiling_and_no_further():
    # the true quality is the perfect metric: its correlation with the 3-seed mean is the
    # ceiling (within sampling error), whatever the noise
    for noise in (0.3, 1.0):
        quality, returns, per_encoder = _simulated(1500, 3, noise, seed=1)
        out = noise_ceiling(per_encoder, n_bootstrap=50)
        perfect = stats.spearmanr(quality, returns.mean(1)).statistic
        assert perfect == pytest.approx(out["ceiling"], abs=0.03)
        assert out["ceiling_ci_low"] <= out["ceiling"] <= out["ceiling_ci_high"]


def test_pure_seed_noise_has_no_ceiling_to_speak_of():
    rng = np.random.default_rng(2)
    per_encoder = {f"e{i}": {s: float(rng.normal()) for s in range(3)} for i in range(300)}
    out = noise_ceiling(per_encoder, n_bootstrap=100)
    assert abs(out["r1"]) < 0.1
    assert out["ceiling_ci_low"] < 0.5


def test_only_the_seeds_every_encoder_has_are_used():
    per_encoder = {"a": {0: 1.0, 1: 2.0, 2: 9.0}, "b": {0: 2.0, 1: 3.0},
                   "c": {0: 3.0, 1: 1.0}, "d": {0: 4.0, 1: 4.0}}
    out = noise_ceiling(per_encoder, n_bootstrap=20)
    assert out["n_seeds"] == 2 and out["n_encoders"] == 4
    assert out["r1"] == pytest.approx(stats.spearmanr([1, 2, 3, 4], [2, 3, 1, 4]).statistic)


def test_too_few_encoders_or_seeds_give_nan():
    assert math.isnan(noise_ceiling({"a": {0: 1.0, 1: 2.0}, "b": {0: 1.0, 1: 3.0}})["ceiling"])
    assert math.isnan(noise_ceiling({e: {0: float(i)} for i, e in enumerate("abcd")})["r1"])
    assert noise_ceiling({})["n_encoders"] == 0


def _board_results():
    from repbench.pipeline.suite import load_suite
    from repbench.report.leaderboard import Results

    res = Results(load_suite("smoke"))
    rng = np.random.default_rng(3)
    quality = rng.normal(size=12)
    for i, q in enumerate(quality):
        enc = f"vae_{i}"
        res.encoder_rows.append({"task": "T-v0", "encoder": enc, "latent_dim": 4,
                                 "fit_time_s": 1, "family": "vae"})
        res.metric_rows.append({"task": "T-v0", "encoder": enc, "metric": "ksg",
                                "value": float(q), "higher_is_better": True, "extras": {}})
        res.rl_rows += [{"task": "T-v0", "encoder": enc, "agent": "sac", "seed": s,
                         "eval_return": float(100 * q + 30 * rng.normal()),
                         "eval_success_rate": 0.0, "curve_steps": [0, 50],
                         "curve_return": [0, 1]} for s in range(3)]
    res.provenance = {"suite": "smoke", "directions": {"ksg": True}}
    return res


def test_the_board_shows_the_ceiling_beside_every_metric_and_in_the_answer():
    from repbench.report.answer import answer_section
    from repbench.report.leaderboard import (
        encoder_table,
        metric_ranking,
        paper_claims,
        robustness_checks,
    )

    res = _board_results()
    metrics, _ = metric_ranking(res, n_bootstrap=200)  # the columns metrics.csv leads with
    per = {e: {r["seed"]: r["eval_return"] for r in res.rl_rows if r["encoder"] == e}
           for e in dict.fromkeys(r["encoder"] for r in res.rl_rows)}  # the board's order
    expected = noise_ceiling(per, n_bootstrap=200)
    row = metrics.iloc[0]
    assert row["noise_ceiling"] == pytest.approx(expected["ceiling"])
    assert row["seed_to_seed_r1"] == pytest.approx(expected["r1"])
    assert row["of_ceiling"] == pytest.approx(row["spearman_learned"] / expected["ceiling"])
    checks = robustness_checks(res, metrics)  # robustness.csv
    ceiling = checks[checks["check"] == "SAC returns rank the encoders reliably T-v0"]
    assert len(ceiling) == 1
    full = noise_ceiling(per)  # the check's own 1000 resamples
    assert ceiling["value"].iloc[0] == pytest.approx(full["ceiling"])
    assert ceiling["ci_low"].iloc[0] == pytest.approx(full["ceiling_ci_low"])
    answer = "".join(answer_section(paper_claims(res, metrics), checks, encoder_table(res), {}))
    assert "noise ceiling [95% CI]" in answer
    share = row["spearman_learned"] / full["ceiling"]
    assert f"best metric: {share:.0%} of it" in answer[:answer.index("</table>")]


def test_the_shipped_quick_board_carries_its_records_ceiling():
    """metrics.csv's ceiling on quick is the one its SAC records give (FACTS.md measured r1 0.79,
    ceiling 0.96 on PegInHole-v0 and Door-v0 before the rebuild), and the page shows it."""
    from pathlib import Path

    import pandas as pd

    from repbench.analysis.noise_ceiling import ceilings
    from repbench.analysis.results import build_results, load_records
    from repbench.report.families import _families

    board = Path(__file__).parents[2] / "leaderboards" / "quick"
    res = build_results(load_records(board / "records", kinds=("encoder", "rl")))
    found = ceilings(res.rl_rows, _families(res))
    metrics = pd.read_csv(board / "metrics.csv")
    sac = metrics[metrics["agent"] == "sac"].groupby("task").first()
    for task in ("PegInHole-v0", "Door-v0", "SurfacePress-v0"):
        assert sac.loc[task, "seed_to_seed_r1"] == pytest.approx(found[(task, "sac")]["r1"],
                                                                  abs=1e-5)
        assert sac.loc[task, "noise_ceiling"] == pytest.approx(
            found[(task, "sac")]["ceiling"], abs=1e-5)
    assert 0.9 < sac.loc["Door-v0", "noise_ceiling"] < 1  # r1 0.79: the seeds rank reliably
    page = (board / "index.html").read_text(encoding="utf-8")
    assert "noise ceiling [95% CI]" in page[:page.index("</section>")]


def test_seeds_in_perfect_disagreement_have_a_zero_ceiling():
    assert math.isnan(spearman_brown(-1.0, 2))
    per_encoder = {f"e{i}": {0: float(i), 1: float(-i)} for i in range(5)}
    out = noise_ceiling(per_encoder, n_bootstrap=20)
    assert out["r1"] == pytest.approx(-1.0) and out["ceiling"] == 0.0
