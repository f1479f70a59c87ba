"""The two ends of a channel, as the core keeps them (see :mod:`dataflow.transports` for
the vocabulary). No transport, no gRPC and no socket here: a transport attaches a
*carrier* to a :class:`WriterEnd` and feeds frames to a :class:`ReaderEnd`.

Counting, in one place each (RTT's rule: the connection owns the buffer and its count):

* every sample an output port writes while a writer end is attached has the port's
  **write number** ``n`` (1, 2, ... per process; a new process starts again at 1, with a
  new boot id);
* the reader end counts what it did not get from the jumps in ``n``
  (:class:`LossCount`), plus what it refused (wrong type, out of bounds) and what its
  policy-shaped buffer dropped; it reports these to the writer end (``report``);
* the writer end knows only what it could not send (not connected, or no room): those
  with a number above the reader's last report are the tail the reader cannot know yet.

So ``written = delivered + dropped`` holds on every transport: what was written and not
read by the sink is counted exactly once, wherever it was lost.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar, cast

from dataflow.policy import ConnPolicy, ConnType
from dataflow.transports.flow import WriterFlow, waits

if TYPE_CHECKING:
    from dataflow.buffers import Storage
    from dataflow.ports import InputPort, OutputPort
    from dataflow.transports.frames import Frame

__all__ = ["Carrier", "Fanout", "LossCount", "OutSample", "ReaderEnd", "WriterEnd", "attach", "detach"]

log = logging.getLogger(__name__)

_time_ns = time.time_ns
T = TypeVar("T")
T_co = TypeVar("T_co", covariant=True)
D = TypeVar("D")


class OutSample(Generic[T_co]):
    """One sample on its way out: the port's write number, when it was written (ns since
    the epoch), the value and the port's type. Each encoding of it is made once, however
    many ends send it (:meth:`encoded`)."""

    __slots__ = ("n", "t_ns", "value", "type", "inline", "_key", "_bytes")

    def __init__(self, n: int, t_ns: int, value: T_co, py_type: object) -> None:
        self.n = n
        self.t_ns = t_ns
        self.value = value
        self.type = py_type
        #: How many carriers sent it from the writer's own thread so far (a transport sends
        #: to the first few there and hands the rest to its own thread: the writer's cost
        #: then does not grow with its readers).
        self.inline = 0
        self._key: Callable[[OutSample[T_co]], object] | None = None
        self._bytes: Any = None  # what the last encoder made (each transport's own type)

    def encoded(self, encode: Callable[[OutSample[T_co]], D]) -> D:
        """``encode(self)``, computed once per encoder (the last one's result is kept:
        the ends of one port almost always share one encoder)."""
        if self._key is encode:
            return self._bytes
        data = encode(self)
        self._key, self._bytes = encode, data
        return data


class Carrier(Protocol[D]):
    """What a transport attaches to a :class:`WriterEnd` while it is connected; ``D`` is
    what a sample becomes for it (scart's frames: ``bytes``)."""

    def encode(self, sample: OutSample[object]) -> D:
        """How a sample is encoded for this transport (the same function for every
        carrier of a transport, so a sample is encoded once however many ends send it)."""

    def send(self, sample: OutSample[object], data: D) -> bool:
        """Send ``sample`` (``data``: :attr:`encode`'s result) now without blocking;
        False when there is no room (the end keeps it, as its policy says, until
        :meth:`WriterEnd.flush`). Called in the writer's thread, or in the transport's
        own from ``flush``; never by two threads at once."""

    # Optional: ``batch_bytes: int``, for a carrier whose encoded samples joined end to end
    # are one message holding them all (scart's frames): what waits for room then leaves
    # in messages of up to that many bytes, many samples each (``send`` gets the last one).


class Fanout(Generic[T]):
    """The writer ends of one output port: each write is handed to every end (in the
    writer's thread), encoded at most once per encoding. Attached to the port while it
    has ends (:func:`attach`, :func:`detach`)."""

    __slots__ = ("port", "ends")

    def __init__(self, port: OutputPort[T]) -> None:
        self.port = port
        self.ends: tuple[WriterEnd[T], ...] = ()

    def push(self, n: int, value: T) -> bool:
        """Offer sample ``n`` to every end; False when a mandatory end refused it."""
        sample = OutSample(n, _time_ns(), value, self.port.type)
        ends = self.ends
        if len(ends) == 1:  # the common case: one channel
            end = ends[0]
            return end.offer(sample) or not end.policy.mandatory
        ok = True
        for end in ends:
            if not end.offer(sample) and end.policy.mandatory:
                ok = False
        return ok


_attach_lock = threading.Lock()


def attach(port: OutputPort[T], end: WriterEnd[T]) -> None:
    """Make ``end`` receive every sample ``port`` writes from now on (setup path)."""
    with _attach_lock:
        fanout = port._fanout if port._fanout is not None else Fanout(port)
        fanout.ends = (*fanout.ends, end)
        if port._fanout is None:
            port.attach_fanout(fanout)


def detach(port: OutputPort[T], end: WriterEnd[T]) -> None:
    """Stop handing ``port``'s samples to ``end`` (idempotent, setup path)."""
    with _attach_lock:
        fanout = port._fanout
        if fanout is None or end not in fanout.ends:
            return
        fanout.ends = tuple(e for e in fanout.ends if e is not end)
        if not fanout.ends:
            port.attach_fanout(None)


class _Ranges:
    """Write numbers, kept as increasing ranges ``[first, last]`` (a disconnection's
    misses are one range, however long)."""

    __slots__ = ("_ranges",)

    def __init__(self) -> None:
        self._ranges: deque[list[int]] = deque()

    def add(self, n: int) -> None:
        ranges = self._ranges
        if ranges and ranges[-1][1] == n - 1:
            ranges[-1][1] = n
        else:
            ranges.append([n, n])

    def above(self, n: int) -> int:
        """How many numbers kept are greater than ``n``."""
        return sum(last - max(first, n + 1) + 1 for first, last in list(self._ranges) if last > n)

    def between(self, low: int, high: int) -> int:
        """How many numbers kept are greater than ``low`` and at most ``high``."""
        return sum(min(last, high) - max(first, low + 1) + 1 for first, last in list(self._ranges)
                   if last > low and first <= high)

    def trim(self, n: int) -> None:
        """Forget the numbers up to ``n``."""
        ranges = self._ranges
        while ranges and ranges[0][1] <= n:
            ranges.popleft()
        if ranges and ranges[0][0] <= n:
            ranges[0][0] = n + 1

    def clear(self) -> None:
        self._ranges.clear()


class WriterEnd(Generic[T]):
    """The writer side of one channel (RTT's sender stream end), next to its output port.

    :meth:`offer` runs in the writer's thread for every sample the port writes: with a
    carrier attached (the transport is connected) the sample is sent at once; while the
    carrier has no room, samples wait in a small policy-shaped queue (DATA: the newest
    one; BUFFER(n): n, then refused; CIRCULAR_BUFFER(n): n, the oldest dropped) that the
    transport drains with :meth:`flush` when it has room again. That queue is the only
    copy the sender keeps, and only while the kernel or the peer is behind: the channel's
    buffer is the reader end's. Without a carrier (connecting, or the peer gone) a sample
    is not sent: counted, and for a mandatory channel ``write`` says ``WRITE_FAILURE``.

    Never blocks and never waits for a lock another thread holds: a writer that finds
    the lock taken (by :meth:`flush`, or another writer) leaves its sample in an inbox
    and raises a flag; whoever holds the lock looks at the flag after letting go, and
    sends what waits. No sample is left queued with no one to send it.
    """

    def __init__(self, port: OutputPort[T], policy: ConnPolicy, label: str, *, reports: bool = True,
                 byte_budget: int | None = None, held: bool = False) -> None:
        self.port = port
        self.policy = policy
        self.label = label
        #: Its reader end reports back (a link); else (a subscription, a stream) what it
        #: could not send is told as a tail (:attr:`tail`) and forgotten once sent past.
        self.reports = reports
        #: Encoded bytes the queue may hold, at most (an end served to another process: a
        #: stuck reader must not grow this one); the size is measured as samples are encoded.
        self.byte_budget = byte_budget
        self._sample_bytes = 0
        self.last_sent = 0
        self.transport = ""  #: the carrier's transport while connected, else ""
        self.sent = 0
        written = port.last_sample()[0]
        #: The port's write number the channel counts from: when this end was made (with
        #: ``init``, one less: the last value written is the channel's first sample).
        self.start = max(0, written - 1) if policy.init else written
        self._carrier: Carrier[Any] | None = None  # any transport's
        self._queue: deque[OutSample[T]] = deque()
        #: Samples written while another thread held the lock, oldest first: only a lock
        #: holder moves them into the queue (so the queue changes under the lock alone).
        self._inbox: deque[OutSample[T]] = deque()
        self._room = 1 if policy.type is ConnType.DATA else max(1, policy.size)
        self._lock = threading.Lock()
        self._more = False
        self._unsent = _Ranges()
        self._unsent_total = 0
        self._warned = False
        self.peer_last = 0  #: the reader end's last report: the last write number it had ...
        self.peer_lost = 0  #: ... and what it lost (jumps, refused, its buffer's drops) ...
        self.peer_pending = 0  #: ... and what its buffer held unread
        self._lost_before = 0  # reports of earlier reader ends (a restarted peer)
        #: Called (in the transport's thread) each time a carrier is attached.
        self.on_connected: Callable[[], None] | None = None
        #: ``held``: a link whose reader end reports its room (a transport with ``waits``):
        #: when its writer waits (``policy.wait``, YARP's flow control), what it knows of
        #: that room, and its :meth:`offer` then waits (see :mod:`.flow`). A stream's
        #: transport holds its writer back itself, if at all.
        self.flow = WriterFlow(policy) if held and waits(policy) else None
        if self.flow is not None:
            self.offer = self._offer_waiting  # type: ignore[method-assign]  # a waiting writer's own offer

    # ---- the writer's thread ------------------------------------------------------------
    def _offer_waiting(self, sample: OutSample[T]) -> bool:
        """:meth:`offer` for a writer that waits: first for its reader's room, then (for
        ``WAIT_AFTER``) for its report that the sample arrived; either bounded by the
        policy's ``wait_timeout``, after which the sample is refused and counted."""
        flow = self.flow
        assert flow is not None
        if self._carrier is not None and not flow.before():
            self._miss(sample.n)
            return False
        if not WriterEnd.offer(self, sample):  # the class's, never waiting
            return False
        flow.sent(sample.n)  # sent now, or queued to leave when the socket has room: in flight either way
        flow.after(sample.n)
        return True

    def offer(self, sample: OutSample[T]) -> bool:
        """Send or keep ``sample`` (see the class); False when it will not leave."""
        carrier = self._carrier
        if carrier is None:
            self._miss(sample.n)
            return False
        lock = self._lock
        if not lock.acquire(blocking=False):  # flush(), or another writer, holds it
            inbox = self._inbox
            if len(self._queue) + len(inbox) >= self.room:  # full, as _keep would find it
                if self.policy.type is ConnType.BUFFER:
                    self._miss(sample.n)  # BUFFER refuses the newest
                    return False
                if len(inbox) >= self.room:  # DATA and CIRCULAR_BUFFER: the newest replaces the oldest
                    try:
                        self._miss(inbox.popleft().n)
                    except IndexError:  # the holder took them meanwhile
                        pass
            inbox.append(sample)
            self._more = True  # once the sample waits: the holder looks again after it lets go ...
            self._pump()  # ... unless it let go before it could see the flag
            return True
        try:
            if not self._queue and not self._inbox:
                data = self._encoded(sample, carrier)  # once per transport
                if data is None:
                    return False
                if carrier.send(sample, data):
                    self.sent += 1
                    self.last_sent = sample.n
                    if not self.reports and self._unsent_total:
                        self._unsent.trim(sample.n)
                    return True
            self._take_inbox()
            return self._keep(sample)
        finally:
            lock.release()
            if self._more:  # another writer queued a sample while this one held the lock
                self._pump()

    def _pump(self) -> None:
        """Send what waits, in the writer's thread, never waiting for the lock: whoever
        holds it looks at ``_more`` once it lets go (see :meth:`flush`). So a sample
        queued while the lock was held is never left waiting with no one to send it."""
        self._drain(blocking=False)

    def _drain(self, blocking: bool) -> None:
        """Send the queue while there is room, again as long as a writer queued meanwhile
        (``_more``); without ``blocking``, only if the lock is free."""
        lock = self._lock
        for _ in range(1000):  # bounded: each round means a writer queued meanwhile
            if not lock.acquire(blocking):
                return
            try:
                self._more = False
                if not self._send_queued():
                    return  # no room: the transport calls flush() once it has
            finally:
                lock.release()
            if not self._more:
                return

    def _encoded(self, sample: OutSample[T], carrier: Carrier[Any]) -> Any:
        """``sample`` encoded for ``carrier`` (once per transport); None, counted and
        said once, when it cannot be (a value the wire cannot carry: never raised into
        the writer)."""
        encode = carrier.encode
        try:
            if sample._key is encode:  # OutSample.encoded's, inline: this runs for every sample written
                data = sample._bytes
            else:
                data = encode(sample)
                sample._key, sample._bytes = encode, data
            if self.byte_budget is not None and type(data) is bytes:
                self._sample_bytes = len(data)
            return data
        except Exception as exc:  # noqa: BLE001 - the writer's thread must never see a transport's error
            self._miss(sample.n)
            if not self._warned:
                self._warned = True
                log.warning("%s: sample %d cannot be encoded for %s: %s", self.label, sample.n, self.transport, exc)
            return None

    @property
    def room(self) -> int:
        """Samples the queue may hold: the policy's, within the byte budget."""
        if self.byte_budget is None or not self._sample_bytes:
            return self._room
        return max(1, min(self._room, self.byte_budget // self._sample_bytes))

    def _keep(self, sample: OutSample[T]) -> bool:
        queue = self._queue
        if len(queue) < self.room:
            queue.append(sample)
            return True
        if self.policy.type is ConnType.BUFFER:
            self._miss(sample.n)
            return False
        try:  # DATA and CIRCULAR_BUFFER: the newest replaces the oldest
            self._miss(queue.popleft().n)
        except IndexError:
            pass
        queue.append(sample)
        return True

    def _sent(self, n: int) -> None:
        self.sent += 1
        self.last_sent = n
        if not self.reports and self._unsent_total:
            self._unsent.trim(n)  # the reader's jump reveals those now

    def _miss(self, n: int) -> None:
        self._unsent.add(n)
        self._unsent_total += 1

    # ---- the transport's side -----------------------------------------------------------
    def connected(self, transport: str, carrier: Carrier[Any], *, new_peer: bool,
                  first: Callable[[], object] | None = None) -> None:
        """The transport is connected: samples go through ``carrier`` from now on.
        ``new_peer``: a reader end that knows nothing of this channel (a first connection,
        or a restarted peer) — it counts from :attr:`peer_last`, so the misses kept here
        become its jumps and are forgotten here; what the old one lost is kept. Call it
        before handing over the new reader end's first :meth:`report`. ``first``: what the transport sends
        before any sample (a "connected" message), with no write slipping in between."""
        with self._lock:  # a write meanwhile finds the lock taken: it waits in the queue, sent after ``first``
            if new_peer:  # what the old reader end lost, and what its buffer held unread when it went
                self._lost_before += self.peer_lost + self.peer_pending
                self.peer_lost = self.peer_pending = 0
                self._unsent.clear()
                if self.flow is not None:
                    self.flow.reset()
            self.transport = transport
            self._carrier = carrier
            if first is not None:
                first()
        if self.policy.init:  # RTT's init: a new connection starts with the last value written
            n, value = self.port.last_sample()
            with self._lock:
                if n > self.peer_last and n > 0 and not self._queue and not self._inbox:
                    self._keep(OutSample(n, _time_ns(), cast(T, value), self.port.type))  # written: n > 0
        self.flush()
        if self.on_connected is not None:
            self.on_connected()

    def disconnected(self) -> None:
        """The transport's connection ended: what waits in the queue will not leave (counted)."""
        with self._lock:
            self._carrier = None
            self.transport = ""
            self._take_inbox()
            while self._queue:
                self._miss(self._queue.popleft().n)

    def flush(self) -> None:
        """Send what waits in the queue until it is empty or the carrier is full again
        (the transport's thread, when its socket has room). Never blocks."""
        self._drain(blocking=True)

    def _take_inbox(self) -> None:
        """Move what writers left in the inbox into the queue, in order (under the lock)."""
        inbox = self._inbox
        while inbox:
            self._keep(inbox.popleft())

    def _send_queued(self) -> bool:
        """Send the queue in order (under the lock); False when the carrier has no room."""
        self._take_inbox()
        carrier = self._carrier
        limit = getattr(carrier, "batch_bytes", 0)
        while self._queue and carrier is not None:
            if not self._send_next(carrier, limit):
                return False
        return True

    def _send_next(self, carrier: Carrier[Any], limit: int) -> bool:
        """Send the oldest queued sample, or (``limit`` > 0: a carrier whose frames join,
        see ``Carrier.batch_bytes``) the oldest samples joined into one message of at most
        ``limit`` bytes; False, with the queue as it was, when the carrier has no room. A
        reader that fell behind then catches up many samples per message, not one each.
        A sample that cannot be encoded is counted (:meth:`_encoded`) and skipped."""
        queue = self._queue
        taken: list[OutSample[T]] = []
        parts: list[Any] = []
        size = 0
        while queue:
            sample = queue[0]
            data = self._encoded(sample, carrier)
            if data is not None:
                if parts and (not limit or size + len(data) > limit):
                    break
                taken.append(sample)
                parts.append(data)
                size += len(data) if limit else 0
            queue.popleft()
        if not parts:
            return True
        if not carrier.send(taken[-1], parts[0] if len(parts) == 1 else b"".join(parts)):
            queue.extendleft(reversed(taken))
            return False
        for sample in taken:
            self._sent(sample.n)
        return True

    @property
    def pending(self) -> int:
        """Samples waiting for room."""
        return len(self._queue) + len(self._inbox)

    def report(self, last: int, lost: int, pending: int = 0) -> None:
        """The reader end's count: it has had every write up to ``last`` but ``lost``, and
        ``pending`` of them wait unread in its buffer (lost too if the reader end goes:
        a restarted peer's buffer is a new one, see :meth:`connected`)."""
        self.peer_last = max(self.peer_last, last)
        self.peer_lost = lost
        self.peer_pending = pending
        self._unsent.trim(self.peer_last)
        if self.flow is not None:
            self.flow.reported(last, pending)

    @property
    def tail(self) -> int:
        """Samples not sent since the last one sent (what a reader cannot know yet)."""
        return self._unsent.above(self.last_sent)

    def tail_after(self) -> tuple[int, int]:
        """``(last sent, tail)``: the write number of the last sample sent, and the samples
        not sent after it (a heartbeat says both: a reader that has a later sample
        already ignores the tail, which that sample's jump counted)."""
        last = self.last_sent
        return last, self._unsent.above(last)

    @property
    def unconfirmed(self) -> int:
        """Writes the reader end has not reported: in flight, waiting here, or not sent
        since its last report (what a connection ending now leaves unknown or lost)."""
        return self.undelivered() + self._unsent.above(self.peer_last)

    def undelivered_upto(self, upto: int) -> int:
        """Writes up to ``upto`` neither reported by the reader end nor counted here as
        not sent: in flight, or waiting here (a graceful stop waits for these)."""
        return max(0, upto - self.peer_last - self._unsent.between(self.peer_last, upto))

    @property
    def unsent(self) -> int:
        """Samples this end never sent (written while not connected, or with no room)."""
        return self._unsent_total

    @property
    def dropped(self) -> int:
        """Samples written and not delivered, as far as known here (see the module docstring)."""
        return self._lost_before + self.peer_lost + self._unsent.above(self.peer_last)

    def undelivered(self) -> int:
        """Samples sent or queued that the reader end has not reported yet (in flight)."""
        last = self.port.last_sample()[0]
        return max(0, last - self.peer_last - self._unsent.above(self.peer_last))


class LossCount:
    """The writes a reader end did not receive, each counted once: the jumps in the write
    numbers, plus the writer's **tail** — what it could not send after the last sample it
    did send, which no jump has revealed yet (its heartbeats say how many; a sample
    received reveals them, so it ends the tail). :meth:`restarted` when the writer's boot
    id changes. Not thread-safe (the receiving thread owns it); :attr:`lost` may be read
    from anywhere."""

    def __init__(self, after: int | None = None) -> None:
        self.last: int | None = after  #: the write number of the last sample received
        self.jumps = 0
        self.tail = 0

    @property
    def lost(self) -> int:
        """Writes not received so far."""
        return self.jumps + self.tail

    def restarted(self) -> None:
        """The writer's process changed: the old one's tail is lost for good, and the new
        one's write numbers start over at 1, so every write of the new process before the
        first one received is a jump from 0 (the writes a restart made a reader miss are
        counted, not hidden)."""
        self.jumps += self.tail
        self.tail = 0
        self.last = 0

    def sample(self, sequence: int) -> bool:
        """Note a received sample; False for one received already (handed over again
        after a reconnection)."""
        last = self.last
        if last is not None and sequence <= last:
            return False
        if last is not None:
            self.jumps += sequence - last - 1
        self.last = sequence
        self.tail = 0
        return True

    def report(self, tail: int, after: int = 0) -> None:
        """The writer's heartbeat: ``tail`` samples not sent since its last one sent,
        ``after`` (its write number; 0: not said). A heartbeat older than a sample received
        since (``after`` below it) is ignored: that sample's jump counted the tail."""
        if after and self.last is not None and self.last > after:
            return
        self.tail = tail

    def began(self, written: int, init: bool) -> None:
        """A stream began when its port had written ``written`` times: the writes up to it
        will not come (the last one will, with ``init``): those not had are lost."""
        upto = written - 1 if init else written
        if self.last is not None and upto > self.last:
            self.jumps += upto - self.last
            self.last = upto
            self.tail = 0


class ReaderEnd(Generic[T]):
    """The reader side of one channel, next to its input port (or observer): it checks
    each sample once (``check``: decode, type, bounds; an exception refuses the sample,
    counted) and keeps it in the channel's one policy-shaped buffer (``store``: the
    input port's :class:`~dataflow.ports.ChannelConnection`, or an observer's mailbox;
    False when the buffer refused it, which the buffer counts as ``buffer_dropped``).

    Fed by one transport thread at a time (:meth:`receive`); the counts may be read
    from anywhere. ``after``: the write number to count jumps from (None: from the first
    sample received).
    """

    def __init__(self, label: str, check: Callable[[Any], T], store: Callable[[int, int, T], bool],
                 buffer_dropped: Callable[[], int], after: int | None = None, init: bool = False,
                 port: InputPort[T] | None = None, policy: ConnPolicy | None = None) -> None:
        self.label = label
        #: The input port it feeds, when there is one (a converting transport maps its type).
        self.port = port
        #: Its channel's policy, when a transport needs it (a ROS 2 stream's QoS depth).
        self.policy = policy
        #: Its channel's storage, when a transport holds writers back until it has room
        #: (flow control: ``has_room()``, ``on_room(callback)``; see :mod:`dataflow.buffers`).
        self.storage: Storage[T] | None = None
        self.init = init  #: its policy hands a new connection the last value written
        self.seen = time.monotonic()  #: when its transport last heard from the writer (any byte)
        self._check = check
        self._store = store
        self._buffer_dropped = buffer_dropped
        self.loss = LossCount(after)
        self.boot_id = ""
        self.received = 0
        self.refused = 0
        self.refusal = ""  #: why the last refused sample was refused
        self.transport = ""
        self._warned = False
        #: Called with each frame a scart transport hands over, before its samples (a
        #: subscription notes the stream is alive, and who sends).
        self.on_frame: Callable[[Frame], None] | None = None

    def writer(self, boot_id: str) -> None:
        """The writer process is ``boot_id``; a change means it restarted (see :class:`LossCount`)."""
        if boot_id and boot_id != self.boot_id:
            if self.boot_id:
                self.loss.restarted()
            self.boot_id = boot_id

    def receive(self, n: int, t_ns: int, payload: object) -> bool:
        """One sample: counted by its write number (False for one had already), checked,
        stored. Never raises: a sample that fails its check is refused and counted (the
        first refusal logged)."""
        loss = self.loss
        last = loss.last
        if last is not None and n == last + 1:  # the hot case: the next write, inline (LossCount.sample's)
            loss.last = n
            loss.tail = 0
        elif not loss.sample(n):
            return False
        self.received += 1
        try:
            value = self._check(payload)
        except Exception as exc:  # noqa: BLE001 - a bad sample never ends the channel
            self._refused(str(exc))
            return False
        return self._store(n, t_ns, value)

    def refuse(self, reason: str) -> None:
        """A sample its transport received and could not hand over (a message that does
        not convert to the port's type): counted as received and refused, like one that
        fails the check (the first one logged). Never raises."""
        self.received += 1
        self._refused(reason)

    def _refused(self, reason: str) -> None:
        self.refused += 1
        self.refusal = reason[:300]
        if not self._warned:
            self._warned = True
            log.warning("%s: a sample refused: %s", self.label, reason)

    @property
    def lost(self) -> int:
        """Samples written and not stored: jumps, refused, dropped by the buffer."""
        return self.loss.lost + self.refused + self._buffer_dropped()

    @property
    def last(self) -> int:
        """The write number of the last sample received (0 before any)."""
        return self.loss.last or 0
