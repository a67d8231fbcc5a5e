"""Checks of command-line inputs that must pass before any stage runs.

Each raises a one-line :class:`~repbench.errors.ConfigError` naming the option and the fix, so a
mistake in the last argument of a command costs seconds, not a finished run:

* :func:`check_ray_address`: the Ray cluster answers (a TCP connect with a short timeout)
  before the address is handed to ``ray.init``, which otherwise waits minutes for a host that
  does not answer, and prints a traceback when ``auto`` finds no cluster;
* :func:`check_out_dir`: a leaderboard folder can be created and written (``run`` and
  ``evaluate`` write it only after every stage ran);
* :func:`check_out_file`: a figure file can be written, in a format matplotlib knows.
"""

from __future__ import annotations

import os
import socket
import tempfile
from pathlib import Path

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
