"""The writer ends a deployer serves to subscribers in other processes (private to the
transports and the deployer's server): one per subscription, whatever carries it."""

from __future__ import annotations

import itertools
import threading
from typing import Any, TypedDict

from dataflow.policy import ConnPolicy
from dataflow.ports import OutputPort
from dataflow.transports.ends import WriterEnd, attach, detach

__all__ = ["BYTE_BUDGET", "Served", "ServedInfo", "ServedSet"]

BYTE_BUDGET = 4 * 1024 * 1024  #: encoded bytes a subscription may have waiting on the deployer's side, at most


class ServedInfo(TypedDict):
    """What listings show of one subscription (:meth:`ServedSet.info`)."""

    id: int
    source: str
    subscriber: str
    policy: str
    transport: str
    samples: int
    dropped: int


class Served:
    """An output port's samples going to one subscriber: a writer end attached to the
    port. It never fails the writer's ``write`` (a subscriber is never mandatory); what it
    could not send is counted (:attr:`dropped`), and the subscriber counts the rest from
    the write numbers."""

    def __init__(self, port: OutputPort[Any], policy: ConnPolicy, serial: int, subscriber: str, transport: str) -> None:
        self.port = port
        self.policy = policy
        self.serial = serial
        self.subscriber = subscriber
        self.transport = transport
        self.end = WriterEnd(port, policy.with_(mandatory=False), f"subscription {serial} of {port.qualname}",
                             reports=False, byte_budget=BYTE_BUDGET)
        attach(port, self.end)

    @property
    def dropped(self) -> int:
        """Samples this side could not send to the subscriber."""
        return self.end.unsent

    @property
    def tail(self) -> int:
        """Samples not sent since the last one sent (its heartbeats tell the subscriber)."""
        return self.end.tail

    def close(self) -> None:
        """Stop serving (idempotent)."""
        detach(self.port, self.end)
        self.end.disconnected()


class ServedSet:
    """The subscriptions one deployer serves, numbered, whatever carries them. A transport
    bounds its own with ``limit`` (gRPC's: a server worker each; ipc's connections are
    bounded by its socket's own limit)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._serials = itertools.count(1)
        self._served: dict[int, Served] = {}

    def open(self, port: OutputPort[Any], policy: ConnPolicy, subscriber: str, transport: str,
             limit: int | None = None) -> Served:
        """A new subscription of ``port`` carried by ``transport``, of which there may be at
        most ``limit`` (None: no bound here); ``OverflowError`` naming the limit past it."""
        with self._lock:
            if limit is not None and sum(1 for s in self._served.values() if s.transport == transport) >= limit:
                raise OverflowError(f"this deployer serves at most {limit} subscriptions over {transport}")
            served = Served(port, policy, next(self._serials), subscriber, transport)
            self._served[served.serial] = served
            return served

    def close(self, served: Served) -> None:
        with self._lock:
            self._served.pop(served.serial, None)
        served.close()

    def all(self) -> list[Served]:
        with self._lock:
            return sorted(self._served.values(), key=lambda s: s.serial)

    def close_all(self) -> None:
        with self._lock:
            served = list(self._served.values())
            self._served.clear()
        for item in served:
            item.close()

    def __len__(self) -> int:
        return len(self._served)

    def info(self) -> list[ServedInfo]:
        """What listings show of each subscription."""
        return [ServedInfo(id=s.serial, source=s.port.qualname, subscriber=s.subscriber[:300], policy=str(s.policy),
                     transport=s.transport, samples=s.port.last_sample()[0], dropped=s.dropped) for s in self.all()]
