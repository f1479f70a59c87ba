"""Streams: a port joined to a named topic of a transport (RTT's ``ConnPolicy.name_id``
and the deployer's ``stream()``), kept by the :class:`~dataflow.Deployer` with its links
(:meth:`dataflow.Deployer.stream`; ``scart stream``; ``<scart:stream>``)."""

from __future__ import annotations

import re
from typing import Any

from dataflow.introspection import LinkDescription
from dataflow.policy import ConnPolicy
from dataflow.transports import load
from dataflow.transports.ends import ReaderEnd, WriterEnd, attach, detach
from dataflow.transports.sinks import port_check

__all__ = ["PortStream", "STREAM_NAME", "default_name"]

#: What a stream's name may be (its default, ``task.port~transport:topic``, included).
STREAM_NAME = re.compile(r"[A-Za-z0-9_./:~>-]{1,300}")


def default_name(port: str, policy: ConnPolicy) -> str:
    """``task.port~transport:topic`` (a character a name may not hold becomes ``_``)."""
    return re.sub(r"[^A-Za-z0-9_./:~>-]", "_", f"{port}~{policy.transport}:{policy.topic}")[:300]


class PortStream:
    """A port of this deployer joined to a topic of a transport (a stream, RTT's
    ``ConnPolicy.name_id``): an output port's writer end publishes, an input port's reader
    end receives (its buffer feeding the port). Listed with the links."""

    def __init__(self, port: Any, policy: ConnPolicy, options: dict[str, str], name: str) -> None:
        self.port = port
        self.policy = policy
        self.options = dict(options)
        self.name = name
        self.transport = load(policy.transport)
        self.topic = policy.topic
        self.writer: WriterEnd | None = None
        self.reader: ReaderEnd | None = None
        self._connection: Any = None
        label = f"stream {name}"
        if port.is_input:
            self._connection = conn = port.open_channel(policy, peer=f"{policy.transport}:{policy.topic}")
            self.reader = ReaderEnd(label, port_check(port), lambda _n, _t, value: conn.write(value),
                                    lambda: conn.dropped, port=port, policy=policy)
            end: Any = self.reader
        else:
            self.writer = end = WriterEnd(port, policy, label)
            attach(port, self.writer)
        try:
            self._stream = self.transport.stream(end, policy.topic, self.options)
        except BaseException:
            self._undo()
            raise

    def describe(self) -> LinkDescription:
        where = f"{self.policy.transport}:{self.topic}"
        source, sink = (where, self.port.qualname) if self.port.is_input else (self.port.qualname, where)
        if self.writer is not None:
            dropped, samples, transport = self.writer.dropped, self.port.last_sample()[0], self.writer.transport
        else:
            assert self.reader is not None
            dropped, samples, transport = self.reader.lost, self.reader.received, self.reader.transport
        words = [f"{k}={v}" for k, v in sorted(self.options.items())]
        if not self.transport.authenticated and self.reader is not None:
            words.append("unauthenticated")  # anyone who reaches the topic writes into the port
        status = self._stream.status()
        detail = " ".join(words + ([status] if status else []))
        return LinkDescription(name=self.name, source=source, sink=sink, policy=str(self.policy),
                               transport=transport or f"{self.policy.transport}?", samples=samples, dropped=dropped,
                               kind="stream", state="connected" if transport else "waiting", detail=detail)

    def _undo(self) -> None:
        if self.writer is not None:
            detach(self.port, self.writer)
            self.writer.disconnected()
        if self._connection is not None:
            self._connection.close()

    def close(self) -> None:
        """Leave the topic (idempotent)."""
        self._stream.close()
        self._undo()
