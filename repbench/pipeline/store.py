"""The stage store: every stage's output under a content hash of its config and inputs.

An artifact is a directory ``<root>/<stage>/<key>/`` holding the stage's files and a
``meta.json`` record (config, input keys, seeds, library versions, CPU model, git commit,
timings, and the SHA-256 of every file). It is built in ``<root>/.tmp/`` and appears under its
final name by one ``rename``: a reader sees a complete artifact or none, even if the writer is
killed with -9.
A later reader that finds a file missing or failing its checksum, or a file where an artifact's
(or a stage's) folder should be, reports it, moves it aside to ``<root>/.corrupt/`` and
recomputes.

Two runs may share a store: a stage is computed under its lock ``<root>/<stage>/<key>.lock``
(``fcntl.flock``, held while its artifact is written), so a second run waits for a stage the
first is computing and then reuses it. The kernel releases the lock when its holder dies, so a
lock left by a killed process never blocks. A temporary folder whose stage lock is free was left
by a killed writer; :meth:`Store.clean_tmp` removes it (every run does, before it starts).

Reading a store's records needs none of this module: the store's layout that readers rely on
(:data:`~repbench.records.META`, :data:`~repbench.records.RECORD_STAGES`,
:func:`~repbench.records.file_sha256`, :func:`~repbench.records.holds_exported_records`) lives in
:mod:`repbench.records`, the provenance every artifact carries (``cpu_model``, ``git_commit``,
``library_versions``, ``source_commit``) in :mod:`repbench.provenance`; both are importable from
here as before.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import inspect
import json
import logging
import os
import platform
import re
import shutil
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from repbench.errors import CorruptArtifactError, RepbenchError, StoreError
from repbench.provenance import cpu_model, git_commit, library_versions
from repbench.provenance import source_commit as source_commit  # re-exported (it lived here)
from repbench.records import META, file_sha256, holds_exported_records
from repbench.records import RECORD_STAGES as RECORD_STAGES  # re-exported (it lived here)

try:
    import fcntl
except ImportError:  # pragma: no cover (Windows: no stage locks)
    fcntl = None  # type: ignore[assignment]

log = logging.getLogger(__name__)

STORE_ENV_VAR = "REPBENCH_STORE"
STORE_FORMAT = 1
LOCK_SUFFIX = ".lock"
#: ``<stage>-<key>-<pid>-<tag>``: the name :meth:`Store.write` gives a temporary folder
_TMP_NAME = re.compile(r"^(?P<stage>.+)-(?P<key>[^-]+)-(?P<pid>\d+)-(?P<tag>[0-9a-f]{8})$")
#: stage locks this process holds: (lock path, thread id) → [file descriptor, depth]
_HELD: dict[tuple[str, int], list[int]] = {}


def default_store_root() -> Path:
    """``$REPBENCH_STORE``, else ``$XDG_CACHE_HOME/repbench/store``, else ``~/.cache/...``."""
    if os.environ.get(STORE_ENV_VAR):
        return Path(os.environ[STORE_ENV_VAR]).expanduser()
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "repbench" / "store"


def canonical_json(obj: Any) -> str:
    """Deterministic JSON used for hashing (sorted keys, no whitespace)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=_json_default)


def _json_default(obj: Any) -> Any:
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot hash a {type(obj).__name__} in a stage config; use plain values")


def stage_key(stage: str, config: Mapping[str, Any], inputs: Sequence[str] = ()) -> str:
    """Content hash of a stage: its name, its config and its inputs' keys."""
    payload = canonical_json({"stage": stage, "config": config, "inputs": list(inputs),
                              "format": STORE_FORMAT})
    return hashlib.sha256(payload.encode()).hexdigest()[:32]


@dataclass(frozen=True)
class Artifact:
    """A finished, verified stage output."""

    stage: str
    key: str
    path: Path
    meta: dict[str, Any]

    def file(self, name: str) -> Path:
        return self.path / name

    def read_json(self, name: str = "result.json") -> Any:
        with open(self.path / name) as f:
            return json.load(f)


class ArtifactWriter:
    """Collects a stage's files in a private temporary directory until commit."""

    def __init__(self, tmp_dir: Path) -> None:
        self.path = tmp_dir
        self.result: Any = None
        self.extra_meta: dict[str, Any] = {}

    def file(self, name: str) -> Path:
        """Path to write a file of the artifact to."""
        return self.path / name

    def write_json(self, obj: Any, name: str = "result.json") -> Path:
        p = self.path / name
        with open(p, "w") as f:
            json.dump(obj, f, default=_json_default)
        return p


class Store:
    """Content-addressed, crash-safe storage of stage outputs.

    Args:
        root: directory to use; default :func:`default_store_root`. Created if missing;
            an unwritable root raises :class:`StoreError` at once.
    """

    def __init__(self, root: str | os.PathLike[str] | None = None) -> None:
        if root is not None and not str(root).strip():  # Path("") would be the current folder
            raise StoreError("--store is empty; pass the store folder, or leave the option out "
                             f"for ${STORE_ENV_VAR} or the default {default_store_root()}")
        self.root = Path(root).expanduser() if root is not None else default_store_root()
        if holds_exported_records(self.root):  # a store here would hide its records from readers
            raise StoreError(f"{self.root} is a folder of exported records (<kind>/<name>.json), "
                             "not a stage store; pass another --store, and give the records "
                             "folder to --records")
        try:
            (self.root / ".tmp").mkdir(parents=True, exist_ok=True)
            probe = self.root / ".tmp" / f".probe-{uuid.uuid4().hex}"
            probe.write_text("ok")
            probe.unlink()
        except OSError as exc:
            raise StoreError(
                f"store root {self.root} is not writable ({exc.strerror or exc}); pass --store DIR "
                f"or set {STORE_ENV_VAR} to a writable directory"
            ) from None

    def artifact_dir(self, stage: str, key: str) -> Path:
        return self.root / stage / key

    def key(self, stage: str, config: Mapping[str, Any], inputs: Sequence[str] = ()) -> str:
        return stage_key(stage, config, inputs)

    # -- reading ---------------------------------------------------------------------------------
    def get(self, stage: str, key: str, *, verify: bool = True) -> Artifact | None:
        """The finished artifact, or None if absent; a corrupt one is quarantined → None."""
        path = self.artifact_dir(stage, key)
        if not path.is_dir():
            self._file_in_the_way(path.parent, "a stage folder")
            self._file_in_the_way(path, f"the artifact folder of {stage}/{key}")
            return None
        try:
            return self._load(stage, key, path, verify=verify)
        except CorruptArtifactError as exc:
            log.warning("%s; it will be recomputed", exc)
            self._quarantine(path)
            return None

    def _load(self, stage: str, key: str, path: Path, *, verify: bool) -> Artifact:
        try:
            with open(path / META) as f:
                meta = json.load(f)
        except (OSError, json.JSONDecodeError) as exc:
            raise CorruptArtifactError(f"artifact {stage}/{key} has no readable {META}: {exc}"
                                       ) from None
        if verify:
            for name, digest in meta.get("files", {}).items():
                fp = path / name
                if not fp.is_file():
                    raise CorruptArtifactError(f"artifact {stage}/{key} lacks file {name}")
                if file_sha256(fp) != digest:
                    raise CorruptArtifactError(
                        f"artifact {stage}/{key} file {name} fails its checksum (truncated or "
                        "modified)"
                    )
        return Artifact(stage, key, path, meta)

    def _file_in_the_way(self, path: Path, what: str) -> None:
        """A file (or a dangling link) where the store keeps a folder is a corrupt artifact:
        it is moved aside to ``.corrupt/`` like one, so the stage is recomputed (a rename of
        the new artifact onto it would fail). StoreError when it cannot be moved."""
        if path.is_dir() or not os.path.lexists(path):
            return
        log.warning("%s is a file, not %s; moved aside to %s, it will be recomputed",
                    path, what, self.root / ".corrupt")
        self._quarantine(path)
        if os.path.lexists(path) and not path.is_dir():
            raise StoreError(f"{path} is a file, not {what}, and it cannot be moved aside; "
                             "remove it, or pass another --store")

    def _quarantine(self, path: Path) -> None:
        dest = self.root / ".corrupt" / f"{path.parent.name}-{path.name}-{uuid.uuid4().hex[:8]}"
        dest.parent.mkdir(parents=True, exist_ok=True)
        with contextlib.suppress(OSError):
            os.replace(path, dest)

    def list(self, stage: str) -> list[Artifact]:
        """Every verified artifact of a stage (used to rebuild leaderboards)."""
        base = self.root / stage
        if not base.is_dir():
            self._file_in_the_way(base, "a stage folder")
            return []
        arts = (self.get(stage, p.name) for p in sorted(base.iterdir()) if p.is_dir())
        return [a for a in arts if a is not None]

    def metas(self, stage: str) -> Iterator[dict[str, Any]]:
        """The ``meta.json`` of every finished artifact of a stage, unverified and unreadable
        ones skipped: cheap enough to read a store of thousands of stages for an estimate."""
        base = self.root / stage
        if not base.is_dir():
            return
        for path in base.iterdir():
            with contextlib.suppress(OSError, json.JSONDecodeError):
                with open(path / META) as f:
                    meta = json.load(f)
                if isinstance(meta, dict):
                    yield meta

    # -- locking ---------------------------------------------------------------------------------
    def lock_path(self, stage: str, key: str) -> Path:
        return self.root / stage / f"{key}{LOCK_SUFFIX}"

    @contextlib.contextmanager
    def lock(self, stage: str, key: str, *, wait: bool = True) -> Iterator[bool]:
        """Hold the stage's lock (an exclusive ``flock`` on :meth:`lock_path`) in the block.

        Yields True once held; with ``wait=False`` it yields False at once instead of waiting
        when another process (or thread) holds it. Re-entrant within one thread. A lock held by
        a process that died is free: the kernel drops it with the process.
        """
        path = self.lock_path(stage, key)
        ident = (str(path), threading.get_ident())
        if fcntl is None or ident in _HELD:
            if ident in _HELD:
                _HELD[ident][1] += 1
            try:
                yield True
            finally:
                if ident in _HELD:
                    _HELD[ident][1] -= 1
            return
        self._file_in_the_way(path.parent, "a stage folder")
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
            except BlockingIOError:
                acquired = False
            else:
                acquired = True
                _HELD[ident] = [fd, 1]
            try:
                yield acquired
            finally:
                _HELD.pop(ident, None)
        finally:
            os.close(fd)  # releases the flock

    # -- writing ---------------------------------------------------------------------------------
    @contextlib.contextmanager
    def write(self, stage: str, key: str, *, config: Mapping[str, Any],
              inputs: Sequence[str] = (), seeds: Mapping[str, Any] | None = None
              ) -> Iterator[ArtifactWriter]:
        """Context manager: write files into ``writer.path``; on success they are committed
        atomically with their metadata record. On any exception nothing becomes visible.

        The stage's lock (:meth:`lock`) is held from the temporary folder's creation until the
        commit, so :meth:`clean_tmp` can tell a folder being written from a leftover."""
        with self.lock(stage, key):
            yield from self._write(stage, key, config=config, inputs=inputs, seeds=seeds)

    def _write(self, stage: str, key: str, *, config: Mapping[str, Any],
               inputs: Sequence[str], seeds: Mapping[str, Any] | None
               ) -> Iterator[ArtifactWriter]:
        tmp = self.root / ".tmp" / f"{stage}-{key}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        tmp.mkdir(parents=True)
        writer = ArtifactWriter(tmp)
        start_wall, start_cpu = time.time(), time.process_time()
        try:
            yield writer
            files = {p.name: file_sha256(p) for p in sorted(tmp.iterdir()) if p.is_file()}
            for p in tmp.iterdir():
                _fsync_file(p)
            meta = {
                "format": STORE_FORMAT, "stage": stage, "key": key, "config": config,
                "inputs": list(inputs), "seeds": dict(seeds or {}), "files": files,
                "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                "wall_time_s": round(time.time() - start_wall, 3),
                "cpu_time_s": round(time.process_time() - start_cpu, 3),
                "versions": library_versions(), "git_commit": git_commit(),
                "cpu": cpu_model(), "host": platform.node(), **writer.extra_meta,
            }
            meta_path = tmp / META
            with open(meta_path, "w") as f:
                f.write(json.dumps(meta, indent=1, default=_json_default))
                f.flush()
                os.fsync(f.fileno())
            final = self.artifact_dir(stage, key)
            final.parent.mkdir(parents=True, exist_ok=True)
            # another worker finished first (keep its copy), or a corrupt leftover (get()
            # quarantines it, then the rename below succeeds)
            if os.path.lexists(final) and self.get(stage, key) is not None:
                shutil.rmtree(tmp, ignore_errors=True)
                return
            os.rename(tmp, final)
            _fsync_dir(final.parent)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)

    def clean_tmp(self, older_than_s: float = 3600.0) -> int:
        """Remove temporary folders left by killed writers; returns how many.

        A folder :meth:`write` names is being written while its stage's lock is held, so one
        whose lock is free is a leftover and goes at once; a folder of another name goes when
        it is older than ``older_than_s``."""
        removed = 0
        now = time.time()
        for p in sorted((self.root / ".tmp").iterdir()):
            if not p.is_dir():
                continue
            m = _TMP_NAME.match(p.name)
            if m is None:
                if now - p.stat().st_mtime > older_than_s:
                    shutil.rmtree(p, ignore_errors=True)
                    removed += 1
                continue
            path = str(self.lock_path(m["stage"], m["key"]))
            if any(held == path for held, _ in _HELD):  # this process is writing it
                continue
            with self.lock(m["stage"], m["key"], wait=False) as free:
                if free and p.exists():
                    shutil.rmtree(p, ignore_errors=True)
                    removed += 1
        return removed


def _fsync_file(path: Path) -> None:
    if path.is_file():
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _fsync_dir(path: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def no_store_left_by_a_refusal(store: str | Path | None) -> Iterator[None]:
    """When a refusal (a :class:`~repbench.errors.RepbenchError`) ends the block while the store
    folder it created holds no file, remove that folder again, and the missing folders above it
    that it made: ``repbench run --suite bad.toml --store /tmp/newstore`` left an empty
    /tmp/newstore (the store is opened, and its folder made, before the plan's checks). A folder
    that was there before, or that holds a file, is never touched. ``store`` as the entry
    points take it (a path, or None for :func:`default_store_root`); a :class:`Store` object
    was made by the caller and is left alone."""
    if isinstance(store, Store) or (isinstance(store, str) and not store.strip()):
        yield  # made by the caller, or refused by Store itself: nothing made here
        return
    root = (Path(store).expanduser() if store is not None else default_store_root()).absolute()
    created = []  # the folders this block may make, deepest first
    folder = root
    while not os.path.lexists(folder) and folder != folder.parent:
        created.append(folder)
        folder = folder.parent
    try:
        yield
    except RepbenchError:
        if created and not _holds_a_file(root):
            for path in created:
                _remove_empty_folders(path)
        raise


def leaves_no_store_on_refusal(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Decorate an entry point that takes ``store``: :func:`no_store_left_by_a_refusal` around
    every call, from the command line or from Python."""
    sig = inspect.signature(fn)

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        bound = sig.bind_partial(*args, **kwargs)
        with no_store_left_by_a_refusal(bound.arguments.get("store")):
            return fn(*args, **kwargs)

    return wrapper


def _holds_a_file(folder: Path) -> bool:
    return any(files or any(os.path.islink(os.path.join(top, d)) for d in dirs)
               for top, dirs, files in os.walk(folder))


def _remove_empty_folders(folder: Path) -> None:
    """Remove ``folder`` and the folders below it, deepest first, where they are empty."""
    for top, _, _ in os.walk(folder, topdown=False):
        with contextlib.suppress(OSError):
            os.rmdir(top)
