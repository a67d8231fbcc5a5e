"""TOML parsing on every Python repbench supports: the standard library's ``tomllib`` from 3.11,
the ``tomli`` package it came from on 3.10 (a dependency there)."""

from __future__ import annotations

import sys

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - 3.10
    import tomli as tomllib

__all__ = ["TOMLDecodeError", "loads"]

loads = tomllib.loads
TOMLDecodeError = tomllib.TOMLDecodeError
