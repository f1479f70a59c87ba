"""A subscriber's inbox on an output port (private; used by the gRPC servicer, the ipc
reader and the in-process subscription; no gRPC here).

The inbox *is* the connection's storage: the output port writes each sample straight
into a policy-shaped :class:`~dataflow.remote._delivery.Mailbox` (the core's own storage
for that policy), tagged on the way in as ``(sequence, source_time_ns, value)``, so the
sequence number and the timestamp always belong to the sample they travel with. The
sequence number is the port's own write number (:meth:`OutputPort.last_sample`, set just
before the port writes to its connections; kept increasing when several threads write
at once), the same for every subscriber: a jump tells a subscriber how many writes it
did not get. A slow subscriber never fails the writer's ``write``: its inbox drops. One storage, one place that counts
drops (full BUFFER, overwritten DATA/CIRCULAR sample, the consumer's byte budget);
samples the consumer discards itself (e.g. too large to send) are added with
:meth:`count_dropped`. The port's data callbacks on :attr:`inp` then run in the writer's
thread (cheap: an ``Event.set``), and never block on the subscriber.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

from dataflow.buffers import Storage
from dataflow.policy import BufferPolicy, ConnPolicy, FlowStatus
from dataflow.ports import InputPort, OutputPort
from dataflow.remote._delivery import Mailbox

__all__ = ["Inbox"]

log = logging.getLogger(__name__)

Tagged = tuple[int, int, Any]  # (sequence, source_time_ns, value)
_NEW = FlowStatus.NEW_DATA
_time_ns = time.time_ns


class _Tagging(Storage):
    """The connection's storage: each sample written is tagged and kept in ``box``.

    Never fails the writer: a full inbox drops (counted) and still answers True, and an
    error of the consumer's ``admit`` is logged, never raised. Sequence numbers only go
    up: with several writers at once a port's newest number may be one a later writer
    took (the sample it travels with is then one write off; nothing is lost or repeated).
    """

    __slots__ = ("_admit", "_last", "_lock", "_port", "_warned", "box")

    def __init__(self, policy: ConnPolicy, port: OutputPort, admit: Any) -> None:
        super().__init__(policy)
        self.box: Mailbox[Tagged] = Mailbox(policy)
        self._port = port
        self._admit = admit
        self._lock = threading.Lock()
        self._last = 0
        self._warned = False

    @property
    def dropped(self) -> int:
        return self.box.dropped

    def write(self, value: Any) -> bool:  # the writer's thread: never raises, never blocks for long
        try:
            self._admit(value)
        except Exception:  # noqa: BLE001 - a subscriber's trouble must never reach the writer
            if not self._warned:
                self._warned = True
                log.exception("subscriber inbox of %s: measuring a sample failed", self._port.qualname)
        with self._lock:  # one number per sample, increasing, whatever the writers' order
            number = max(self._port._sample[0], self._last + 1)  # this write's number
            self._last = number
            return self.box.put((number, _time_ns(), value))  # refused: counted; never a failed write (not mandatory)

    def read(self) -> tuple[FlowStatus, Any]:
        item = self.box.get(0.0)
        return (_NEW, item) if item is not None else (FlowStatus.NO_DATA, None)

    def clear(self) -> None:
        self.box.clear()

    def size(self) -> int:
        return len(self.box)


class Inbox:
    """Samples of ``port`` tagged on arrival; :meth:`take` drains them (non-blocking)."""

    def __init__(self, port: OutputPort, policy: ConnPolicy, name: str) -> None:
        self.port = port
        self.policy = policy
        self.wake = threading.Event()
        self._lock = threading.Lock()
        self._discarded = 0
        # the inbox belongs to this subscriber alone, and never fails the writer's write
        own = policy.with_(buffer_policy=BufferPolicy.PER_CONNECTION, mandatory=False)
        self._storage = _Tagging(own, port, self._admit)
        self.inp: InputPort = InputPort(port.type, name=name)
        self.inp.add_data_callback(self._on_data)
        self.connection = port.connect_to(self.inp, own, storage=self._storage)
        if self._storage.size():
            self.wake.set()  # an init=True policy handed a sample over already

    def _on_data(self, _inp: InputPort) -> None:  # the writer's thread, after the sample was kept
        self.wake.set()

    def _admit(self, value: Any) -> None:
        """Called with each sample before it is kept (in the writer's thread); a subclass
        may bound the inbox here (:meth:`limit`). Default: nothing."""

    def limit(self, samples: int) -> None:
        """Keep at most ``samples`` pending (within the policy's own size)."""
        self._storage.box.limit(samples)

    @property
    def pending(self) -> int:
        """Samples kept, not taken yet."""
        return len(self._storage.box)

    @property
    def dropped(self) -> int:
        """Samples lost: by the policy-shaped inbox (its byte budget too), or discarded by the consumer."""
        return self._storage.dropped + self._discarded

    def count_dropped(self, n: int = 1) -> None:
        """Count ``n`` samples the consumer had to discard."""
        with self._lock:
            self._discarded += n

    def take(self, limit: int = 10_000) -> list[Tagged]:
        """Every pending sample, oldest first (at most ``limit``; non-blocking)."""
        out: list[Tagged] = []
        box = self._storage.box
        for _ in range(limit):
            item = box.get(0.0)
            if item is None:
                break
            out.append(item)
        return out

    def close(self) -> None:
        """Disconnect from the output port (idempotent)."""
        self.port.disconnect(self.inp)
        self.inp.remove_data_callback(self._on_data)
        self._storage.box.close()
