"""Checks of command-line inputs that must pass before any stage runs.

Each raises a one-line :class:`~repbench.errors.ConfigError` naming the option and the fix, so a
mistake in the last argument of a command costs seconds, not a finished run:

* :func:`check_ray_address`: the Ray cluster answers (a TCP connect with a short timeout)
  before the address is handed to ``ray.init``, which otherwise waits minutes for a host that
  does not answer, and prints a traceback when ``auto`` finds no cluster.
"""

from __future__ import annotations

import os
import socket
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

