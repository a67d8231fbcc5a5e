"""The reference's latents, shipped: every encoder's z on the metric data, beside its records.

A metric is a function of (z, true state, trajectory), so with the latents behind a reference's
metric records anyone can score a new metric against the reference's RL returns without
training an encoder or running RL (``repbench score-metric``,
:mod:`repbench.analysis.score_metric`).

**Format** (:data:`FORMAT`, version :data:`FORMAT_VERSION`), one folder per suite, e.g.
``leaderboards/quick/latents/``::

    manifest.json                      the index below
    <task>/data-<sha12>.npz            the arrays every encoder of the task shares, stored once
    <task>/<record stem>.npz           one encoder's z, named like the latents record that made
                                       it (records/latents/<record stem>.json)

* ``<task>/<record stem>.npz`` holds ``z``: float32 ``[N, D]``, the encoder's mean latent μ_z of
  each row (``np.savez_compressed``).
* ``<task>/data-<sha12>.npz`` holds the rows' ``z_true`` (the true state z°), ``task_state``,
  ``robot_state``, ``action``, ``reward``, ``episode``, ``step``, ``source`` (an index into
  ``source_names``, which dataset a row came from: ``heldout`` or ``on_policy``) and
  ``source_names``: exactly the latents stage's arrays (:func:`repbench.pipeline.stages.
  _run_latents`) without ``z``. ``sha12`` is the first 12 hex digits of the SHA-256 of those
  arrays' bytes, so encoders computed on the same data share one file.
* ``manifest.json``: ``format``, ``format_version``, and ``sets``, one entry per latent set
  with ``task``, ``encoder``, ``file``, ``data_file``, ``sha256`` (of ``file``), ``n``,
  ``latent_dim``, ``latents_identity`` and ``latents_key`` (the latents record's identity and
  stage key), ``encoder_weights`` (SHA-256 of the encoder that made z, as in its records) and
  ``data_checksums`` (the datasets' checksums); and ``data``, file → its ``sha256``.

Every file's SHA-256 is checked when it is read: a damaged or edited file is refused in one
line naming it, never scored.
"""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from repbench.analysis.results import record_stem
from repbench.errors import DataError

__all__ = ["FORMAT", "FORMAT_VERSION", "MANIFEST", "LatentSet", "read_latent_sets",
           "write_latent_sets"]

FORMAT = "repbench.latents"
FORMAT_VERSION = 1
MANIFEST = "manifest.json"
#: The arrays stored once per task (everything a latents stage stores but z).
SHARED = ("z_true", "task_state", "robot_state", "action", "reward", "episode", "step",
          "source", "source_names")


@dataclass
class LatentSet:
    """One encoder's latents on one task, with the task's shared arrays (read lazily)."""

    task: str
    encoder: str
    #: the manifest's entry, plus ``data_sha256`` (its data file's checksum)
    entry: dict[str, Any]
    folder: Path
    #: shared arrays already read, by path (one dict for every set of a task)
    cache: dict[str, Any] = field(default_factory=dict, repr=False)

    def arrays(self) -> dict[str, np.ndarray]:
        """``z`` and the shared arrays, checksums verified (a DataError names a bad file)."""
        shared = _load_npz(self.folder / self.entry["data_file"], self.entry["data_sha256"],
                           self.cache)
        own = _load_npz(self.folder / self.entry["file"], self.entry["sha256"], None)
        return {**shared, "z": own["z"]}


def _sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _npz_bytes(arrays: Mapping[str, np.ndarray]) -> bytes:
    """``np.savez_compressed``'s format, byte-reproducible: members in name order with a fixed
    date (numpy stamps the current time), so exporting the same latents twice changes no
    file."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in sorted(arrays):
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            with zf.open(info, "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.asanyarray(arrays[name]), allow_pickle=False)
    return buf.getvalue()


def _arrays_digest(arrays: Mapping[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(name.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _load_npz(path: Path, sha256: str, cache: dict[str, Any] | None) -> dict[str, np.ndarray]:
    if cache is not None and str(path) in cache:
        return cache[str(path)]
    if not path.is_file():
        raise DataError(f"shipped latents file {path} is missing; restore it from git "
                        "(`git checkout -- <file>`) or export the latents again")
    data = path.read_bytes()
    if _sha256_bytes(data) != sha256:
        raise DataError(f"shipped latents file {path} does not match its checksum in "
                        f"{MANIFEST} (edited or damaged); restore it from git")
    with np.load(io.BytesIO(data), allow_pickle=False) as f:
        out = {k: f[k] for k in f.files}
    if cache is not None:
        cache[str(path)] = out
    return out


def read_manifest(folder: str | Path) -> dict[str, Any]:
    """The manifest of a latents folder; DataError (one line) if there is none or it is not
    this format."""
    path = Path(folder) / MANIFEST
    if not path.is_file():
        raise DataError(f"no shipped latents in {folder} (no {MANIFEST}); the reference's "
                        "latents are exported with `repbench export-latents`")
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DataError(f"{path} is not a readable latents manifest ({exc}); restore it "
                        "from git") from None
    if manifest.get("format") != FORMAT or int(manifest.get("format_version", 0)) > \
            FORMAT_VERSION:
        raise DataError(f"{path} is not a {FORMAT} manifest of version <= {FORMAT_VERSION}; "
                        "upgrade repbench")
    return manifest


def read_latent_sets(folder: str | Path, tasks: Iterable[str] | None = None
                     ) -> list[LatentSet]:
    """The latent sets of ``folder`` (of ``tasks`` only, when given), in the manifest's order.
    Files are read (and their checksums checked) when :meth:`LatentSet.arrays` is called; the
    sets of one task share one cache of its shared arrays."""
    folder = Path(folder)
    manifest = read_manifest(folder)
    wanted = set(tasks) if tasks is not None else None
    caches: dict[str, dict[str, Any]] = {}
    out = []
    for entry in manifest.get("sets", []):
        if wanted is not None and entry["task"] not in wanted:
            continue
        entry = {**entry, "data_sha256": manifest["data"][entry["data_file"]]["sha256"]}
        out.append(LatentSet(entry["task"], entry["encoder"], entry, folder,
                             caches.setdefault(entry["task"], {})))
    return out


def write_latent_sets(pairs: Iterable[tuple[Mapping[str, Any], Path]], folder: str | Path,
                      extra: Any = None) -> list[Path]:
    """Write each (latents record, its ``latents.npz``) into ``folder`` in the format above,
    with ``extra(record, arrays)``'s arrays added to the shared ones where the file lacks them
    (the export adds ``reward`` to latents stored before the latents stage kept it),
    adding to (or replacing the same task × encoder in) what the folder's manifest already
    lists; returns the files written. Data files no set refers to any more are removed (only
    files the manifest lists: nothing else in the folder is touched)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        manifest = read_manifest(folder)
    except DataError:
        if (folder / MANIFEST).exists():
            raise
        manifest = {"format": FORMAT, "format_version": FORMAT_VERSION, "sets": [], "data": {}}
    sets = {(e["task"], e["encoder"]): e for e in manifest["sets"]}
    written = []
    for record, npz in pairs:
        task, encoder = record["task"]["name"], record["encoder"]["name"]
        with np.load(npz, allow_pickle=False) as f:
            arrays = {k: f[k] for k in f.files}
        if extra is not None:
            arrays = {**extra(record, arrays), **arrays}
        shared = {k: arrays[k] for k in SHARED if k in arrays}
        data_file = f"{task}/data-{_arrays_digest(shared)[:12]}.npz"
        if data_file not in manifest["data"] or not (folder / data_file).is_file():
            blob = _npz_bytes(shared)
            (folder / task).mkdir(exist_ok=True)
            (folder / data_file).write_bytes(blob)
            manifest["data"][data_file] = {"sha256": _sha256_bytes(blob), "task": task,
                                           "n": len(arrays["z"]),
                                           "arrays": sorted(shared)}
            written.append(folder / data_file)
        z = np.asarray(arrays["z"], dtype=np.float32)
        blob = _npz_bytes({"z": z})
        old = sets.get((task, encoder))
        file = f"{task}/{record_stem(record)}.npz"
        if old is not None and old["file"] != file:
            (folder / old["file"]).unlink(missing_ok=True)
        (folder / file).write_bytes(blob)
        written.append(folder / file)
        sets[(task, encoder)] = {
            "task": task, "encoder": encoder, "file": file, "data_file": data_file,
            "sha256": _sha256_bytes(blob), "n": int(z.shape[0]), "latent_dim": int(z.shape[1]),
            "latents_identity": record.get("identity"),
            "latents_key": (record.get("stage") or {}).get("key"),
            "encoder_weights": record.get("encoder_weights"),
            "data_checksums": record.get("data_checksums", {})}
    manifest["sets"] = sorted(sets.values(), key=lambda e: (e["task"], e["encoder"]))
    used = {e["data_file"] for e in manifest["sets"]}
    for data_file in sorted(set(manifest["data"]) - used):
        (folder / data_file).unlink(missing_ok=True)
        del manifest["data"][data_file]
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n",
                                   encoding="utf-8")
    return written
