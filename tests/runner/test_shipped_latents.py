"""The latents quick ships (leaderboards/quick/latents): checksummed, named by their records, and
the built-in metrics computed from them reproduce the committed metric records exactly (issue 54)
— to the last bit, or one bit off: a value can move by one unit in the last place from one
process to the next on the same machine and the same files (measured: `smoothness_objective` on
barlow_twins, −80.21817114422299 vs −80.218171144223 in its entropy term, in 1 of 12
processes; not the hash seed, not the input's memory alignment), so the check allows
:data:`ULPS` units in the last place and nothing more.

The default run checks every shipped set's files and recomputes the cheap metrics (under 0.2 s a
set); ``-m slow`` recomputes every metric of every set."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from repbench.analysis.latent_sets import read_latent_sets, read_manifest
from repbench.analysis.results import load_records
from repbench.latent_metrics import compute_on_latents
from repbench.pipeline.suite import load_suite
from repbench.registry import metrics

BOARD = Path(__file__).parents[2] / "leaderboards" / "quick"
#: Units in the last place a recomputed value may differ from its record (the docstring says why).
ULPS = 2
CHEAP = ("task_probe", "action_probe", "coherence", "smoothness", "smoothness_objective")
ALL = tuple(load_suite("quick").metrics)

pytestmark = pytest.mark.skipif(not (BOARD / "latents" / "manifest.json").is_file(),
                                reason="quick ships no latents yet")


def _records() -> dict[tuple[str, str, str], dict]:
    return {(r["task"]["name"], r["encoder"]["name"], r["metric"]["name"]): r
            for r in load_records(BOARD / "records", kinds=("metric",))}


def _reproduce(names: tuple[str, ...]) -> None:
    suite = load_suite("quick")
    records = _records()
    checked = 0
    for latent_set in read_latent_sets(BOARD / "latents"):
        arrays = latent_set.arrays()
        for name in names:
            record = records[(latent_set.task, latent_set.encoder, name)]
            assert record["encoder_weights"] == latent_set.entry["encoder_weights"], (
                f"{latent_set.task} {latent_set.encoder} {name}: the committed record is of "
                "other encoder weights than the shipped latents")
            params = record["metric"]["params"]
            assert params == {"n_bootstrap": suite.metric_settings.bootstrap,
                              **suite.metric_params.get(name, {})}
            from repbench.devices import torch_threads

            with torch_threads(1, blas=True):  # as the metric stage ran it
                values = compute_on_latents(metrics.get(name), arrays, seed=record["seed"],
                                            params=params, who=name)
            for key in ("value", "ci_low", "ci_high"):
                got, want = values[key], record["values"][key]
                assert (got is want is None) or abs(got - want) <= ULPS * math.ulp(want), (
                    latent_set.task, latent_set.encoder, name, key, got, want)
            checked += 1
    assert checked >= len(names)


def test_every_shipped_set_is_named_by_its_latents_record_and_its_files_check():
    manifest = read_manifest(BOARD / "latents")
    latents = {(r["task"]["name"], r["encoder"]["name"]): r
               for r in load_records(BOARD / "records", kinds=("latents",))}
    assert manifest["sets"]
    for latent_set in read_latent_sets(BOARD / "latents"):
        record = latents[(latent_set.task, latent_set.encoder)]
        assert latent_set.entry["latents_identity"] == record["identity"]
        assert latent_set.entry["encoder_weights"] == record["encoder_weights"]
        arrays = latent_set.arrays()  # every checksum verified
        assert arrays["z"].shape == (record["values"]["n"], record["values"]["latent_dim"])
        assert arrays["z"].dtype.name == "float32"


def test_every_shipped_encoders_sac_records_are_of_the_shipped_weights():
    rl = load_records(BOARD / "records", kinds=("rl",))
    for latent_set in read_latent_sets(BOARD / "latents"):
        runs = [r for r in rl if r["task"]["name"] == latent_set.task
                and r["encoder"]["name"] == latent_set.encoder and r["agent"]["name"] == "sac"]
        assert len(runs) == 3, (latent_set.task, latent_set.encoder)
        assert {r["encoder_weights"] for r in runs} == {latent_set.entry["encoder_weights"]}


def test_cheap_builtin_metrics_from_the_shipped_latents_reproduce_the_records():
    _reproduce(CHEAP)


@pytest.mark.slow
def test_every_builtin_metric_from_the_shipped_latents_reproduces_the_records():
    _reproduce(ALL)


def test_a_plain_file_metric_is_scored_against_the_shipped_reference(tmp_path: Path):
    from repbench.pipeline.score_metric import score_metric

    (tmp_path / "spread.py").write_text(
        "import numpy as np\n\n\ndef spread(z, z_true, episode, rng):\n"
        "    return float(np.var(z, axis=0).sum())\n")
    result = score_metric(f"{tmp_path / 'spread.py'}:spread", "quick", workers=1,
                          progress=False, n_bootstrap=100, observable=True)
    shipped = read_latent_sets(BOARD / "latents")
    assert set(result.row["task"]) == {s.task for s in shipped}
    assert len(result.values) == len(shipped)
    for row in result.row.to_dict("records"):
        assert row["group"] == "observable" and 1 <= row["rank"] <= row["n_metrics"]
        assert row["n_learned"] == sum(s.task == row["task"] for s in shipped
                                       if s.encoder not in ("oracle", "oracle_task", "random",
                                                            "pca", "proprio_only"))
        assert 0 < row["noise_ceiling"] <= 1
