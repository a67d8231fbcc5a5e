"""Export a suite's latents from a stage store into the shipped format
(:mod:`repbench.analysis.latent_sets`): ``repbench export-latents``."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from repbench.analysis.latent_sets import write_latent_sets
from repbench.analysis.results import installed_versions, load_records, select
from repbench.errors import ConfigError
from repbench.pipeline.plan import build_plan
from repbench.pipeline.records import identity_key
from repbench.pipeline.stages import DATASET, LATENTS
from repbench.pipeline.store import Store
from repbench.pipeline.suite import load_suite

__all__ = ["export_latents"]


def export_latents(suite: str | Path, *, store: str | Path | None, out: str | Path,
                   tasks: Sequence[str] | None = None,
                   encoders: Sequence[str] | None = None) -> list[Path]:
    """Write the latents of ``suite``'s latents stages that ``store`` holds (of ``tasks`` and
    ``encoders`` only, when given) into ``out``, beside what ``out`` already holds; returns the
    files written. Each set is named by its latents record, which the suite's records folder
    holds once ``repbench leaderboard`` has copied the store's records."""
    s = load_suite(suite)
    st = Store(store)
    wanted = {identity_key(spec.record) for spec in build_plan(s).stages()
              if spec.kind == LATENTS and spec.record is not None}
    records = load_records(st, kinds=(LATENTS,))
    chosen = [r for r in select(records, wanted, installed_versions(records))
              if (tasks is None or r["task"]["name"] in tasks)
              and (encoders is None or r["encoder"]["name"] in encoders)]
    pairs = []
    for r in chosen:
        art = st.get(LATENTS, r["stage"]["key"])
        if art is not None and art.file("latents.npz").is_file():
            pairs.append((r, art.file("latents.npz")))
    if not pairs:
        raise ConfigError(f"store {st.root} holds no latents of suite {s.name!r}"
                          + (f" on {', '.join(tasks)}" if tasks else "")
                          + f"; run `repbench run --suite {suite} --no-rl` first")
    return write_latent_sets(pairs, out, extra=lambda record, arrays: _rewards(
        st, record, arrays))


def _rewards(store: Store, record: dict, arrays: dict) -> dict:
    """``reward`` of latents stored before the latents stage kept it: the rewards of the
    record's datasets, concatenated in the stage's order (its inputs sorted by name)."""
    if "reward" in arrays:
        return {}
    parts = []
    for _, key in sorted((record.get("data_stages") or {}).items()):
        art = store.get(DATASET, key)
        if art is None:
            return {}
        with np.load(art.file("dataset.npz"), allow_pickle=False) as f:
            parts.append(np.asarray(f["reward"], dtype=np.float32))
    reward = np.concatenate(parts) if parts else np.zeros(0, np.float32)
    return {"reward": reward} if len(reward) == len(arrays["z"]) else {}
