"""repbench: which learned state representation is good for control, and which representation
metric predicts reinforcement-learning performance.

Public API:

* :class:`Encoder`, :class:`Task`, :class:`Agent` — base classes of plugins;
* :func:`metric` and :class:`MetricResult` — write a metric;
* ``repbench.encoders``, ``repbench.tasks``, ``repbench.agents`` — registries
  (metrics: ``repbench.registry.metrics``);
* :class:`Dataset`, :class:`Store`, :func:`load_suite`.
"""

from repbench._rendering import configure_headless_rendering

configure_headless_rendering()  # must run before anything imports mujoco

from repbench.agent import Agent, AgentResult  # noqa: E402
from repbench.dataset import Dataset  # noqa: E402
from repbench.encoder import Encoder  # noqa: E402
from repbench.errors import RepbenchError  # noqa: E402
from repbench.gym_envs import register_gym_envs  # noqa: E402
from repbench.metric import Metric, MetricResult, metric  # noqa: E402
from repbench.pipeline.store import Store  # noqa: E402
from repbench.pipeline.suite import Suite, load_suite  # noqa: E402
from repbench.registry import agents, encoders, tasks  # noqa: E402
from repbench.task import Task  # noqa: E402

register_gym_envs()  # gymnasium.make("repbench/PegInHole-v0") after `import repbench`

from repbench import _moved  # noqa: E402

_moved.install()  # repbench.store etc. moved into pipeline/, analysis/, report/

__version__ = "0.1.0"

__all__ = [
    "Agent", "AgentResult", "Dataset", "Encoder", "Metric", "MetricResult", "RepbenchError",
    "Store", "Suite", "Task", "__version__", "agents", "encoders", "load_suite", "metric", "tasks",
]
