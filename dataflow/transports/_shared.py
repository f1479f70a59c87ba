"""One stream per subscribing process, port and policy, on scart's own transports (private).

Subscriptions of one process (one system proxy) to one port with one policy share one
stream of a transport (a gRPC ``Subscribe`` call, an ipc socket), as ROS subscribers of
one node share a topic's connection: the deployer then sends each sample once, to one
peer, whatever the number of them (before, each was a stream of its own, so a writer's
process sent and woke once per subscriber).

A :class:`SharedFeed` hands each frame of its stream to every reader end attached (each
keeps its own check, buffer and counts, as on a stream of its own). A reader end that
joins a running stream is told where it joins: who writes, and the last write number
the stream carried (the writes before it will not come to it and, for an end that had
received some, are counted as lost); with the policy's ``init``, it gets the stream's
last sample. The stream ends when its last reader end leaves, or for all of them when
it fails (each subscription then reconnects, as before). A stream silent for
:data:`SILENT_HEARTBEATS` heartbeats is not joined but ended: its peer froze.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from dataflow.transports import Peer, frames
from dataflow.transports.ends import ReaderEnd

if TYPE_CHECKING:
    from google.protobuf.message import Message

__all__ = ["SILENT_HEARTBEATS", "SharedFeed", "SharedStreams", "carry_shared"]

SILENT_HEARTBEATS = 3  #: a stream silent this many heartbeats is not joined (its peer froze)
OPEN_WAIT_S = 60.0  #: how long a joining end waits for another's opening of the stream, at most


class SharedFeed:
    """The reader ends one stream feeds (see the module docstring). The transport calls
    :meth:`feed` with each parsed frame (one thread at a time), :meth:`alive` for any byte,
    and :meth:`ended` when the stream is over; :attr:`close` (set by the transport) ends
    the stream once its last reader end has left.

    Two locks: ``_feeding`` makes the stream's frames and a joining end's first frame take
    turns at the reader ends (each is fed by one thread at a time), and ``_lock`` guards
    who is attached, so that leaving never waits for a frame being handed over."""

    def __init__(self, streams: SharedStreams, key: tuple[object, ...], heartbeat: float) -> None:
        self.key = key
        self.heartbeat = heartbeat
        self.error: BaseException | None = None  #: why the stream ended, when it failed
        self.close: Callable[[], object] = lambda: None  #: ends the stream, never blocking (the transport's)
        self.join_stream: Callable[[], object] = lambda: None  #: waits for what :attr:`close` ended
        self.opened = threading.Event()  #: the opening is over (the stream is up, or it failed)
        self._streams = streams
        self._ends: dict[ReaderEnd[Any], threading.Event] = {}
        self._lock = threading.Lock()
        self._feeding = threading.RLock()  # a reader end's hooks run in the feeding thread
        self._boot_id = ""
        self._written = 0  # the last write number the stream carried, or said it will not carry
        self._last: pb.Sample | None = None  # the last sample it carried (a joiner with ``init`` gets it)
        self._last_value: object = None  # its value, when its bytes are elsewhere (shared memory)
        self._connected = False  # its first frame came
        self._seen = time.monotonic()
        self._ended = False
        self._closing = False

    @property
    def usable(self) -> bool:
        """Whether an end may join: the stream goes on, and something came within
        :data:`SILENT_HEARTBEATS` heartbeats (else its peer froze)."""
        return not (self._ended or self._closing) and not (
            self._connected and time.monotonic() - self._seen > SILENT_HEARTBEATS * self.heartbeat)

    def join(self, end: ReaderEnd) -> threading.Event | None:
        """Attach ``end``: the event is set when it is to stop waiting (it left, or the
        stream ended); None when the stream has ended already."""
        left = threading.Event()
        with self._feeding:
            with self._lock:
                if self._ended or self._closing:
                    return None
                self._ends[end] = left
            if self._connected:  # joining midway: where the stream is, as its first frame would say
                frame = pb.SubscribeResponse(heartbeat=True, boot_id=self._boot_id, written=self._written)
                if end.init and self._last is not None:
                    frame.samples.append(self._last)
                end.seen = self._seen
                frames.feed(end, frame, None if self._last_value is None else {0: self._last_value})
        return left

    def leave(self, end: ReaderEnd) -> None:
        """Detach ``end`` (never waits for a frame being handed over); the last one to
        leave ends the stream."""
        with self._streams.lock, self._lock:
            left = self._ends.pop(end, None)
            if left is not None:
                left.set()
            last = not self._ends and not self._closing
            if last:
                self._closing = True  # no end joins any more: one that tries opens a stream of its own
                self._streams.forget(self)
        if last:
            self.close()
            self.join_stream()

    def ended_for(self, end: ReaderEnd) -> bool:
        """Whether the stream ended while ``end`` was attached (it did not leave by itself)."""
        with self._lock:
            return self._ended and end in self._ends

    def alive(self) -> None:
        """Something came (any byte): the peer is alive."""
        self._seen = seen = time.monotonic()
        for end in tuple(self._ends):
            end.seen = seen

    def feed(self, message: pb.SubscribeResponse, values: Mapping[int, object] | None = None) -> None:
        """Hand a parsed frame to every reader end attached (``values``: see
        :func:`~dataflow.transports.frames.feed`)."""
        ends = self._ends
        with self._feeding:
            self._seen = seen = time.monotonic()
            self._note(message, values)
            with self._lock:
                attached = tuple(ends)
            for end in attached:
                if end in ends:  # not left meanwhile
                    end.seen = seen
                    frames.feed(end, message, values)

    def ended(self, error: BaseException | None = None) -> None:
        """The stream is over (``error``: why it failed): every end attached is told."""
        with self._streams.lock, self._lock:
            self._streams.forget(self)
            if not self._ended:
                self._ended = True
                self.error = error
            for left in self._ends.values():
                left.set()
        self.opened.set()

    def _note(self, message: pb.SubscribeResponse, values: Mapping[int, object] | None = None) -> None:
        """Keep where the stream is, for a reader end that joins later."""
        self._connected = True
        if message.boot_id:
            self._boot_id = message.boot_id
        if message.samples:
            self._last = message.samples[-1]
            self._last_value = values.get(len(message.samples) - 1) if values else None
            self._written = max(self._written, self._last.sequence)
        if message.written:
            self._written = max(self._written, message.written)


class SharedStreams:
    """A transport's shared streams open in this process, by key (the system proxy's
    channel and the request; see the module docstring). Thread-safe."""

    def __init__(self) -> None:
        self.lock = threading.Lock()  # taken before a SharedFeed's own
        self._feeds: dict[tuple[object, ...], SharedFeed] = {}

    def attach(self, key: tuple[object, ...], end: ReaderEnd[Any], heartbeat: float,
               open_stream: Callable[[SharedFeed], bool]) -> tuple[SharedFeed, threading.Event] | None:
        """The stream for ``key``, shared or opened now, with ``end`` attached; and the
        event set when ``end`` is to stop waiting (it left, or the stream ended). The
        first end opens it with ``open_stream(feed)`` (in the caller's thread): True once
        it is up, False when the transport cannot carry it (then None is returned, for
        the next transport to try); what it raises propagates. Call
        :meth:`SharedFeed.leave` once done. Raises :class:`TimeoutError` when another
        end's opening took over :data:`OPEN_WAIT_S`."""
        for _ in range(100):  # bounded: a round is lost only to a stream that ended as it was joined
            with self.lock:
                feed = stale = self._feeds.get(key)
                fresh = feed is None or not feed.usable
                if fresh:
                    feed = self._feeds[key] = SharedFeed(self, key, heartbeat)
            if fresh and stale is not None:
                stale.close()  # a frozen peer's stream: the ends on it reconnect too
            assert feed is not None
            if fresh:
                left = feed.join(end)
                assert left is not None  # nobody else can end it before it opens
                try:
                    up = open_stream(feed)
                except BaseException as exc:
                    feed.ended(exc)
                    feed.leave(end)
                    raise
                if not up:
                    feed.ended()
                    feed.leave(end)
                    return None
                feed.opened.set()
                return feed, left
            if not feed.opened.wait(OPEN_WAIT_S):
                raise TimeoutError(f"the stream for {end.label} did not open within {OPEN_WAIT_S:.0f} s")
            left = feed.join(end)
            if left is not None:
                return feed, left
        raise RuntimeError(f"no stream for {end.label}: each one ended as it was joined")

    def forget(self, feed: SharedFeed) -> None:
        """``feed`` is ending: no end joins it any more (under :attr:`lock`)."""
        if self._feeds.get(feed.key) is feed:
            del self._feeds[feed.key]


def carry_shared(transport: str, streams: SharedStreams, request: Message, end: ReaderEnd[Any], peer: Peer,
                 open_stream: Callable[[SharedFeed], bool]) -> bool:
    """A transport's ``subscribe`` on a shared stream: attach ``end`` to the stream that
    ``request`` (a protobuf message) opens at the peer, opening it when it is the first;
    wait until it leaves (the peer's cancel) or the stream ends, then leave. False when
    the transport cannot carry it; raises what the stream failed with."""
    end.transport = transport  # before the first frame: the subscription is up with it
    key = (peer.stub, request.SerializeToString(deterministic=True))  # the system proxy's channel, the request
    attached = streams.attach(key, end, peer.heartbeat, open_stream)
    if attached is None:
        end.transport = ""
        return False
    feed, left = attached
    try:
        if peer.opened(lambda: feed.leave(end)):
            left.wait()
        failed = feed.ended_for(end)
    finally:
        feed.leave(end)
    if failed and feed.error is not None:
        raise feed.error
    return True
