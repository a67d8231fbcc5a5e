"""A third-party encoder, pip-installed, evaluated with `repbench evaluate --metrics-only`
against the smoke records shipped in leaderboards/smoke/records/."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from tests.core.test_packaging import _PLUGIN_MODULE, _PLUGIN_PYPROJECT

from .conftest import SuiteRun

# one xdist worker runs every test of the smoke_run fixture, so the smoke suite runs once
pytestmark = pytest.mark.xdist_group("smoke_run")

ROOT = Path(__file__).resolve().parents[2]


def test_shipped_smoke_records_are_readable() -> None:
    from repbench.analysis.results import build_results, load_records

    records = load_records(ROOT / "leaderboards" / "smoke" / "records")
    kinds = {r["kind"] for r in records}
    assert {"dataset", "encoder", "metric", "rl"} <= kinds
    res = build_results(records)
    shipped = pd.read_csv(ROOT / "leaderboards" / "smoke" / "encoders.csv")
    assert sorted({r["encoder"] for r in res.encoder_rows}) == sorted(shipped["encoder"])


def test_leaderboard_is_a_function_of_the_shipped_records(tmp_path: Path) -> None:
    """`repbench leaderboard --records` rebuilds the shipped tables from the records alone."""
    shipped = ROOT / "leaderboards" / "smoke"
    proc = subprocess.run([sys.executable, "-m", "repbench.cli", "leaderboard", "--suite",
                           "smoke", "--records", str(shipped / "records"), "--out",
                           str(tmp_path / "lb")], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    for table in ("encoders.csv", "metrics.csv"):
        pd.testing.assert_frame_equal(pd.read_csv(shipped / table),
                                      pd.read_csv(tmp_path / "lb" / table))


def test_third_party_encoder_evaluated_metrics_only(smoke_run: SuiteRun, tmp_path: Path) -> None:
    pkg = tmp_path / "plugin"
    pkg.mkdir()
    (pkg / "pyproject.toml").write_text(_PLUGIN_PYPROJECT)
    (pkg / "rb_ext_plugin.py").write_text(_PLUGIN_MODULE)
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps",
                    "--no-build-isolation", "--target", str(site), str(pkg)], check=True,
                   capture_output=True, timeout=600)
    env = {**os.environ, "PYTHONPATH": str(site)}
    out_dir = tmp_path / "lb"
    # the smoke run's store holds the suite's datasets: only mean_pixel's stages are computed
    proc = subprocess.run([sys.executable, "-m", "repbench.cli", "evaluate", "mean_pixel",
                           "--suite", "smoke", "--metrics-only", "--store", str(smoke_run.store),
                           "--out", str(out_dir), "--workers", "2"],
                          capture_output=True, text=True, cwd=tmp_path, env=env, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    print(proc.stdout[-1500:])
    assert "predicted sac return of mean_pixel" in proc.stdout
    enc = pd.read_csv(out_dir / "encoders.csv").set_index("encoder")
    shipped = pd.read_csv(ROOT / "leaderboards" / "smoke" / "encoders.csv")
    assert set(enc.index) == {*shipped["encoder"], "mean_pixel"}
    assert enc.loc["mean_pixel", ["ksg", "regression", "coherence"]].notna().all()
    assert pd.notna(enc.loc["mean_pixel", "sac_predicted_return"])
    html = (out_dir / "index.html").read_text()
    assert '<tr class="highlight"' in html and "Predicted sac return of mean_pixel" in html


def test_encoder_in_a_plain_file_evaluated_metrics_only(smoke_run: SuiteRun,
                                                        tmp_path: Path) -> None:
    """`repbench evaluate my_encoder.py:MeanPixel`: no package, no entry point; the stages run
    in 2 worker processes, which resolve the file reference themselves (issue 24, item 3)."""
    (tmp_path / "my_encoder.py").write_text(_PLUGIN_MODULE)
    out_dir = tmp_path / "lb"
    spec = "my_encoder.py:MeanPixel"
    proc = subprocess.run([sys.executable, "-m", "repbench.cli", "evaluate", spec,
                           "--suite", "smoke", "--metrics-only", "--store", str(smoke_run.store),
                           "--out", str(out_dir), "--workers", "2"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert f"predicted sac return of {spec}" in proc.stdout
    enc = pd.read_csv(out_dir / "encoders.csv").set_index("encoder")
    assert enc.loc[spec, ["ksg", "regression", "coherence"]].notna().all()
    assert pd.notna(enc.loc[spec, "sac_predicted_return"])
