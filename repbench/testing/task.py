"""Conformance checks for tasks (filled in by the task issue)."""

from typing import Any


def check_task(plugin: Any, **kwargs: Any) -> None:
    raise NotImplementedError("check_task is not written yet")
