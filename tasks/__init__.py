"""Built-in task plugins for repbench (installed as ``repbench_tasks``)."""
