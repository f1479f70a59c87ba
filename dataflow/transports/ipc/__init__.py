"""Transport ``ipc``: the same-host fast path (registered as the ``scart.transports``
entry point ``ipc``; rank 10, so ``auto`` tries it first).

gRPC stays the control plane: a peer asks for a one-time ticket with ``OpenIpcWriter`` (a
link into an input port; role ``operate``) or ``OpenIpcReader`` (a subscription of an
output port; role ``read``), connects to the deployer's abstract Unix socket
(``SOCK_SEQPACKET``, Linux only), sends the ticket as its first frame and waits for the
deployer's first message (a link's first report, or a subscription's "connected"
heartbeat). Then samples flow: a link's ``LinkRequest`` frames one way and its
``LinkResponse`` s back; a subscription's ``SubscribeResponse`` frames.

Every ipc socket of a process is read by its one io thread (:mod:`._hub`, RTT's mqueue
dispatcher); a sample is sent from the writer's own thread, encoded once for every
reader of its port. It declines (``auto`` goes on to gRPC) when the two ends are not on
one host, or the peer has no ipc; a policy naming ``ipc`` gets an error saying why.

Transport ``shm`` (:mod:`.shm`) is this one with large samples in shared memory: the
same tickets, socket and io thread, registered under a name of its own.

Both halves are here: this module and :mod:`._conns` connect; a deployer hands out
tickets (:mod:`._tickets`, its serving half) and serves their connections (:mod:`._serve`).
The one io thread is :mod:`._hub`, the socket and its frames :mod:`._wire`; shm's slots
are :mod:`._slots`, its connections :mod:`._shm_conns` (connecting) and
:mod:`._shm_serve` (serving).

Why a socket and not a shared-memory ring: a ring still needs a kernel wake-up per
sample in Python (no spinning under the GIL), and a datagram socket is a bounded kernel
ring with that wake-up built in; an abstract socket has no file to clean up.
"""

from __future__ import annotations

import logging
import socket
from collections.abc import Callable
from typing import TYPE_CHECKING

from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from dataflow.transports import LinkRefused, Peer, Transport, TransportError, frames
from dataflow.transports._shared import SharedFeed, SharedStreams, carry_shared
from dataflow.transports.ends import ReaderEnd, WriterEnd
from dataflow.transports.ipc._conns import LinkOut, SubIn
from dataflow.transports.ipc._hub import Hub
from dataflow.transports.ipc._wire import IpcUnavailable, available, connect, host_id

if TYPE_CHECKING:
    from dataflow.transports.serving import Serving

__all__ = ["IpcTransport", "REFUSED"]

log = logging.getLogger(__name__)

#: What ``OpenIpc*`` may answer that means "use gRPC" under transport ``auto``: an old
#: deployer, another host or platform, a deployer out of ipc room.
REFUSED = frozenset({"UNIMPLEMENTED", "FAILED_PRECONDITION", "RESOURCE_EXHAUSTED"})


class IpcTransport(Transport):
    """Samples over the deployer's abstract Unix socket, when both ends are on one host."""

    name = "ipc"
    rank = 10
    carries = frozenset({"link", "subscription"})
    waits = True

    #: What it asks the deployer for (OpenIpcWriterRequest.shm...): a socket alone, here.
    shm = False

    def __init__(self) -> None:
        self._streams = SharedStreams()  # the subscriptions' sockets open, shared by subscriptions alike

    def link(self, end: WriterEnd, peer: Peer) -> bool:
        return self._link(end, peer, LinkOut)

    def _link(self, end: WriterEnd, peer: Peer, conn_class: Callable[[Hub, socket.socket, WriterEnd], LinkOut]) -> bool:
        """:meth:`link`, its connection made by ``conn_class`` (a :class:`LinkOut`)."""
        hello = frames.link_hello(end, peer)
        request = pb.OpenIpcWriterRequest(task=peer.task, port=peer.port, policy=peer.policy_msg,
                                          host_id=host_id(), hello=hello, shm=self.shm)
        opened = _open(lambda: peer.stub.OpenIpcWriter(request, timeout=peer.timeout), end.policy.transport, peer,
                       self.name)
        if opened is None:
            return False
        sock, first = opened
        report = pb.LinkResponse.FromString(first)
        if report.refused:
            sock.close()
            raise LinkRefused(report.refused)
        conn = conn_class(Hub.acquire(), sock, end)
        # connected first: a new reader end's first report must not replace the old one's
        # counts before the writer end has kept them (a restarted sink)
        end.connected(self.name, conn, new_peer=not report.known)
        end.report(report.last, report.lost, report.pending)
        conn.start()
        try:
            if peer.opened(conn.close, finish=conn.finish):
                conn.ended.wait()
        finally:
            conn.close()
            end.disconnected()
        return True

    def serving(self) -> type[Serving]:
        """ipc's and shm's serving half: the tickets of ``OpenIpcWriter`` and ``OpenIpcReader``."""
        from dataflow.transports.ipc._tickets import IpcServing

        return IpcServing

    def subscribe(self, end: ReaderEnd, peer: Peer) -> bool:
        """Feed ``end`` from the peer's port: one socket, read by the io thread and shared
        by the subscriptions of this system proxy to that port with the same policy (see
        :mod:`~dataflow.transports._shared`)."""
        return self._subscribe(end, peer, SubIn)

    def _subscribe(self, end: ReaderEnd, peer: Peer, conn_class: Callable[[Hub, socket.socket, SharedFeed, str], SubIn]) -> bool:
        """:meth:`subscribe`, its connection made by ``conn_class`` (a :class:`SubIn`)."""
        request = pb.OpenIpcReaderRequest(task=peer.task, port=peer.port, policy=peer.policy_msg, host_id=host_id(),
                                          heartbeat_ms=int(peer.heartbeat * 1000), shm=self.shm)

        def open_stream(feed: SharedFeed) -> bool:
            opened = _open(lambda: peer.stub.OpenIpcReader(request, timeout=peer.timeout), peer.transport, peer,
                           self.name)
            if opened is None:
                return False
            sock, first = opened
            conn = conn_class(Hub.acquire(), sock, feed, f"subscription to {peer.where}")
            feed.close = conn.close
            conn.message(first)  # the "connected" heartbeat
            conn.start()
            return True

        return carry_shared(self.name, self._streams, request, end, peer, open_stream)


def _open(ask: Callable[[], pb.OpenIpcWriterResponse | pb.OpenIpcReaderResponse], transport: str, peer: Peer,
          name: str = "ipc") -> tuple[socket.socket, bytes] | None:
    """Ask the deployer for a ticket and connect with it: the socket (non-blocking) and the
    deployer's first message. None when the transport ``name`` does not work between the
    two ends and the policy (``auto``) lets another transport do; with ``name`` named, that
    raises :class:`TransportError` saying why. Other failures of ``ask`` propagate."""
    import grpc

    try:
        if not available():
            raise IpcUnavailable("no ipc on this platform")
        try:
            reply = ask()
        except grpc.RpcError as exc:
            if exc.code().name not in REFUSED:
                raise
            raise IpcUnavailable(exc.details() or exc.code().name) from None
        return connect(reply.ticket.socket, reply.ticket.secret, peer.timeout, peer.cancelled)
    except IpcUnavailable as exc:
        if transport == name:
            raise TransportError(f"transport {name} to {peer.where}: {exc}") from None
        return None
