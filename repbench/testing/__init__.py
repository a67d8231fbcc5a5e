"""The public conformance kit: run the same checks on your plugin that repbench runs on its own.

``check_task``, ``check_encoder``, ``check_metric`` and ``check_agent`` each take a registered
name or an instance/function and raise ``AssertionError`` with a message on the first failure.
"""

from repbench.testing.agent import check_agent
from repbench.testing.encoder import check_encoder
from repbench.testing.metric import check_metric
from repbench.testing.task import check_task

__all__ = ["check_agent", "check_encoder", "check_metric", "check_task"]
