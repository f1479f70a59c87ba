"""A subscriber's inbox on an output port (private; used by the gRPC servicer and the
in-process subscription; no gRPC here).

A free-standing InputPort with the subscriber's policy is connected to the output port.
Its data callback runs in the writer's thread right after a sample was stored: it takes
the sample out at once and keeps it as ``(sequence, source_time_ns, value)`` in a
policy-shaped :class:`~dataflow.remote._delivery.Mailbox`, so the sequence number and the
timestamp always belong to the sample they travel with. The sequence number is the
port's own write number (:meth:`OutputPort.last_sample`), the same for every subscriber:
a jump tells a subscriber exactly how many writes it did not get. The callback is cheap (a read, a
short lock, an ``Event.set``) and never blocks on the subscriber. Drops (full BUFFER,
overwritten DATA/CIRCULAR sample) are counted by the mailbox; samples the consumer
discards itself (e.g. too large to send) are added with :meth:`count_dropped`.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from dataflow.policy import ConnPolicy, FlowStatus
from dataflow.ports import InputPort, OutputPort
from dataflow.remote._delivery import Mailbox

__all__ = ["Inbox"]

Tagged = tuple[int, int, Any]  # (sequence, source_time_ns, value)


class Inbox:
    """Samples of ``port`` tagged on arrival; :meth:`take` drains them (non-blocking)."""

    def __init__(self, port: OutputPort, policy: ConnPolicy, name: str) -> None:
        self.port = port
        self.policy = policy
        self.wake = threading.Event()
        self._lock = threading.Lock()
        self._mailbox: Mailbox[Tagged] = Mailbox(policy)
        self._seq = 0
        self._discarded = 0
        self.inp: InputPort = InputPort(port.type, name=name)
        self.inp.add_data_callback(self._on_data)
        self.connection = port.connect_to(self.inp, policy)
        self._on_data(self.inp)  # an init=True policy may have handed a sample over already

    def _on_data(self, _inp: InputPort) -> None:  # writer's thread: cheap, never blocks for long
        with self._lock:  # one reader of self.inp at a time (several writers may call us)
            values = []
            for _ in range(10_000):  # bounded: the connection holds at most its size
                status, value = self.inp.read()
                if status is not FlowStatus.NEW_DATA:
                    break
                values.append(value)
            if not values:
                return
            # called right after each write: the newest value read is the port's latest write
            newest = max(self.port.last_sample()[0], self._seq + len(values))
            now = time.time_ns()
            for k, value in enumerate(values):
                self._admit(value)
                self._mailbox.put((newest - len(values) + 1 + k, now, value))
            self._seq = newest
        self.wake.set()

    def _admit(self, value: Any) -> None:
        """Called with each sample before it is kept (under the inbox's lock); a subclass
        may bound the inbox here (:meth:`limit`). Default: nothing."""

    def limit(self, samples: int) -> None:
        """Keep at most ``samples`` pending (within the policy's own size)."""
        self._mailbox.limit(samples)

    @property
    def dropped(self) -> int:
        """Samples lost: by the connection, by the policy-shaped inbox, or discarded by the consumer."""
        return self.connection.dropped + self._mailbox.dropped + self._discarded

    def count_dropped(self, n: int = 1) -> None:
        """Count ``n`` samples the consumer had to discard."""
        with self._lock:
            self._discarded += n

    def take(self, limit: int = 10_000) -> list[Tagged]:
        """Every pending sample, oldest first (at most ``limit``; non-blocking)."""
        out: list[Tagged] = []
        for _ in range(limit):
            item = self._mailbox.get(0.0)
            if item is None:
                break
            out.append(item)
        return out

    def close(self) -> None:
        """Disconnect from the output port (idempotent)."""
        self.port.disconnect(self.inp)
        self.inp.remove_data_callback(self._on_data)
        self._mailbox.close()
