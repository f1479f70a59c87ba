"""scart's own transports (private; registered as the ``scart.transports`` entry points
``ipc`` and ``grpc``; see :mod:`dataflow.remote.transport`).

* :class:`IpcTransport` — the same-host fast path: tickets over the control plane, then
  the deployer's abstract Unix socket (see :mod:`dataflow.remote._ipc`). Rank 10: ``auto``
  tries it first; it declines (False) when the two ends are not on one host or the peer
  has no ipc, so ``auto`` goes on to gRPC; a policy naming ``ipc`` gets an error saying why.
* :class:`GrpcTransport` — gRPC streams (client streaming ``WritePortStream`` for links,
  server streaming ``Subscribe`` for subscriptions). Rank 100: works between any two hosts.
  A link sends the samples waiting together when the sink's deployer says it reads them.

Both carry the same messages (``WritePortStreamRequest``, ``SubscribeResponse``).
"""

from __future__ import annotations

import logging
import select
import socket
import threading
from typing import Any

from dataflow.remote import _convert as cv
from dataflow.remote import _ipc, errors
from dataflow.remote._proto import df as pb
from dataflow.remote.transport import LinkEnd, ReaderEnd, Transport

__all__ = ["GrpcTransport", "IpcTransport"]

log = logging.getLogger(__name__)

BATCHES_PER_WAKE = 160  #: a gRPC link sends at most 160 × 64 samples per wake-up, then looks again


class GrpcTransport(Transport):
    """Samples over gRPC streams: works between any two hosts (the fallback of ``auto``)."""

    name = "grpc"
    rank = 100

    def link(self, end: LinkEnd, address: str, stub: Any) -> bool:
        ended = threading.Event()  # grpc may still wait on the generator after the call ended
        batch_bytes = _ipc.BATCH_BYTES if end.reads_batches() else 0  # an older sink: one value a message

        def requests() -> Any:
            yield pb.WritePortStreamRequest(task=end.sink_task, port=end.sink_port, policy=cv.policy_to_msg(end.policy))
            while not end.closed.is_set() and not ended.is_set():
                if not end.wait_data(0.5):
                    continue
                if ended.is_set():
                    end.wake()  # for the next connection
                    return
                for _ in range(BATCHES_PER_WAKE):
                    values = end.take()
                    if not values:
                        break
                    yield from end.requests(values, batch_bytes)

        call = stub.WritePortStream.future(requests())
        try:
            if end.opened(self.name, call.cancel):
                call.result()
        finally:
            ended.set()
            end.wake()  # a generator still waiting sees it ended
        return True

    def subscribe(self, end: ReaderEnd, address: str) -> bool:
        request = pb.SubscribeRequest(task=end.component, port=end.port, policy=cv.policy_to_msg(end.policy),
                                      heartbeat_ms=end.heartbeat_ms)
        call = end.stub(address).Subscribe(request)
        if not end.opened(self.name, call.cancel):
            call.cancel()
            return True
        for message in call:
            end.receive(message)
        return True


class IpcTransport(Transport):
    """Samples over the deployer's abstract Unix socket, when both ends are on one host."""

    name = "ipc"
    rank = 10

    def link(self, end: LinkEnd, address: str, stub: Any) -> bool:
        request = pb.OpenIpcWriterRequest(task=end.sink_task, port=end.sink_port,
                                          policy=cv.policy_to_msg(end.policy), host_id=_ipc.host_id())
        opened = _ipc.open_with(lambda: stub.OpenIpcWriter(request, timeout=end.timeout),
                                end.policy.transport, f"{end.sink_task}.{end.sink_port}", address)
        if opened is None:
            return False
        sock, _, reply = opened
        _carry_link(end, sock, _ipc.BATCH_BYTES if reply.batches else 0)
        return True

    def subscribe(self, end: ReaderEnd, address: str) -> bool:
        request = pb.OpenIpcReaderRequest(task=end.component, port=end.port, policy=cv.policy_to_msg(end.policy),
                                          host_id=_ipc.host_id(), heartbeat_ms=end.heartbeat_ms)
        stub = end.stub(address)
        opened = _ipc.open_with(lambda: stub.OpenIpcReader(request, timeout=end.timeout),
                                end.policy.transport, f"{end.component}.{end.port}", address)
        if opened is None:
            return False
        sock, first, _ = opened  # first: the deployer's "connected" heartbeat
        try:
            if not end.opened(self.name, lambda: _ipc.shutdown_quietly(sock)):
                return True
            end.receive(pb.SubscribeResponse.FromString(first))
            silence = 3 * end.heartbeat
            try:
                for message in _ipc.messages_in(sock, silence):
                    end.receive(pb.SubscribeResponse.FromString(message))
            except TimeoutError:
                raise errors.RemoteTimeoutError(f"no heartbeat for {silence:.1f} s (peer frozen?)",
                                                "DEADLINE_EXCEEDED", "ipc") from None
        finally:
            sock.close()
        return True


def _carry_link(end: LinkEnd, sock: socket.socket, batch_bytes: int) -> None:
    """Samples go from the writer's thread (the outbox's pump); this thread waits for the
    sink to go away (its socket's end), for room when the socket was full, or for the link
    to be undone. With ``batch_bytes`` (the sink reads batches), the samples waiting go
    together in messages of at most that many bytes: one send and one wake-up for a burst.
    Then too, a write less than :data:`~dataflow.remote._ipc.SOON_S` after the last send
    leaves the sending to this thread, which takes what came meanwhile in one message: a
    fast writer pays for storing a sample, not for a send each (a periodic one, slower
    than that, still sends from its own thread at once)."""
    wake_r, wake_w = socket.socketpair()
    wake_w.setblocking(False)

    def wake() -> None:
        try:
            wake_w.send(b"x")
        except OSError:  # full (a wake-up is pending anyway), or closed: the link moved on
            pass

    outbox = _ipc.Outbox(sock, end.take, lambda values: end.messages(values, batch_bytes), wake, wake,
                         defer=wake if batch_bytes else None)

    def pump() -> None:  # the writer's thread
        if outbox.closed:
            end.wake()  # the next connection sends it
        else:
            outbox.offer()

    try:
        if not end.opened("ipc", wake, pump=pump, dropped=lambda: outbox.dropped):
            return
        poller = select.poll()
        poller.register(wake_r, select.POLLIN)
        outbox.pump()  # what came while connecting
        while not end.closed.is_set() and not outbox.broken:
            poller.register(sock, select.POLLIN | (select.POLLOUT if outbox.blocked else 0))
            ready = dict(poller.poll(500))
            if ready.get(wake_r.fileno()):
                wake_r.recv(4096)
            if ready.get(sock.fileno(), 0) & (select.POLLIN | select.POLLHUP | select.POLLERR):
                break  # the sink sends nothing after its acknowledgement: any such event is its end
            if ready.get(sock.fileno(), 0) & select.POLLOUT:
                outbox.pump()
            outbox.pump_deferred()
        if not end.closed.is_set():
            log.info("link to %s.%s: the sink's ipc socket closed; reconnecting", end.sink_task, end.sink_port)
    finally:
        outbox.close()  # waits for a pump in progress; what it held is lost, counted
        end.wake()  # what the port's storage holds goes by the next connection
        _ipc.close_quietly(sock)
        wake_r.close()
        wake_w.close()

