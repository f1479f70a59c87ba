"""The ``grpc`` transport's serving half (see :mod:`dataflow.transports.serving`): a
deployer's ``Subscribe`` calls (a subscription's frames, each a server-streaming call)
and ``Link`` calls (a link coming in, a bidirectional stream).

A subscription is a :class:`~dataflow.transports.served.Served` writer end attached to
the output port (never failing the writer) whose carrier is a :class:`ServedCarrier`; a
link coming in is an :class:`~dataflow.transports.sinks.IncomingLink` reader end whose
buffer feeds the input port. The deployer's control plane owns both sets, and counts
them in ``ListLinks`` whichever transport carries them.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterator

import grpc

from dataflow.threads import Wake
from dataflow.transports import frames
from dataflow.transports.ends import OutSample, WriterEnd
from dataflow.transports.grpc._messages import Parts, messages_of, passthrough, room
from dataflow.transports.serving import ChannelHost, Serving
from dataflow.transports.sinks import LINGER_S, REPORT_EVERY, REPORT_S, Refused
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from scart_wire.rpc import Abort, MethodHandler, abort

__all__ = ["GrpcServing", "MAX_WAKE_WINDOW_S", "ServedCarrier", "WAKE_SHARE_S", "serve_subscription"]

WAKE_SHARE_S = 0.0005  #: a served stream's wake-up window per channel of its port (see ServedCarrier)
MAX_WAKE_WINDOW_S = 0.02


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

    def __init__(self, end: WriterEnd) -> None:
        self.encode = frames.encoder(end.port.type)
        self.queue: deque[bytes] = deque()
        self.size = [0]  # bytes in the queue
        self.wake = Wake()
        self.end = end
        self.next_wake = 0.0

    def window(self) -> float:
        """Seconds between two wake-ups of this stream's thread, at most."""
        fanout = self.end.port._fanout  # noqa: SLF001
        readers = len(fanout.ends) if fanout is not None else 1
        return 0.0 if readers <= 1 else min(MAX_WAKE_WINDOW_S, WAKE_SHARE_S * readers)

    def send(self, sample: OutSample, data: bytes) -> bool:  # the writer's thread
        if not room(self.queue, self.size, data):
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


def serve_subscription(end: WriterEnd, carrier: ServedCarrier, boot_id: str, heartbeat: float,
                       alive: Callable[[], bool], dropped: Callable[[], tuple[int, int]]) -> Iterator[bytes]:
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


class GrpcServing(Serving):
    """A deployer's ``Subscribe`` and ``Link`` calls (see the module docstring)."""

    methods = frozenset({"Subscribe", "Link"})

    def handler(self, method: str) -> MethodHandler:
        if method == "Subscribe":  # frames are sent as the bytes they were encoded to, once per write
            return grpc.unary_stream_rpc_method_handler(
                self.subscribe, request_deserializer=pb.SubscribeRequest.FromString, response_serializer=passthrough)
        return grpc.stream_stream_rpc_method_handler(self.link, request_deserializer=pb.LinkRequest.FromString,
                                                     response_serializer=pb.LinkResponse.SerializeToString)

    def subscribe(self, request: pb.SubscribeRequest, context: grpc.ServicerContext) -> Iterator[bytes]:
        """``Subscribe``: the frames of the output port ``request.task.port``, until the
        call ends or the deployer stops."""
        host = self.host
        try:
            _open(host)
            served = host.serve(request.task, request.port, host.policy(request.policy), context.peer() or "", "grpc",
                                host.max_streams)  # each a worker of the deployer's server, for its life
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)
        carrier = ServedCarrier(served.end)
        context.add_callback(carrier.wake.set)  # a cancelled stream wakes at once
        try:
            yield from serve_subscription(served.end, carrier, host.boot_id, host.heartbeat_s(request.heartbeat_ms),
                                          lambda: context.is_active() and not host.stopping.is_set(),
                                          served.end.tail_after)
        finally:
            host.served.close(served)

    def link(self, requests: Iterator[pb.LinkRequest], context: grpc.ServicerContext) -> Iterator[pb.LinkResponse]:
        """``Link``: a link coming in — its hello, then its frames into the link's reader
        end, its reports back — until the source closes it or the deployer stops."""
        host = self.host
        try:
            _open(host)
            first = next(requests)
            link, known = host.sinks.open(first.hello, host.policy(first.hello.policy))
        except StopIteration:
            return
        except Refused as exc:
            yield pb.LinkResponse(refused=str(exc))
            return
        except Exception as exc:  # noqa: BLE001
            abort(context, exc)
        link.end.transport = "grpc"
        finished = False
        try:
            yield frames.report_of(link.end, known=known)
            unreported, reported_at = 0, time.monotonic()
            parts = Parts(pb.LinkRequest.FromString)
            for message in requests:
                frame = parts.whole(message)
                if frame is None:  # a part of a large sample
                    link.end.seen = time.monotonic()
                    continue
                unreported += frames.feed(link.end, frame) + 1
                if link.closed and not frame.closing:  # this deployer stops: the last report
                    yield frames.report_of(link.end)
                    return
                if frame.closing:
                    link.linger(time.monotonic() + LINGER_S, host.stopping)
                    finished = True
                    host.sinks.finish(link)
                    yield frames.report_of(link.end, final=True)
                    return
                now = time.monotonic()
                if unreported >= REPORT_EVERY or now - reported_at >= REPORT_S or frame.heartbeat:
                    yield frames.report_of(link.end, pending=link.pending)
                    unreported, reported_at = 0, now
        finally:
            if not finished:
                host.sinks.carried(link)


def _open(host: ChannelHost) -> None:
    """Refuse a new channel once the deployer stops (UNAVAILABLE: the peer comes back later)."""
    if host.stopping.is_set():
        raise Abort("UNAVAILABLE", "this deployer is stopping")
