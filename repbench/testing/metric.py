"""Conformance checks for metrics (filled in by the metric issue)."""

from typing import Any


def check_metric(plugin: Any, **kwargs: Any) -> None:
    raise NotImplementedError("check_metric is not written yet")
