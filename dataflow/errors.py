"""The dataflow error tree: one base, one class per kind of setup failure.

Hot paths (``write``/``read``) return statuses and never raise for ordinary
conditions; setup paths (connect, deploy, set a property) raise these, with a
message that names where (``task.port``), what is wrong and what would be valid.
"""

from __future__ import annotations

__all__ = [
    "CONNECT_DIRECTION",
    "CONNECT_TYPE",
    "DataflowError",
    "PortTypeError",
    "NotFoundError",
    "DeploymentError",
    "PropertyValueError",
    "PortValueError",
]


#: The codes a refused connection carries, the same for ``scart connect`` and a
#: composite's ``<scart:connect>``: ports of different types; an output used as a sink
#: (or an input as a source).
CONNECT_TYPE = "SCART-T003"
CONNECT_DIRECTION = "SCART-T002"


class DataflowError(Exception):
    """Base of every error raised by :mod:`dataflow`."""


class PortTypeError(DataflowError, TypeError):
    """A value or a connection does not match a port's (or property's) type."""


class NotFoundError(DataflowError, KeyError):
    """A task, port, property or operation name does not exist; the message lists what does."""

    def __str__(self) -> str:  # KeyError quotes its argument; keep the message readable
        return str(self.args[0]) if self.args else ""


class DeploymentError(DataflowError):
    """A deployment step failed (duplicate task name, a task refused to configure, ...)."""


class PropertyValueError(DataflowError, ValueError):
    """A property value has the right type but is outside what the property accepts."""


class PortValueError(DataflowError, ValueError):
    """A value written to an input port from outside has the right type but is outside the
    port's bounds (not finite, below or above its range)."""
