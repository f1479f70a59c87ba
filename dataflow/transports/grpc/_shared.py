"""One ``Subscribe`` stream per subscribing process, port and policy (private).

Subscriptions of one process (one system proxy) to one port with one policy over gRPC
share one ``Subscribe`` call, as ROS subscribers of one node share a topic's connection:
the deployer then encodes and sends each sample once, from one thread of its gRPC
server, whatever number of them (before, each was a stream and a server thread of its
own, so a writer's process woke one thread per subscriber).

The call is read by the :class:`Upstream`'s own thread, which hands each frame to every
reader end attached (each keeps its own check, buffer and counts, as on a stream of its
own). A reader end that joins a stream already running is told where it joins: who
writes, and the last write number the stream carried (the writes before it will not
come to it and, for an end that had received some, are counted as lost); with the
policy's ``init``, it gets the stream's last sample. The stream ends when its last
reader end leaves, or for all of them when the call fails (each subscription then
reconnects, as before).
"""

from __future__ import annotations

import threading
import time
from typing import Any

from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from dataflow.threads import OwnedThread
from dataflow.transports import frames
from dataflow.transports.ends import ReaderEnd

__all__ = ["SharedStreams", "Upstream"]

SILENT_HEARTBEATS = 3  #: a stream silent this many heartbeats is not joined (its peer froze)


class Upstream:
    """One ``Subscribe`` call and the reader ends it feeds (see the module docstring).

    Two locks: ``_feeding`` makes the call's thread and a joining end's first frame take
    turns at the reader ends (each is fed by one thread at a time), and ``_lock`` guards
    who is attached, so that leaving never waits for a frame being handed over."""

    def __init__(self, streams: SharedStreams, key: tuple[Any, bytes], stub: Any, request: Any,
                 heartbeat: float) -> None:
        self._streams = streams
        self.key = key
        self.heartbeat = heartbeat
        self.error: BaseException | None = None  #: why the call ended, when it failed
        self._ends: dict[ReaderEnd, threading.Event] = {}
        self._lock = threading.Lock()
        self._feeding = threading.RLock()  # a reader end's hooks run in the feeding thread
        self._boot_id = ""
        self._written = 0  # the last write number the stream carried, or said it will not carry
        self._last: Any = None  # the last sample it carried (a joiner with ``init`` gets it)
        self._connected = False  # its first frame came
        self._seen = time.monotonic()
        self._ended = False
        self._closing = False
        self._call = stub.Subscribe(request)
        self._thread = OwnedThread(self._run, f"scart-grpc-sub-{request.task}.{request.port}", wake=self._call.cancel)

    @property
    def usable(self) -> bool:
        """Whether an end may join: the call goes on, and something came within
        :data:`SILENT_HEARTBEATS` heartbeats (else its peer froze)."""
        return not (self._ended or self._closing) and not (
            self._connected and time.monotonic() - self._seen > SILENT_HEARTBEATS * self.heartbeat)

    def start(self) -> None:
        self._thread.start()

    def cancel(self) -> None:
        """End the call: every end attached is told (and reconnects)."""
        self._call.cancel()

    def join(self, end: ReaderEnd) -> threading.Event | None:
        """Attach ``end``: the event is set when it is to stop waiting (it left, or the call
        ended); None when the call has ended already."""
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
                frames.feed(end, frame)
        return left

    def leave(self, end: ReaderEnd) -> None:
        """Detach ``end`` (never waits for a frame being handed over); the last one to
        leave ends the call and its thread."""
        with self._streams.lock, self._lock:
            left = self._ends.pop(end, None)
            if left is not None:
                left.set()
            last = not self._ends and not self._closing
            if last:
                self._closing = True  # no end joins any more: one that tries opens a stream of its own
                self._streams.forget(self)
        if last:
            self._thread.stop()

    def ended_for(self, end: ReaderEnd) -> bool:
        """Whether the call ended while ``end`` was attached (it did not leave by itself)."""
        with self._lock:
            return self._ended and end in self._ends

    def _run(self, stopping: threading.Event) -> None:
        ends = self._ends
        try:
            for message in self._call:
                with self._feeding:
                    self._seen = seen = time.monotonic()
                    self._note(message)
                    with self._lock:
                        attached = tuple(ends)
                    for end in attached:
                        if end in ends:  # not left meanwhile
                            end.seen = seen
                            frames.feed(end, message)
        except Exception as exc:  # noqa: BLE001 - every reader end is told, and reconnects
            self.error = exc
        finally:
            with self._streams.lock, self._lock:
                self._streams.forget(self)
                self._ended = True
                for left in ends.values():
                    left.set()

    def _note(self, message: Any) -> None:
        """Keep where the stream is, for a reader end that joins later."""
        self._connected = True
        if message.boot_id:
            self._boot_id = message.boot_id
        if message.samples:
            self._last = message.samples[-1]
            self._written = max(self._written, self._last.sequence)
        if message.written:
            self._written = max(self._written, message.written)


class SharedStreams:
    """The ``Subscribe`` streams open in this process, by system proxy channel and
    request (the grpc transport's; see the module docstring). Thread-safe."""

    def __init__(self) -> None:
        self.lock = threading.Lock()  # taken before an Upstream's own
        self._streams: dict[tuple[Any, bytes], Upstream] = {}

    def attach(self, stub: Any, request: Any, end: ReaderEnd, heartbeat: float) -> tuple[Upstream, threading.Event]:
        """The stream for ``request`` on ``stub`` (a system proxy's channel to one deployer),
        opened now or shared, with ``end`` attached; and the event set when ``end`` is to stop
        waiting (it left, or the call ended). Call :meth:`Upstream.leave` once done."""
        key = (stub, request.SerializeToString(deterministic=True))
        for _ in range(100):  # bounded: a round is lost only to a call that ended meanwhile
            fresh = False
            with self.lock:
                stream = self._streams.get(key)
                if stream is None or not stream.usable:
                    if stream is not None:
                        stream.cancel()  # a frozen peer's stream: the ends on it reconnect too
                    stream = self._streams[key] = Upstream(self, key, stub, request, heartbeat)
                    fresh = True
            left = stream.join(end)
            if fresh:
                stream.start()
            if left is not None:
                return stream, left
        raise RuntimeError(f"no stream for {request.task}.{request.port}: each one ended as it was joined")

    def forget(self, stream: Upstream) -> None:
        """``stream`` is ending: no end joins it any more (under :attr:`lock`)."""
        if self._streams.get(stream.key) is stream:
            del self._streams[stream.key]
