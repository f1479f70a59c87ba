"""``scart play``'s data plane: a recorded sample of an array or ``bytes`` port (a camera's
frame) is written through a link of play's own, not through the control plane, whose
messages hold 4 MiB (a 1080p RGB frame is 8.3 MB of JSON in the file, 6.2 MB as a value).

:class:`PlayLink` is what a link between two deployers is at its source
(:class:`~dataflow.remote._links.RemoteLink`), with play's process as the source: an output
port of a player task of its own (never served, never in the name service), linked to the
input port under :data:`POLICY` over ``auto`` (shm on one host, else ipc, else gRPC in
parts). What the sink's buffer refuses is counted, and :meth:`PlayLink.close` delivers
what waits before it undoes the link.
"""

from __future__ import annotations

import os
import secrets
from typing import TYPE_CHECKING, Protocol

from dataflow.errors import DataflowError
from dataflow.policy import ConnPolicy
from dataflow.ports import OutputPort
from dataflow.task import TaskContext
from scart_wire import rosmsgs
from scart_wire.arrays import array_spec
from scart_wire.types import registry

if TYPE_CHECKING:
    from scart_wire.security import Security

__all__ = ["POLICY", "PlayLink", "on_data_plane"]

#: The link's policy: each sample kept until the task reads it (a full buffer refuses, counted).
POLICY = ConnPolicy.buffer(8)
SETTLE_S = 5.0  #: how long the first connection may take


def on_data_plane(type_name: str) -> bool:
    """Whether samples of a port of ``type_name`` go through a :class:`PlayLink`: arrays,
    ``bytes`` and rosbags' messages, the types of large samples (images, clouds)."""
    return type_name == "bytes" or array_spec(type_name) is not None or type_name.startswith(rosmsgs.PREFIX)


class NameSource(Protocol):
    """The system proxy a link's source reaches the name service through (a GrpcSystem)."""

    @property
    def security(self) -> Security: ...
    @property
    def timeout(self) -> float: ...
    @property
    def address(self) -> str: ...
    def resolve(self, component: str, fresh: bool = False) -> str: ...


class _Source:
    """What a link asks of its source's deployer, from play's process: an id of its own, the
    system proxy's name service, security and deadline."""

    def __init__(self, system: NameSource) -> None:
        self.boot_id = secrets.token_hex(8)
        self.security = system.security
        self.ns_timeout = float(system.timeout)
        self.ns_address = str(system.address)
        self._system = system

    def resolve(self, component: str) -> str:
        return str(self._system.resolve(component, fresh=True))


class PlayLink:
    """A link from play's process to input port ``task.port`` of ``type_name``: made at
    once (raises :class:`DataflowError` saying why when it does not connect within
    :data:`SETTLE_S`), :meth:`write` from play's thread, :meth:`close` once."""

    def __init__(self, system: NameSource, task: str, port: str, type_name: str, serial: int) -> None:
        from dataflow.remote._links import RemoteLink

        self.type_name = type_name
        self._type = registry.python_type(type_name) or bytes
        player = type("Player", (TaskContext,), {"out": OutputPort(self._type, doc="what play writes")})
        self._out = player(f"scart_play_{os.getpid()}_{serial}").port("out")
        self._link = RemoteLink(_Source(system), self._out, task, port, POLICY, f"play->{task}.{port}", serial)
        self._link.settled.wait(SETTLE_S)
        if not self._link.end.transport:
            why = self._link.refusal or self._link.detail
            self._link.close(graceful=False)
            raise DataflowError(f"no link to {task}.{port} for its samples ({type_name}): {why}")

    @property
    def transport(self) -> str:
        """The transport the link took (``shm``, ``ipc``, ``grpc``)."""
        return self._link.end.transport or ""

    def write(self, json_value: object) -> str:
        """Write one recorded sample (its JSON form: converted to the port's type here, as
        the task's side would); returns the write status's name. Raises ``PortTypeError``
        (or ``ValueError``) for a value that is not of the port's type."""
        return self._out.write(registry.from_jsonable(self._type, json_value)).name

    def close(self) -> int:
        """Deliver what waits (a moment at most), undo the link; returns the samples
        written that the sink did not take (its buffer full, or not delivered)."""
        return self._link.close(graceful=True)
