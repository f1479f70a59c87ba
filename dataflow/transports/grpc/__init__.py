"""Transport ``grpc``: samples over gRPC streams, between any two hosts (registered as
the ``scart.transports`` entry point ``grpc``; rank 100: ``auto``'s fallback).

* A link is one bidirectional ``Link`` stream: ``LinkRequest`` s to the sink (the first
  says which port and channel), ``LinkResponse`` s back. The writer end's samples wait in
  a small queue (:data:`ROOM` frames) for the stream's sending thread, which sends what
  waits together (frames joined end to end are one frame holding all their samples).
* A subscription is fed by a server-streaming ``Subscribe`` call of ``SubscribeResponse`` s
  (the deployer's side is :mod:`._serve`'s), one per subscribing system proxy,
  port and policy: subscriptions alike share it (:mod:`~dataflow.transports._shared`).

The frames are the same bytes as on ipc, encoded once per write (:mod:`~dataflow.transports.frames`).
A frame larger than :data:`PART_BYTES` (a sample of up to 64 MiB) goes in parts, each a
message of its own within gRPC's 4 MiB limit (``part`` and ``more``; :func:`messages_of`,
:class:`Parts`).

Both halves are here: this module connects (:class:`GrpcTransport`), :mod:`._serve`
answers a deployer's ``Subscribe`` and ``Link`` calls (its serving half).
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Iterator
from typing import TYPE_CHECKING

from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from dataflow.threads import OwnedThread, Wake
from dataflow.transports import LinkRefused, Peer, Transport, frames
from dataflow.transports._shared import SharedFeed, SharedStreams, carry_shared
from dataflow.transports.ends import OutSample, ReaderEnd, WriterEnd
from dataflow.transports.grpc._messages import (BATCH_BYTES, PART_BYTES, ROOM, ROOM_BYTES, Parts, messages_of,
                                                passthrough, room)

if TYPE_CHECKING:
    from dataflow.transports.serving import Serving

__all__ = ["GrpcTransport", "LINK_METHOD", "PART_BYTES", "Parts", "ROOM", "ROOM_BYTES", "messages_of", "passthrough"]

log = logging.getLogger(__name__)

LINK_METHOD = "/scart.dataflow.v1.DeployerService/Link"
REPORT_ASK_S = 0.1  #: an idle link with samples not yet confirmed asks the sink for a report this often
HEARTBEAT = pb.LinkRequest(heartbeat=True).SerializeToString()


class GrpcTransport(Transport):
    """Samples over gRPC streams: works between any two hosts (the fallback of ``auto``)."""

    name = "grpc"
    rank = 100
    carries = frozenset({"link", "subscription"})

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

    def serving(self) -> type[Serving]:
        from dataflow.transports.grpc._serve import GrpcServing

        return GrpcServing

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


def _read(call: Iterator[pb.SubscribeResponse], feed: SharedFeed) -> None:
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
        if self._closing or not room(self._queue, self._size, data):
            return False
        self._queue.append(data)
        self._size[0] += len(data)
        self._wake.set()
        return True

    def frames(self, hello: pb.LinkHello) -> Iterator[bytes]:
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


