"""Streams: a port joined to a named topic of a transport (RTT's ``ConnPolicy.name_id``
and the deployer's ``stream()``), kept by the :class:`~dataflow.Deployer` with its links
(:meth:`dataflow.Deployer.stream`; ``scart stream``; ``<scart:stream>``)."""

from __future__ import annotations

import re
import threading
from typing import Any

from dataflow.errors import DeploymentError
from dataflow.introspection import LinkDescription, PortStreamDescription
from dataflow.policy import ConnPolicy
from dataflow.ports import ChannelConnection, InputPort, OutputPort, Port
from dataflow.transports import load
from dataflow.transports.ends import ReaderEnd, WriterEnd, attach, detach
from dataflow.transports.limits import check_fits
from dataflow.transports.sinks import port_check

__all__ = ["PortStream", "STREAM_NAME", "default_name"]

#: What a stream's name may be (its default, ``task.port~transport:topic``, included).
STREAM_NAME = re.compile(r"[A-Za-z0-9_./:~>-]{1,300}")
_ports_lock = threading.Lock()  # a port's streams tuple is replaced, never changed in place


def default_name(port: str, policy: ConnPolicy) -> str:
    """``task.port~transport:topic`` (a character a name may not hold becomes ``_``)."""
    return re.sub(r"[^A-Za-z0-9_./:~>-]", "_", f"{port}~{policy.transport}:{policy.topic}")[:300]


class PortStream:
    """A port of this deployer joined to a topic of a transport (a stream, RTT's
    ``ConnPolicy.name_id``): an output port's writer end publishes, an input port's reader
    end receives (its buffer feeding the port). Listed with the links."""

    def __init__(self, port: Port[Any], policy: ConnPolicy, options: dict[str, str], name: str) -> None:
        self.port = port
        self.policy = policy
        self.options = dict(options)
        self.name = name
        check_fits(port, f"stream {name}")
        self.transport = load(policy.transport)
        self.topic = policy.topic
        self.writer: WriterEnd[Any] | None = None
        self.reader: ReaderEnd[Any] | None = None
        self._connection: ChannelConnection[Any] | None = None
        label = f"stream {name}"
        end: WriterEnd[Any] | ReaderEnd[Any]
        if isinstance(port, InputPort):
            self._connection = conn = port.open_channel(policy, peer=f"{policy.transport}:{policy.topic}")
            self.reader = end = ReaderEnd(label, port_check(port, nan_ok=self.transport.converts), conn.store,
                                          lambda: conn.dropped, port=port, policy=policy)
            self.reader.storage = conn.storage
        elif isinstance(port, OutputPort):
            self.writer = end = WriterEnd(port, policy, label)
            attach(port, self.writer)
        else:
            raise DeploymentError(f"{port.qualname}: a stream joins an input or an output port")
        try:
            self._stream = self.transport.stream(end, policy.topic, self.options)
        except BaseException:
            self._undo()
            raise
        with _ports_lock:
            port.streams = (*port.streams, self)

    @property
    def where(self) -> str:
        """``transport:topic``."""
        return f"{self.policy.transport}:{self.topic}"

    def _state(self) -> tuple[str, str]:
        """``(transport now, or "" while waiting; what it waits for)``."""
        end = self.writer if self.writer is not None else self.reader
        assert end is not None
        waiting = self._stream.waiting
        return ("" if waiting else end.transport), waiting

    def describe(self) -> LinkDescription:
        source, sink = (self.where, self.port.qualname) if self.port.is_input else (self.port.qualname, self.where)
        refused = self._stream.refused
        if self.writer is not None:
            dropped, samples = self.writer.dropped + refused, self.writer.port.last_sample()[0]
        else:
            assert self.reader is not None
            dropped, samples = self.reader.lost + refused, self.reader.received
        transport, waiting = self._state()
        detail = " ".join([f"{k}={v}" for k, v in sorted(self.options.items())] +
                          ([f"(waiting for {waiting})"] if waiting else []))
        return LinkDescription(name=self.name, source=source, sink=sink, policy=str(self.policy),
                               transport=transport or f"{self.policy.transport}?", samples=samples, dropped=dropped,
                               kind="stream", state="connected" if transport else "waiting", detail=detail)

    def note(self) -> PortStreamDescription:
        """What ``scart describe`` shows of it under its port."""
        stream = self._stream
        refused, refusal = stream.refused, stream.refusal
        if self.reader is not None:
            refused += self.reader.refused
            refusal = self.reader.refusal or refusal
        return PortStreamDescription(name=self.name, topic=self.where, type_name=stream.type_name,
                                     state="connected" if self._state()[0] else "waiting", refused=refused,
                                     refusal=refusal,
                                     unauthenticated=self.reader is not None and stream.authenticated is False)

    def _undo(self) -> None:
        with _ports_lock:
            self.port.streams = tuple(s for s in self.port.streams if s is not self)
        if self.writer is not None:
            detach(self.writer.port, self.writer)
            self.writer.disconnected()
        if self._connection is not None:
            self._connection.close()

    def close(self) -> None:
        """Leave the topic (idempotent)."""
        self._stream.close()
        self._undo()
