"""Drop robosuite's known-harmless import-time warnings (nothing else).

robosuite 1.5.2 warns at every import that no private macro file exists, that the optional
``robosuite_models`` package is missing and that mink's whole-body IK (for the GR1 humanoid) is
unavailable. None applies to repbench's tasks; in a process pool they repeat once per worker and
bury real messages. Any other robosuite warning still shows.
"""

from __future__ import annotations

import logging

_HARMLESS = ("private macro file", "setup_macros.py", "robosuite_models",
             "mink-based whole-body IK")


class _HarmlessRobosuiteWarnings(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        return not any(text in message for text in _HARMLESS)


def quiet_robosuite_import_warnings() -> None:
    """Install the filter on robosuite's logger (idempotent; call before importing robosuite)."""
    logger = logging.getLogger("robosuite_logs")
    if not any(isinstance(f, _HarmlessRobosuiteWarnings) for f in logger.filters):
        logger.addFilter(_HarmlessRobosuiteWarnings())
