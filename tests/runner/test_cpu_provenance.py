"""Records and artifacts carry the CPU model; the data-checksum warning of ``repbench
evaluate`` names what differs (versions, CPU, or neither) and never blames versions for a CPU."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from repbench.pipeline.evaluate import _compare_data
from repbench.pipeline.records import make_record
from repbench.pipeline.store import Store, cpu_model, library_versions

VERSIONS = {"python": "3.11.9", "numpy": "1.26.4", "mujoco": "3.1.6"}


def _metric(digest: str, *, cpu: str | None, versions: dict[str, str] | None = None
            ) -> dict[str, Any]:
    r: dict[str, Any] = {"kind": "metric", "task": {"name": "ToyReach-v0"}, "data": {"n": 2},
                         "data_checksums": {"random": digest},
                         "library_versions": dict(versions or VERSIONS)}
    if cpu is not None:
        r["cpu"] = cpu
    return r


def test_cpu_model_is_recorded_in_records_and_artifact_meta(tmp_path: Path) -> None:
    cpu = cpu_model()
    assert isinstance(cpu, str) and cpu.strip()
    record = make_record({"kind": "metric"}, {"value": 1.0}, stage={}, timings={})
    assert record["cpu"] == cpu
    assert "cpu" not in library_versions()  # a CPU is no library version
    store = Store(tmp_path / "store")
    with store.write("metric", "k1", config={}) as w:
        w.write_json({"x": 1})
    meta = json.loads((tmp_path / "store" / "metric" / "k1" / "meta.json").read_text())
    assert meta["cpu"] == cpu


def test_only_the_cpu_differs_names_the_cpus_not_versions() -> None:
    ref = [_metric("aaa", cpu="Intel(R) Xeon(R) Platinum 8375C CPU @ 2.90GHz")]
    new = [_metric("bbb", cpu="AMD EPYC 7R13 Processor")]
    [warning] = _compare_data(new, ref)
    assert "versions differ" not in warning
    assert "same versions" in warning and "CPU differs" in warning
    assert "AMD EPYC 7R13 Processor" in warning and "Platinum 8375C" in warning
    assert "\n" not in warning


def test_versions_differ_names_the_library_and_the_cpus_when_both_differ() -> None:
    ref = [_metric("aaa", cpu="cpu A")]
    new = [_metric("bbb", cpu="cpu B", versions={**VERSIONS, "mujoco": "3.2.0"})]
    [warning] = _compare_data(new, ref)
    assert "versions differ" in warning and "mujoco 3.2.0 here vs 3.1.6 in the reference" in warning
    assert "CPU differs: cpu B here vs cpu A in the reference" in warning


def test_same_versions_and_cpu_claims_neither() -> None:
    ref = [_metric("aaa", cpu="cpu A")]
    new = [_metric("bbb", cpu="cpu A")]
    [warning] = _compare_data(new, ref)
    assert "versions differ" not in warning and "CPU differs" not in warning
    assert "same versions and CPU" in warning


def test_reference_without_cpu_says_it_is_not_recorded() -> None:
    ref = [_metric("aaa", cpu=None)]
    new = [_metric("bbb", cpu="cpu A")]
    [warning] = _compare_data(new, ref)
    assert "versions differ" not in warning
    assert "CPU not recorded" in warning
