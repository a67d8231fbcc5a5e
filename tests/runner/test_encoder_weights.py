"""Records name the trained encoder weights they were computed from, and a board that mixes two
trainings of one encoder says so.

Encoder training is not bit-reproducible across CPUs (torch picks AVX2 or AVX-512 kernels): the
same stage key on two machines stands for different weights. Merging one machine's metric
records with another's RL records of "the same" encoder would publish a metric and a return of
two different encoders as one row."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from repbench.pipeline.records import (
    mixed_encoder_weights,
    read_record,
    record_checksum,
    write_record,
)
from repbench.pipeline.runner import rebuild_leaderboards, run_suite

from .tiny_toy_suite import tiny_toy_suite


@pytest.fixture(scope="module")
def toy_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A tiny ToyReach-v0 run: (suite file, store)."""
    root = tmp_path_factory.mktemp("weights")
    suite = root / "toyweights.toml"
    suite.write_text(tiny_toy_suite("toyweights", ["oracle", "random"]))
    result = run_suite(suite, store=root / "store", out=root / "lb", workers=1, progress=False)
    assert not result.report.failed
    return suite, root / "store"


def _store_records(store: Path) -> list[dict]:
    return [r for p in sorted(store.glob("*/*/record.json")) if (r := read_record(p))]


def test_every_record_names_the_weights_of_its_encoder(toy_run: tuple[Path, Path]) -> None:
    _, store = toy_run
    digests = {}
    for meta_file in store.glob("encoder/*/meta.json"):
        meta = json.loads(meta_file.read_text())
        digests[meta["config"]["encoder"]] = meta["files"]["encoder.pt"]
    assert set(digests) == {"oracle", "random"} and len(set(digests.values())) == 2
    records = _store_records(store)
    with_encoder = [r for r in records if r.get("encoder")]
    assert {r["kind"] for r in with_encoder} == {"encoder", "latents", "metric", "rl"}
    for r in with_encoder:
        assert r["encoder_weights"] == digests[r["encoder"]["name"]], (r["kind"], r["encoder"])
    assert all(r["encoder_weights"] is None for r in records if not r.get("encoder"))
    assert mixed_encoder_weights(records) == []


def _restamped(record: dict, **changes: object) -> dict:
    out = {k: v for k, v in record.items() if not k.startswith("_")}
    out.update(changes)
    out["checksum"] = record_checksum(out)
    return out


def test_a_board_mixing_two_trainings_of_one_encoder_says_so(
        toy_run: tuple[Path, Path], tmp_path: Path) -> None:
    suite, store = toy_run
    records = _store_records(store)
    rl = next(r for r in records if r["kind"] == "rl" and r["encoder"]["name"] == "random")
    other_training = "0" * 64
    folder = tmp_path / "records"
    for i, r in enumerate(records):
        write_record(_restamped(r, encoder_weights=other_training) if r is rl else r,
                     folder / f"{i}.json")
    out = rebuild_leaderboards(suite, records=folder, out=tmp_path / "board")
    page = (out / "index.html").read_text()
    assert "encoder random on ToyReach-v0: its records come from 2 different trainings" in page
    assert "encoder oracle on" not in page

    (warning,) = mixed_encoder_weights([read_record(p) for p in sorted(folder.glob("*.json"))])
    assert f"{other_training[:12]}: rl" in warning and "encoder, latents, metric" in warning


def test_records_without_weights_are_not_judged() -> None:
    def rec(kind: str, weights: str | None) -> dict:
        return {"kind": kind, "task": {"name": "T"}, "encoder": {"name": "e", "params": {}},
                "encoder_weights": weights}

    assert mixed_encoder_weights([rec("metric", "a" * 64), rec("rl", None)]) == []
    assert mixed_encoder_weights([rec("metric", "a" * 64), {"kind": "rl"}]) == []
    assert len(mixed_encoder_weights([rec("metric", "a" * 64), rec("rl", "b" * 64)])) == 1
