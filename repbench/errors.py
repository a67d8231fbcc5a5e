"""Errors a person can act on.

Every exception repbench raises for a user's mistake derives from :class:`RepbenchError`; the CLI
prints its one-line message and exits with code 2 instead of showing a traceback.
"""

from __future__ import annotations


class RepbenchError(Exception):
    """A user-facing error: the message names the thing at fault and what to do."""


class PluginError(RepbenchError, LookupError):
    """Unknown, duplicate, or unimportable plugin."""


class ConfigError(RepbenchError, ValueError):
    """A suite file or a plugin parameter is invalid."""


class DataError(RepbenchError, ValueError):
    """Input arrays or files are malformed: wrong shape, NaN, missing modality, truncated file."""


class StoreError(RepbenchError, OSError):
    """The stage store cannot be used (unwritable root, ...)."""


class DiskFullError(StoreError):
    """The disk holding the store is full: the run stops (every later stage would fail)."""


class CorruptArtifactError(StoreError):
    """A stored artifact failed its checksum or is incomplete; it will be recomputed."""


class TrainingDivergedError(RepbenchError, FloatingPointError):
    """A training loss became NaN or infinite."""
