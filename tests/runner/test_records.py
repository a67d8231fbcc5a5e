"""Results as records: every final stage writes a self-describing record; the leaderboard is a
function of records; plugin identity is its declared version, not its source code."""

from __future__ import annotations

import importlib
import json
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest

from repbench.pipeline.records import SCHEMA, SCHEMA_VERSION, identity_key
from repbench.pipeline.runner import rebuild_leaderboards, run_suite
from repbench.registry import encoders

from .tiny_toy_suite import tiny_toy_suite

SUITE = tiny_toy_suite("toyrec", ["oracle", "docenc"])

MODULE = '''
"""DOCSTRING"""
import numpy as np
import repbench


class DocEncoder(repbench.Encoder):
    """DOCSTRING"""

    required_modalities = ("proprio",)
    version = VERSION

    def __init__(self, latent_dim: int = 3):
        self.latent_dim_param = latent_dim

    def get_params(self):
        return {"latent_dim": self.latent_dim_param}

    def fit(self, dataset):
        self.mean_ = dataset.observations["proprio"].mean(0)
        return self

    def encode(self, observations):
        self.check_is_fitted()
        p = self.check_observations(observations)["proprio"]
        return (p - self.mean_)[:, : self.latent_dim_param].astype(np.float32)

    @property
    def latent_dim(self):
        return self.latent_dim_param
'''


@pytest.fixture
def plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """A plugin module on sys.path, registered by reference; ``write`` rewrites its source."""
    monkeypatch.syspath_prepend(str(tmp_path))

    def write(doc: str = "A test encoder.", version: int = 0) -> None:
        text = MODULE.replace("DOCSTRING", doc).replace("VERSION", str(version))
        (tmp_path / "rec_docenc.py").write_text(textwrap.dedent(text))
        importlib.invalidate_caches()
        if "rec_docenc" in sys.modules:
            importlib.reload(sys.modules["rec_docenc"])
        encoders.register("docenc", sys.modules["rec_docenc"].DocEncoder
                          if "rec_docenc" in sys.modules else "rec_docenc:DocEncoder",
                          replace=True)

    write()
    yield write
    encoders.unregister("docenc")
    sys.modules.pop("rec_docenc", None)


@pytest.fixture
def suite_file(tmp_path: Path) -> Path:
    p = tmp_path / "toyrec.toml"
    p.write_text(SUITE)
    return p


def _records(store: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(store.glob("*/*/record.json"))]


def test_records_docstrings_and_stale_versions(plugin, suite_file: Path, tmp_path: Path) -> None:
    store = tmp_path / "store"
    first = run_suite(suite_file, store=store, out=tmp_path / "lb1", workers=1, progress=False)
    assert not first.report.failed
    records = _records(store)
    kinds = sorted(r["kind"] for r in records)
    # 1 dataset, 1 diagnostics, 2 × (encoder, latents, 2 metrics, 1 RL run)
    assert kinds.count("metric") == 4 and kinds.count("rl") == 2 and kinds.count("encoder") == 2
    metric = next(r for r in records if r["kind"] == "metric" and r["encoder"]["name"] == "docenc"
                  and r["metric"]["name"] == "ksg")
    assert metric["schema"] == SCHEMA and metric["schema_version"] == SCHEMA_VERSION
    assert metric["task"] == {"name": "ToyReach-v0", "version": 0, "params": {"horizon": 20}}
    assert metric["encoder"] == {"name": "docenc", "version": 0, "params": {"latent_dim": 3}}
    assert metric["metric"]["name"] == "ksg" and metric["metric"]["params"]["n_bootstrap"] == 20
    assert {"value", "ci_low", "ci_high", "higher_is_better"} <= set(metric["values"])
    assert metric["seed"] == 0 and metric["data_checksums"]["random"]
    assert metric["library_versions"]["numpy"] and "wall_time_s" in metric["timings"]
    assert metric["identity"] == identity_key(metric)
    rl = next(r for r in records if r["kind"] == "rl" and r["encoder"]["name"] == "docenc")
    assert rl["agent"]["name"] == "sac" and rl["budget"]["train_steps"] == 60
    assert "eval_return" in rl["values"] and len(rl["values"]["eval_episode_returns"]) == 1
    before = pd.read_csv(tmp_path / "lb1" / "encoders.csv")
    assert "stale" not in before.columns

    # editing the plugin's docstrings changes nothing: same keys, nothing recomputed
    plugin(doc="A test encoder, now documented at length.")
    again = run_suite(suite_file, store=store, out=tmp_path / "lb2", workers=1, progress=False)
    assert again.report.done == {}
    rebuild_leaderboards(suite_file, store=store, out=tmp_path / "lb3")
    for out in ("lb2", "lb3"):
        pd.testing.assert_frame_equal(before, pd.read_csv(tmp_path / out / "encoders.csv"))
        pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "lb1" / "metrics.csv"),
                                      pd.read_csv(tmp_path / out / "metrics.csv"))

    # a version bump: the leaderboard still shows the old results, marked stale
    plugin(version=1)
    rebuild_leaderboards(suite_file, store=store, out=tmp_path / "lb4")
    stale = pd.read_csv(tmp_path / "lb4" / "encoders.csv").set_index("encoder")
    assert stale.loc["docenc", "stale"] == "encoder docenc v0, installed v1"
    assert pd.isna(stale.loc["oracle", "stale"])
    assert stale.loc["docenc", "ksg"] == before.set_index("encoder").loc["docenc", "ksg"]
    assert '<tr class="stale"' in (tmp_path / "lb4" / "index.html").read_text()
    # ... and a run recomputes exactly the stages of that encoder, after which nothing is stale
    third = run_suite(suite_file, store=store, out=tmp_path / "lb5", workers=1, progress=False)
    assert len(third.report.done) == 1 + 1 + 2 + 1  # encoder, latents, 2 metrics, 1 RL run
    assert "stale" not in pd.read_csv(tmp_path / "lb5" / "encoders.csv").columns
