"""Transport ``grpc``: samples over gRPC streams, between any two hosts (registered as
the ``scart.transports`` entry point ``grpc``; rank 100: ``auto``'s fallback).

* A link is one bidirectional ``Link`` stream: ``LinkRequest`` s to the sink (the first
  says which port and channel), ``LinkResponse`` s back. The writer end's samples wait in
  a small queue (:data:`ROOM` frames) for the stream's sending thread, which sends what
  waits together (frames joined end to end are one frame holding all their samples).
* A subscription is fed by a server-streaming ``Subscribe`` call of ``SubscribeResponse`` s
  (the deployer's side is :func:`serve_subscription`), one per subscribing system proxy,
  port and policy: subscriptions alike share it (:mod:`~dataflow.transports._shared`).

The frames are the same bytes as on ipc, encoded once per write (:mod:`~dataflow.transports.frames`).
A frame larger than :data:`PART_BYTES` (a sample of up to 64 MiB) goes in parts, each a
message of its own within gRPC's 4 MiB limit (``part`` and ``more``; :func:`messages_of`,
:class:`Parts`).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any, Generic, TypeVar

from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from dataflow.threads import OwnedThread, Wake
from dataflow.transports import LinkRefused, Peer, Transport, frames
from dataflow.transports._shared import SharedFeed, SharedStreams, carry_shared
from dataflow.transports.ends import OutSample, ReaderEnd, WriterEnd
from dataflow.transports.limits import MAX_FRAME_BYTES

__all__ = ["GrpcTransport", "LINK_METHOD", "PART_BYTES", "Parts", "ROOM", "messages_of", "passthrough"]

log = logging.getLogger(__name__)

LINK_METHOD = "/scart.dataflow.v1.DeployerService/Link"
ROOM = 256  #: frames a gRPC link or subscription holds for its stream's thread, at most ...
ROOM_BYTES = 4 * 1024 * 1024  #: ... and encoded bytes (then the writer end's own queue, by its policy)
BATCH_BYTES = 1024 * 1024  #: encoded samples sent in one message, at most
PART_BYTES = 1024 * 1024  #: a frame larger than this goes in parts of this size (gRPC's messages: 4 MiB at most)
REPORT_ASK_S = 0.1  #: an idle link with samples not yet confirmed asks the sink for a report this often
WAKE_SHARE_S = 0.0005  #: a served stream's wake-up window per channel of its port (see ServedCarrier)
MAX_WAKE_WINDOW_S = 0.02
HEARTBEAT = pb.LinkRequest(heartbeat=True).SerializeToString()


def passthrough(data: bytes) -> bytes:
    """A gRPC serializer for frames that are bytes already."""
    return data


def messages_of(batch: list[bytes]) -> Iterator[bytes]:
    """The gRPC messages carrying ``batch`` (encoded frames, oldest first): frames joined
    end to end up to :data:`BATCH_BYTES` a message (one frame holding their samples), a
    frame larger than :data:`PART_BYTES` in parts, each a message holding nothing else
    (protobuf would merge a part joined to a frame)."""
    joined: list[bytes] = []
    size = 0
    for data in batch:
        if len(data) > PART_BYTES or (joined and size + len(data) > BATCH_BYTES):
            if joined:
                yield b"".join(joined)
                joined, size = [], 0
            if len(data) > PART_BYTES:
                yield from _parts_of(data)
                continue
        joined.append(data)
        size += len(data)
    if joined:
        yield b"".join(joined)


_PART = b"\x72"  # field 14 (part), length-delimited: the same number in LinkRequest and SubscribeResponse
_MORE = b"\x78\x01"  # field 15 (more) = true


def _parts_of(data: bytes) -> Iterator[bytes]:
    """``data`` as part messages (see :func:`messages_of`): one copy of each part."""
    view = memoryview(data)
    for start in range(0, len(data), PART_BYTES):
        chunk = view[start:start + PART_BYTES]
        more = _MORE if start + PART_BYTES < len(data) else b""
        yield b"".join((_PART, frames.varint(len(chunk)), chunk, more))


M = TypeVar("M")


class Parts(Generic[M]):
    """A frame sent in parts (:func:`messages_of`), whole again: :meth:`whole` returns each
    message as it is, or None while the parts of one come; the last part gives the frame
    parsed with ``parse``. A frame over :data:`~dataflow.transports.limits.MAX_FRAME_BYTES`
    is dropped whole and counted in :attr:`dropped` (a writer refuses one before it
    leaves). One receiving thread."""

    def __init__(self, parse: Callable[[bytes], M]) -> None:
        self._parse = parse
        self._parts: list[bytes] = []
        self._size = 0
        self._skipping = False
        self.dropped = 0

    def whole(self, message: M) -> M | None:
        part: bytes = message.part  # type: ignore[attr-defined]  # LinkRequest and SubscribeResponse alike
        if not part and not self._parts and not self._skipping:
            return message  # the common case: a message of its own
        more = message.more  # type: ignore[attr-defined]  # (as above)
        if not self._skipping:
            self._parts.append(part)
            self._size += len(part)
            if self._size > MAX_FRAME_BYTES:
                self.dropped += 1
                self._parts, self._size, self._skipping = [], 0, True
        if more:
            return None
        if self._skipping:
            self._skipping = False
            return None
        data = b"".join(self._parts)
        self._parts, self._size = [], 0
        return self._parse(data)


class GrpcTransport(Transport):
    """Samples over gRPC streams: works between any two hosts (the fallback of ``auto``)."""

    name = "grpc"
    rank = 100

    def __init__(self) -> None:
        self._streams = SharedStreams()  # the Subscribe streams open, shared by subscriptions alike

    def link(self, end: WriterEnd, peer: Peer) -> bool:
        if peer.channel_of is None:  # not a deployer's peer: nothing to open a stream on
            return False
        carrier = _LinkCarrier(end)
        call = peer.channel_of.stream_stream(LINK_METHOD, request_serializer=passthrough,
                                             response_deserializer=pb.LinkResponse.FromString)(
            carrier.frames(frames.link_hello(end, peer)))
        try:
            first = next(call)
            if first.refused:
                raise LinkRefused(first.refused)
            end.connected(self.name, carrier, new_peer=not first.known)  # first: it keeps a restarted
            end.report(first.last, first.lost, first.pending)  # sink's old counts before the new ones come
            if peer.opened(call.cancel, finish=carrier.finish):
                for report in call:
                    end.report(report.last, report.lost, report.pending)
                    if report.final:
                        carrier.final.set()
                        break
        finally:
            carrier.close()
            call.cancel()
            end.disconnected()
        return True

    def subscribe(self, end: ReaderEnd, peer: Peer) -> bool:
        """Feed ``end`` from the peer's port: one ``Subscribe`` call, read by a thread of its
        own and shared by the subscriptions of this system proxy to that port with the
        same policy (see :mod:`~dataflow.transports._shared`)."""
        request = pb.SubscribeRequest(task=peer.task, port=peer.port, policy=peer.policy_msg,
                                      heartbeat_ms=int(peer.heartbeat * 1000))

        def open_stream(feed: SharedFeed) -> bool:
            call = peer.stub.Subscribe(request)
            reader = OwnedThread(lambda stopping: _read(call, feed), f"scart-grpc-sub-{peer.where}", wake=call.cancel)
            feed.close, feed.join_stream = reader.signal, reader.join
            reader.start()
            return True

        return carry_shared(self.name, self._streams, request, end, peer, open_stream)


def _read(call: Any, feed: SharedFeed) -> None:
    """A shared ``Subscribe`` call's thread: each response to the reader ends, until it ends."""
    error = None
    parts = Parts(pb.SubscribeResponse.FromString)
    try:
        for message in call:
            whole = parts.whole(message)
            if whole is None:
                feed.alive()  # a part of a large sample: the writer is alive
                continue
            feed.feed(whole)
    except Exception as exc:  # noqa: BLE001 - every reader end is told, and reconnects
        error = exc
    finally:
        feed.ended(error)


class _LinkCarrier:
    """A gRPC link's carrier: frames wait in a bounded queue for the stream's thread."""

    def __init__(self, end: WriterEnd) -> None:
        self.end = end
        self.encode = frames.encoder(end.port.type)
        self.final = threading.Event()
        self._queue: deque[bytes] = deque()
        self._size = [0]  # bytes in the queue
        self._wake = Wake()
        self._closing = False
        self._closed = False

    def send(self, sample: OutSample, data: bytes) -> bool:  # the writer's thread
        if self._closing or not _room(self._queue, self._size, data):
            return False
        self._queue.append(data)
        self._size[0] += len(data)
        self._wake.set()
        return True

    def frames(self, hello: Any) -> Iterator[bytes]:
        """The stream's requests (gRPC's thread): the hello, then what waits, joined."""
        yield pb.LinkRequest(hello=hello).SerializeToString()
        while not self._closed:
            if not self._wake.wait(REPORT_ASK_S):
                if self.end.undelivered() or self.end.peer_pending:  # the sink reports when it hears from
                    yield HEARTBEAT  # us: ask for the rest, and for what its task read since
                continue
            self._wake.clear()
            while self._queue:
                batch, size = [], 0
                while self._queue and size < BATCH_BYTES:
                    data = self._queue.popleft()
                    self._size[0] -= len(data)
                    batch.append(data)
                    size += len(data)
                yield from messages_of(batch)
                self.end.flush()  # what waited in the end's own queue comes in now
            if self._closing:
                yield pb.LinkRequest(closing=True).SerializeToString()
                self._closing = False

    def finish(self, timeout: float) -> bool:
        """Close gracefully (see :meth:`Peer.finish`): the rest, a closing frame, the final report."""
        self.end.flush()
        self._closing = True
        self._wake.set()
        return self.final.wait(timeout)

    def close(self) -> None:
        self._closed = True
        self._wake.set()


def _room(queue: deque[bytes], size: list[int], data: bytes) -> bool:
    """Whether a frame of ``data`` fits in a carrier's queue (:data:`ROOM`, :data:`ROOM_BYTES`)."""
    return not queue or (len(queue) < ROOM and size[0] + len(data) <= ROOM_BYTES)


def wait_frames(queue: deque[bytes], size: list[int], wake: Wake, timeout: float) -> list[bytes]:
    """What waits in ``queue`` after waiting up to ``timeout`` s for ``wake``, taken."""
    if timeout > 0 and wake.wait(timeout):
        wake.clear()
    out = []
    while queue:
        data = queue.popleft()
        size[0] -= len(data)
        out.append(data)
    return out


class ServedCarrier:
    """The deployer's side of a subscription over gRPC: frames wait here for the
    ``Subscribe`` call's thread, which sends them joined (:func:`serve_subscription`).

    Each stream is a thread of the gRPC server, so a writer with many gRPC subscribers
    would wake as many threads per write. A stream's thread is woken at most once per
    :meth:`window` — :data:`WAKE_SHARE_S` times the number of channels its port feeds
    (none for a lone subscriber): 40 subscribers of a 1 kHz port then cost the process
    2,000 wake-ups a second, not 40 000, at the price of that much latency (20 ms each;
    2 ms with 4). Each wake-up costs the process several GIL hand-overs (the stream's
    thread, gRPC's completion queue): with half this share, a 1 kHz writer with 40
    subscribers closed 58 % of its cycles on time; with this one, 88 %."""

    def __init__(self, end: WriterEnd | None = None) -> None:
        self.encode = frames.encoder(end.port.type) if end is not None else frames.sample_frame
        self.queue: deque[bytes] = deque()
        self.size = [0]  # bytes in the queue
        self.wake = Wake()
        self.end = end
        self.next_wake = 0.0

    def window(self) -> float:
        """Seconds between two wake-ups of this stream's thread, at most."""
        fanout = self.end.port._fanout if self.end is not None else None  # noqa: SLF001
        readers = len(fanout.ends) if fanout is not None else 1
        return 0.0 if readers <= 1 else min(MAX_WAKE_WINDOW_S, WAKE_SHARE_S * readers)

    def send(self, sample: OutSample, data: bytes) -> bool:  # the writer's thread
        if not _room(self.queue, self.size, data):
            return False
        self.queue.append(data)
        self.size[0] += len(data)
        now = time.monotonic()
        if now >= self.next_wake:  # else the stream's thread comes for it by itself, at next_wake
            self.wake.set()
        return True

    def first(self, data: bytes) -> None:
        """Put ``data`` before anything else (the "connected" frame)."""
        self.queue.appendleft(data)
        self.size[0] += len(data)
        self.wake.set()


def serve_subscription(end: WriterEnd, carrier: ServedCarrier, boot_id: str, heartbeat: float, alive: Any,
                       dropped: Callable[[], tuple[int, int]]) -> Iterator[bytes]:
    """The ``Subscribe`` responses for a served writer end (the call's thread), as bytes:
    "connected", then samples as they come (what waits, joined into one message), and a
    heartbeat after ``heartbeat`` s without one (with ``dropped()``: the last sample sent
    and the tail after it), until ``alive()`` is false (set ``carrier.wake`` to have it
    looked at at once)."""
    end.connected("grpc", carrier, new_peer=True,  # "connected", first: from now on every write comes
                  first=lambda: carrier.first(frames.connected(end, boot_id)))
    last = time.monotonic()
    try:
        while alive():
            wait = max(0.0, carrier.next_wake - time.monotonic()) if carrier.queue else heartbeat
            batch = wait_frames(carrier.queue, carrier.size, carrier.wake, min(wait, heartbeat))
            if batch:
                yield from messages_of(batch)
                end.flush()
                last = time.monotonic()
                carrier.next_wake = last + carrier.window()
            elif time.monotonic() - last >= heartbeat:
                sent_last, tail = dropped()
                yield frames.heartbeat(dropped=tail, sent_last=sent_last)
                last = time.monotonic()
    finally:
        end.disconnected()
