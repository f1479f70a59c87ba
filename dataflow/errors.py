"""The dataflow error tree: one base, one class per kind of setup failure.

Hot paths (``write``/``read``) return statuses and never raise for ordinary
conditions; setup paths (connect, deploy, set a property) raise these, with a
message that names where (``task.port``), what is wrong and what would be valid.

The classes are defined in :mod:`scart_wire.errors` (the type registry and the codec,
which both worlds share, raise them) and are the same objects here.
"""

from __future__ import annotations

from scart_wire.errors import (
    DataflowError,
    DeploymentError,
    NotFoundError,
    PortTypeError,
    PortValueError,
    PropertyValueError,
)

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
