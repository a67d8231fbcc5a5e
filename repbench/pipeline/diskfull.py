"""A full disk stops the run with one message.

Without this, every stage after the disk filled failed in turn with ``OSError: [Errno 28] No
space left on device``. :func:`stop_when_full` turns that error, where a stage writes its
artifact, into a :class:`~repbench.errors.DiskFullError`; the executors hand it back as fatal
and :func:`repbench.pipeline.executors.run_stages` stops the run with it (the CLI prints it as one
line, exit code 2). Finished stages stay in the store, so the same command resumes once there
is room.
"""

from __future__ import annotations

import contextlib
import errno
from collections.abc import Iterator

from repbench.errors import DiskFullError

#: errno values that mean "no room to write": a full device, an exhausted disk quota.
FULL_DISK_ERRNOS = frozenset({errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)})


def is_disk_full(exc: BaseException) -> bool:
    """Whether ``exc``, or an exception it was raised from, is a full-disk OSError."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, OSError) and current.errno in FULL_DISK_ERRNOS:
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False


@contextlib.contextmanager
def stop_when_full(what: str, where: str) -> Iterator[None]:
    """Re-raise a full-disk error inside the block as one :class:`DiskFullError` naming
    ``what`` was being written and ``where`` (the store folder)."""
    try:
        yield
    except DiskFullError:
        raise
    except Exception as exc:
        if not is_disk_full(exc):
            raise
        raise DiskFullError(
            f"no space left on the disk of {where} while writing {what}; the run stopped. "
            "Free some space (or pass --store on a bigger disk) and run the same command "
            "again: finished stages are kept") from None
