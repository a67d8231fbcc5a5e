"""Built-in task plugins for repbench (installed as ``repbench_tasks``)."""

from repbench_tasks._quiet import quiet_robosuite_import_warnings

quiet_robosuite_import_warnings()
