"""The reader ends of the links coming into one deployer (its sink side), whatever
transport carries them (private to the transports and the deployer's server).

A link keeps one :class:`IncomingLink` for as long as it exists, across reconnections
of its channel (same channel id): its reader end keeps counting, and its buffer — a
:class:`~dataflow.ports.ChannelConnection` on the input port — keeps what it holds. A
channel the sink does not know (a first connection, or this deployer restarted) counts
from the source's ``after``. When the source closes the link, the sink first lets the
task read what the buffer still holds (at most :data:`LINGER_S`), then reports and
detaches: what was never read is counted, not silently lost.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

from scart_wire import codec
from dataflow.errors import DataflowError
from dataflow.policy import ConnPolicy
from dataflow.ports import InputPort, Port
from dataflow.buffers import WaitingStorage
from dataflow.transports.ends import ReaderEnd
from dataflow.transports.flow import waits
from scart_wire.types import registry

if TYPE_CHECKING:
    from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb

__all__ = ["IncomingLink", "LINGER_S", "REPORT_EVERY", "REPORT_S", "Refused", "Sinks", "port_check"]

log = logging.getLogger(__name__)

LINGER_S = 1.0  #: how long a closing link's buffer may wait for its task to read it
REPORT_EVERY = 64  #: samples between two reports of a link's reader end to its source, at most ...
REPORT_S = 0.1  #: ... or this many seconds, when something changed (on every transport)
MAX_CHANNELS = 4096  #: incoming links one deployer keeps, at most
T = TypeVar("T")


class Refused(DataflowError):
    """The sink refuses a link (no such input port, another type, out of room)."""


def port_check(port: InputPort[T], nan_ok: bool = False) -> Callable[[object], T]:
    """The one check of a sample from outside into ``port``: decode (a ``Value``; a
    transport that converts types gives a Python value), the port's type, its bounds
    (``nan_ok``: NaN and inf are legal where the sample comes from, ROS, so only a port
    that asked for ``finite=True`` refuses them). Raises what refuses the sample."""
    py_type = port.type
    admit = port.admit
    plain = not (isinstance(py_type, type) and issubclass(py_type, (codec.Value, codec.Payload)))

    def check(msg: object) -> T:
        if plain and type(msg) is py_type:  # a converting transport's value, of the port's type: the hot case
            return admit(msg, nan_ok)
        value = codec.decode(msg) if isinstance(msg, (codec.Value, codec.Payload)) else msg  # else a converting
        # transport's value
        if type(value) is not py_type:
            value = registry.validate(py_type, value)
        return admit(value, nan_ok)

    return check


class IncomingLink:
    """One link's reader end at its sink (see the module docstring)."""

    def __init__(self, channel: str, port: InputPort[Any], policy: ConnPolicy, after: int, source: str,
                 name: str, boot_id: str, source_ns: str) -> None:
        self.channel = channel
        self.port = port
        self.policy = policy
        self.source = source
        self.name = name
        self.boot_id = boot_id
        self.source_ns = source_ns
        self.carriers = 0  #: transports carrying it now
        self.seen = time.monotonic()
        self.closed = False  #: detached from its port (undone, or this deployer stops): reports what it holds
        self._after_close = 0  # samples that came once closed: dropped, counted
        self.connection = port.open_channel(policy, peer=source)
        conn = self.connection
        #: Called (in the reader's thread) when a read frees room in the buffer of a link
        #: whose writer waits: its transport reports at once (see :mod:`.flow`).
        self.on_room: Callable[[], None] | None = None
        self.waits = waits(policy)
        if isinstance(conn.storage, WaitingStorage):
            conn.storage.on_room(self._room)
        self.end = ReaderEnd(f"link {name or source} into {port.qualname}", port_check(port),
                             self._store, lambda: conn.dropped + self._after_close, after=after)
        self.end.writer(boot_id)

    def _room(self) -> None:
        on_room = self.on_room
        if on_room is not None:
            on_room()

    def _store(self, n: int, t_ns: int, value: object) -> bool:
        if self.closed:
            self._after_close += 1
            return False
        return self.connection.store(n, t_ns, value)

    @property
    def pending(self) -> int:
        """Samples in the buffer, not read yet."""
        return self.connection.storage.size()

    def linger(self, deadline: float, stop: threading.Event | None = None) -> None:
        """Wait (polling, bounded by ``deadline``) until the task has read the buffer."""
        while self.pending and time.monotonic() < deadline:
            if stop is not None and stop.wait(0.01):
                return
            if stop is None:
                time.sleep(0.01)

    def close(self) -> None:
        """Detach from the port: what the buffer still holds is counted as dropped, and so
        is what comes later (idempotent)."""
        self.closed = True
        self.connection.close()


class Sinks:
    """The incoming links of one deployer, by channel id. ``port_of(task, port)`` finds an
    input port (raising :class:`~dataflow.errors.DataflowError` when there is none).
    Thread-safe."""

    def __init__(self, port_of: Callable[[str, str], Port[Any]]) -> None:
        self._port_of = port_of
        self._lock = threading.Lock()
        self._links: dict[str, IncomingLink] = {}

    def open(self, hello: pb.LinkHello, policy: ConnPolicy) -> tuple[IncomingLink, bool]:
        """The reader end for a channel opening (``hello``: a ``LinkHello``) and whether
        it was known already. Raises :class:`Refused` saying why not."""
        where = f"{hello.task}.{hello.port}"
        try:
            port = self._port_of(hello.task, hello.port)
        except DataflowError as exc:
            raise Refused(str(exc)) from None
        if not isinstance(port, InputPort):
            raise Refused(f"{where} is an output port; a link's sink must be an input port")
        if hello.type_name and hello.type_name != port.type_name:
            raise Refused(f"cannot connect {hello.source} ({hello.type_name}) to {where} ({port.type_name}): "
                          "types differ")
        with self._lock:
            found = self._links.get(hello.channel)
            if found is not None and found.port is port:
                found.carriers += 1
                found.seen = time.monotonic()
                return found, True
            if len(self._links) >= MAX_CHANNELS:
                raise Refused(f"this deployer keeps at most {MAX_CHANNELS} incoming links")
            link = IncomingLink(hello.channel, port, policy, hello.after, hello.source, hello.name, hello.boot_id,
                                hello.source_ns)
            link.carriers = 1
            self._links[hello.channel] = link
        if found is not None:  # rerouted to another port under the same channel: the old buffer goes
            found.close()
        return link, False

    def carried(self, link: IncomingLink) -> None:
        """A transport stopped carrying ``link`` (it stays, waiting for its source)."""
        with self._lock:
            link.carriers = max(0, link.carriers - 1)
            link.seen = time.monotonic()

    def finish(self, link: IncomingLink) -> None:
        """The source closed ``link``: forget it and detach its buffer."""
        with self._lock:
            if self._links.get(link.channel) is link:
                del self._links[link.channel]
        link.close()

    def links(self) -> list[IncomingLink]:
        """Every incoming link (connected or waiting for its source)."""
        with self._lock:
            return list(self._links.values())

    def close_all(self) -> None:
        """Forget every incoming link (the deployer stops)."""
        with self._lock:
            links = list(self._links.values())
            self._links.clear()
        for link in links:
            link.close()
