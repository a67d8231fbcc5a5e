"""Conformance checks for agents (filled in by the agent issue)."""

from typing import Any


def check_agent(plugin: Any, **kwargs: Any) -> None:
    raise NotImplementedError("check_agent is not written yet")
