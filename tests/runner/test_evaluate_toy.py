"""`repbench evaluate` on the toy task: only the new encoder's stages run; the leaderboard merges
them with reference records and predicts the return from the metrics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import repbench
from repbench.analysis.calibration import MIN_REFERENCE, predict_return
from repbench.errors import ConfigError
from repbench.pipeline.evaluate import evaluate_encoder
from repbench.pipeline.runner import run_suite
from repbench.registry import encoders

from .tiny_toy_suite import tiny_toy_suite

SUITE = tiny_toy_suite("toyeval", ["oracle", "pca", "proprio_only", "random"])


class HalfState(repbench.Encoder):
    """Half of the proprioception (a deliberately partial encoder)."""

    required_modalities = ("proprio",)

    def __init__(self) -> None:
        pass

    def fit(self, dataset: repbench.Dataset) -> HalfState:
        self.width_ = dataset.observations["proprio"].shape[1] // 2
        return self

    def encode(self, observations):  # type: ignore[no-untyped-def]
        self.check_is_fitted()
        p = self.check_observations(observations)["proprio"]
        return p[:, : self.width_].astype(np.float32)

    @property
    def latent_dim(self) -> int:
        return self.width_


@pytest.fixture
def half_state():
    encoders.register("half_state", HalfState, replace=True)
    yield "half_state"
    encoders.unregister("half_state")


def test_evaluate_metrics_only_against_reference_records(tmp_path: Path, half_state: str
                                                         ) -> None:
    suite = tmp_path / "toyeval.toml"
    suite.write_text(SUITE)
    store = tmp_path / "store"
    run_suite(suite, store=store, out=tmp_path / "ref", workers=1, progress=False)
    ref = tmp_path / "ref" / "records"
    assert len(list(ref.rglob("*.json"))) > 10

    # a fresh store: datasets are regenerated from their seeds; only half_state's stages run
    res = evaluate_encoder(half_state, suite, metrics_only=True, store=tmp_path / "fresh",
                           out=tmp_path / "eval", reference=ref, workers=1, progress=False)
    kinds = sorted(label.split()[1] for label in res.report.labels.values())
    assert not res.report.failed and "sac" not in " ".join(res.report.labels.values())
    assert kinds.count("encoder") == 1 and res.warnings == []  # same data as the reference
    enc = pd.read_csv(tmp_path / "eval" / "encoders.csv").set_index("encoder")
    assert set(enc.index) == {"oracle", "pca", "proprio_only", "random", "half_state"}
    assert enc["ksg"].notna().all() and pd.isna(enc.loc["half_state", "sac_return"])
    pred = res.predictions[0]
    assert pred["agent"] == "sac" and pred["n_reference"] == 4
    # 4 reference encoders are too few for a nested held-out interval: said, not hidden
    assert "coverage was not measured out of sample" in pred["method_warning"]
    assert pred["ci_low"] <= pred["predicted_return"] <= pred["ci_high"]
    assert enc.loc["half_state", "sac_predicted_return"] == pytest.approx(
        pred["predicted_return"], rel=1e-5)
    html = (tmp_path / "eval" / "index.html").read_text()
    assert '<tr class="highlight"' in html and "Predicted sac return of half_state" in html
    # the reference encoders' values are the shipped ones, unchanged
    ref_enc = pd.read_csv(tmp_path / "ref" / "encoders.csv").set_index("encoder")
    for e in ref_enc.index:
        assert enc.loc[e, "ksg"] == pytest.approx(ref_enc.loc[e, "ksg"], rel=1e-5)
    # --task: the suite's own task gives the same stages (all reused); another is refused
    again = evaluate_encoder(half_state, suite, metrics_only=True, store=tmp_path / "fresh",
                             out=tmp_path / "eval2", reference=ref, workers=1, progress=False,
                             tasks=["ToyReach-v0"])
    assert again.report.done == {} and len(again.report.cached) == len(res.report.done)
    # --predictor: the return predicted from that metric only (the stages are all reused)
    only = evaluate_encoder(half_state, suite, metrics_only=True, store=tmp_path / "fresh",
                            out=tmp_path / "eval4", reference=ref, workers=1, progress=False,
                            predictors=["regression"])
    assert [p["predictor"] for p in only.predictions] == ["regression"]
    with pytest.raises(ConfigError, match=r"--predictor task_cmi is not a metric of suite"):
        evaluate_encoder(half_state, suite, metrics_only=True, store=tmp_path / "fresh",
                         out=tmp_path / "eval5", reference=ref, predictors=["task_cmi"])
    with pytest.raises(ConfigError, match=r"--predictor applies to --metrics-only"):
        evaluate_encoder(half_state, suite, store=tmp_path / "fresh", out=tmp_path / "eval6",
                         reference=ref, predictors=["ksg"])
    with pytest.raises(ConfigError, match=r"--task PegInHole-v0 is not a task of suite"):
        evaluate_encoder(half_state, suite, metrics_only=True, store=tmp_path / "fresh",
                         out=tmp_path / "eval3", reference=ref, tasks=["PegInHole-v0"])


def test_prediction_interval_is_held_out() -> None:
    metrics = {f"e{i}": {"m": float(i), "noise": float((i * 7) % 5)} for i in range(6)}
    returns = {f"e{i}": 10.0 + 2.0 * i + (0.5 if i == 3 else 0.0) for i in range(6)}
    pred = predict_return(metrics, returns, {"m": 2.5, "noise": 1.0})
    assert pred is not None and pred["predictor"] == "m"
    assert pred["predicted_return"] == pytest.approx(15.0, abs=0.3)
    assert pred["ci_high"] - pred["predicted_return"] == pytest.approx(max(pred["heldout_errors"]))
    errors = pred["heldout_errors"]  # in encoder order e0..e5, each its own family here
    # the ends are clipped to the others' range: 2.0 from the neighbour's return
    assert errors[0] == pytest.approx(2.0) and errors[5] == pytest.approx(2.0)
    assert errors[3] == pytest.approx(0.5)  # the bump at e3, seen out of sample
    few = dict(list(metrics.items())[: MIN_REFERENCE - 1])
    assert predict_return(few, returns, {"m": 1.0}) is None


class NoisyHalfState(HalfState):
    """HalfState plus fresh noise on every call, and it scales its input in place."""

    def encode(self, observations):  # type: ignore[no-untyped-def]
        self.check_is_fitted()
        p = self.check_observations(observations)["proprio"]
        z = p[:, : self.width_] + np.random.default_rng().normal(size=(len(p), self.width_))
        observations["proprio"] *= 1.0  # harmless
        if len(p):
            observations["proprio"][0, 0] += 1.0  # modifies its input
        return z.astype(np.float32)


def test_evaluate_says_when_the_encoder_is_not_deterministic_or_modifies_its_input(
        tmp_path: Path) -> None:
    """Issue 56: evaluate published an encoder check_encoder would flag without a word."""
    from repbench.pipeline.evaluate import conformance_warnings
    from repbench.pipeline.plan import build_plan
    from repbench.pipeline.store import Store
    from repbench.pipeline.suite import load_suite

    suite = tmp_path / "toynoisy.toml"
    suite.write_text(tiny_toy_suite("toynoisy", ["noisy_half", "half_state"]))
    store = tmp_path / "store"
    encoders.register("noisy_half", NoisyHalfState, replace=True)
    encoders.register("half_state", HalfState, replace=True)
    try:
        run_suite(suite, store=store, out=tmp_path / "ref", workers=1, progress=False,
                  no_rl=True)
        plan = build_plan(load_suite(suite))
        noisy = conformance_warnings(plan, Store(store), "noisy_half")
        assert len(noisy) == 2
        assert "modified its input proprio" in noisy[0]
        assert "not deterministic" in noisy[1] and "check_encoder('noisy_half')" in noisy[1]
        assert conformance_warnings(plan, Store(store), "half_state") == []
    finally:
        encoders.unregister("noisy_half")
        encoders.unregister("half_state")
