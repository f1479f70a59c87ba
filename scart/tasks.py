"""Data-flow tasks inside a composite: ``implementation.task`` and ``scart:connect``.

The public face of :mod:`scart.bindings._dataflow_tasks` (see its docstring for the XML
forms, the lifecycle and the static checks); the runtime registers both kinds itself, so
importing this module is only needed to use the names below.
"""

from __future__ import annotations

from scart.bindings._dataflow_host import DataflowHost, host_of
from scart.bindings._dataflow_tasks import (
    ConnectExtension,
    ConnectParticipant,
    Link,
    TaskImplementation,
    TaskManager,
    ensure_registered,
    task_interface,
)

__all__ = [
    "ConnectExtension", "ConnectParticipant", "DataflowHost", "Link", "TaskImplementation", "TaskManager",
    "ensure_registered", "host_of", "task_interface",
]
