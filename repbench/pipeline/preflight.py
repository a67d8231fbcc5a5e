"""Checks of command-line inputs that must pass before any stage runs.

Each raises a one-line :class:`~repbench.errors.ConfigError` naming the option and the fix, so a
mistake in the last argument of a command costs seconds, not a finished run:

* :func:`check_ray_address`: the Ray cluster answers (a TCP connect with a short timeout)
  before the address is handed to ``ray.init``, which otherwise waits minutes for a host that
  does not answer, and prints a traceback when ``auto`` finds no cluster;
* :func:`check_out_dir`: a leaderboard folder can be created and written (``run`` and
  ``evaluate`` write it only after every stage ran);
* :func:`check_out_file`: a figure file can be written, in a format matplotlib knows;
* :func:`check_dataset_sizes`: every dataset the suite collects fits in the memory that is
  available, and the ones still to collect fit on the store's disk (a ``random_episodes`` of
  10⁷ otherwise ran until a MemoryError at ~10 GB that named nothing).
"""

from __future__ import annotations

import dataclasses
import inspect
import os
import shutil
import socket
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from repbench.pipeline.plan import Plan
    from repbench.pipeline.store import Store

from repbench.errors import ConfigError

#: Seconds to wait for a Ray cluster's address to accept a TCP connection.
RAY_CONNECT_TIMEOUT_S = 2.0
#: Ray's environment variable with the address of the cluster to join.
RAY_ADDRESS_ENV = "RAY_ADDRESS"

_RAY_HINT = ("start the cluster there (`ray start --head`), fix --ray-address, or leave it out "
             "to start a local Ray instance")


def ray_address_file() -> Path:
    """Where ``ray start`` records the address of the latest cluster (as Ray looks it up:
    ``$RAY_TMPDIR``, else ``$TMPDIR``, else ``/tmp``, then ``ray/ray_current_cluster``)."""
    base = os.environ.get("RAY_TMPDIR") or os.environ.get("TMPDIR") or "/tmp"
    return Path(base) / "ray" / "ray_current_cluster"


def check_ray_address(address: str, timeout_s: float = RAY_CONNECT_TIMEOUT_S) -> None:
    """Raise ConfigError unless ``address`` names a Ray cluster that answers.

    ``auto`` is resolved as Ray resolves it (``$RAY_ADDRESS``, else the address file written by
    ``ray start``, :func:`ray_address_file`); ``local`` (start a new instance) needs no check;
    ``host:port`` and ``ray://host:port`` must accept a TCP connection within ``timeout_s``.
    """
    address = address.strip()
    if address == "local":
        return
    where = "--ray-address"
    if address == "auto":
        env = os.environ.get(RAY_ADDRESS_ENV, "").strip()
        if env and env != "auto":
            address, where = env, f"--ray-address auto (${RAY_ADDRESS_ENV}={env})"
        else:
            file = ray_address_file()
            try:
                address = file.read_text().strip()
            except OSError:
                address = ""
            if not address:
                raise ConfigError(
                    f"--ray-address auto: no running Ray cluster found (${RAY_ADDRESS_ENV} is "
                    f"unset and {file} does not exist); {_RAY_HINT}")
            where = f"--ray-address auto (found {address} in {file})"
    host, port = _host_port(address, where)
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:
        reason = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise ConfigError(f"{where}: no Ray cluster answers at {host}:{port} ({reason} within "
                          f"{timeout_s:g} s); {_RAY_HINT}") from None


def _host_port(address: str, where: str) -> tuple[str, int]:
    """``host:port`` (optionally ``ray://``-prefixed, IPv6 hosts in brackets) → (host, port)."""
    rest = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = rest.rstrip("/").rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ConfigError(f"{where}: {address!r} is not a Ray address; use 'auto', 'local' or "
                          "HOST:PORT of the cluster's head node (e.g. 10.0.0.5:6379)")
    return host, int(port)


def check_out_dir(out: str | os.PathLike[str], option: str = "--out") -> Path:
    """Raise ConfigError unless ``out`` is (or can be created as) a writable folder; creates
    nothing. Returns it as a Path."""
    if not str(out).strip():
        raise ConfigError(f"{option} is empty; pass the folder to write to (or leave the "
                          "option out for the default)")
    path = Path(out).expanduser()
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{option} {path} is a file, not a folder; pass a folder (it is "
                          "created if missing)")
    _check_writable_below(path, option, "folder")
    return path


def check_out_file(out: str | os.PathLike[str], option: str = "--out") -> Path:
    """Raise ConfigError unless a figure can be written to ``out``: not a folder, a writable
    (or creatable) parent folder, and a file extension matplotlib can write. Creates nothing."""
    from matplotlib.backend_bases import FigureCanvasBase

    if not str(out).strip():
        raise ConfigError(f"{option} is empty; pass the file to write, e.g. preview.png")
    path = Path(out).expanduser()
    if path.is_dir():
        raise ConfigError(f"{option} {path} is a folder; pass a file name, e.g. "
                          f"{path / 'preview.png'}")
    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    suffix = path.suffix.lower().lstrip(".")
    if suffix and suffix not in formats:
        raise ConfigError(f"{option} {path}: unknown image format {path.suffix!r}; use one of "
                          f"{', '.join('.' + f for f in formats)}")
    _check_writable_below(path.parent, option, "file")
    return path


def _check_writable_below(path: Path, option: str, what: str) -> None:
    """``path`` can be created (its nearest existing ancestor is a folder we can write in)."""
    existing = path.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise ConfigError(f"{option} {path}: {existing} is a file, so the {what} cannot be "
                          "created there; choose another path")
    try:
        with tempfile.TemporaryFile(dir=existing, prefix=".repbench-probe-"):
            pass
    except OSError as exc:
        raise ConfigError(f"{option} {path}: cannot write in {existing} "
                          f"({exc.strerror or exc}); choose a writable path") from None


#: Bytes a dataset holds per step beside its image: float32 ``ft`` (6), ``proprio``,
#: ``last_action``, ``action``, ``true_state`` and ``reward`` (64 floats, above every built-in
#: task's total), bool ``success``, int64 ``episode`` and ``step``.
NON_IMAGE_BYTES_PER_STEP = 64 * 4 + 1 + 2 * 8
#: The camera side a task declares no ``image_size`` for (the paper's 64).
DEFAULT_IMAGE_SIZE = 64
#: Which suite fields size each dataset, by its plan label's ending.
_DATASET_FIELDS = {"random data": ("random_episodes", "random_steps"),
                   "on-policy data": ("on_policy_episodes", "on_policy_steps"),
                   "held-out data": ("heldout_episodes", "heldout_steps")}


def dataset_bytes_per_step(image_size: int = DEFAULT_IMAGE_SIZE) -> int:
    """Bytes one step of a dataset takes in memory: the ``image_size``² RGB uint8 image and the
    per-step arrays (:data:`NON_IMAGE_BYTES_PER_STEP`)."""
    return image_size * image_size * 3 + NON_IMAGE_BYTES_PER_STEP


def check_dataset_sizes(plan: Plan, store: Store) -> None:
    """Raise ConfigError when a dataset of ``plan`` would not fit: the largest one in the
    memory available now (collection holds it whole, uncompressed), or those not yet in
    ``store`` together on its disk (counted uncompressed: an upper bound). The message names
    the suite field that sizes the dataset and the estimate in GB. Creates nothing."""
    from repbench.pipeline.stages import DATASET

    sized = []  # (bytes, fields, what, stored)
    for spec in plan.stages():
        if spec.kind != DATASET:
            continue
        episodes, steps = int(spec.config["n_episodes"]), int(spec.config["steps_per_episode"])
        task = str(spec.config["task"])
        side = _image_size(task, spec.config.get("task_params") or {})
        fields = _sizing_fields(plan, task, spec.label, episodes, steps)
        what = (f"the {spec.label} ({episodes} episodes × {steps} steps × "
                f"{dataset_bytes_per_step(side) / 1e3:.1f} kB a step)")
        stored = store.artifact_dir(spec.kind, spec.key).is_dir()
        sized.append((episodes * steps * dataset_bytes_per_step(side), fields, what, stored))
    if not sized:
        return
    where = f"suite {plan.suite.source or plan.suite.name}"
    need, fields, what, _ = max(sized, key=lambda t: t[0])
    memory = _available_memory_bytes()
    if memory is not None and need > memory:
        raise ConfigError(
            f"{where}, {fields}: {what} needs about {_gb(need)} GB of memory, {_gb(memory)} GB "
            "is available; lower them")
    missing = [t for t in sized if not t[3]]
    total = sum(t[0] for t in missing)
    free = _free_disk_bytes(store.root)
    if missing and free is not None and total > free:
        need, fields, what, _ = max(missing, key=lambda t: t[0])
        raise ConfigError(
            f"{where}, {fields}: the datasets to collect need up to "
            f"{_gb(total)} GB on the disk of the store {store.root} (the largest, {what}: "
            f"{_gb(need)} GB), {_gb(free)} GB is free; lower them or pass --store on a bigger "
            "disk")


def _gb(n_bytes: float) -> str:
    gb = n_bytes / 1e9
    return f"{gb:.3g}" if gb < 1000 else f"{gb:,.0f}"


def _sizing_fields(plan: Plan, task: str, label: str, episodes: int, steps: int) -> str:
    """The suite fields (``dataset.X`` or ``task_dataset.<task>.X``) that size the dataset of
    ``label``, with their values."""
    n_name, s_name = next((v for k, v in _DATASET_FIELDS.items() if label.endswith(k)),
                          ("random_episodes", "random_steps"))
    if s_name == "heldout_steps" and plan.suite.dataset_for(task).heldout_steps is None:
        s_name = "random_steps"  # held-out episodes default to the random ones' length
    override = plan.suite.task_dataset.get(task)

    def where(name: str) -> str:
        if override is not None and name in override.model_fields_set:
            return f"task_dataset.{task}.{name}"
        return f"dataset.{name}"

    return f"fields {where(n_name)} = {episodes} and {where(s_name)} = {steps}"


def _image_size(task: str, params: dict[str, Any]) -> int:
    """The camera side of ``task`` with ``params``: the parameter, else the task's declared
    default (its config class or constructor), else :data:`DEFAULT_IMAGE_SIZE`."""
    if isinstance(params.get("image_size"), int):
        return int(params["image_size"])
    try:
        from repbench.registry import tasks

        cls = tasks.get(task)
    except Exception:  # the plan resolved it already; never fail a size estimate on it
        return DEFAULT_IMAGE_SIZE
    config = getattr(cls, "config_class", None)
    if dataclasses.is_dataclass(config):
        for f in dataclasses.fields(config):
            if f.name == "image_size" and isinstance(f.default, int):
                return f.default
    try:
        default = inspect.signature(cls).parameters["image_size"].default
    except (KeyError, TypeError, ValueError):
        return DEFAULT_IMAGE_SIZE
    return default if isinstance(default, int) else DEFAULT_IMAGE_SIZE


def _available_memory_bytes() -> int | None:
    """Memory available to a new allocation now (psutil, else ``/proc/meminfo``'s
    MemAvailable, else free pages); None when unknown."""
    try:
        import psutil

        return int(psutil.virtual_memory().available)
    except Exception:  # psutil is optional
        pass
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _free_disk_bytes(path: Path) -> int | None:
    try:
        return shutil.disk_usage(path).free
    except OSError:
        return None
