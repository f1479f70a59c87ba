"""A deployer's side of ipc (private): its socket, the tickets it hands out through the
control plane, and the connections they open — links coming in (a reader end each) and
subscriptions going out (a writer end each), all read by the process's one io thread.

Bounds: only processes of this deployer's user may connect (``SO_PEERCRED``); at most
:data:`MAX_PENDING` connections without a ticket yet (the oldest is closed for a new one),
each closed after :data:`HELLO_S` s; at most :data:`MAX_CONNECTIONS` connections;
:data:`MAX_TICKETS` tickets pending (:data:`TICKETS_PER_PEER` per peer), each valid
:data:`TICKET_S` s, used once.
"""

from __future__ import annotations

import logging
import os
import secrets
import socket
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from dataflow.policy import ConnPolicy
from scart_wire import codec
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from dataflow.transports import frames
from dataflow.transports.ipc._hub import Conn, Encode, Hub
from dataflow.transports.ipc._wire import WHOLE
from dataflow.transports.sinks import LINGER_S, REPORT_EVERY, REPORT_S, IncomingLink, Refused, Sinks
from dataflow.transports.served import Served

__all__ = ["Flavour", "IpcServer", "MAX_CONNECTIONS"]

log = logging.getLogger(__name__)

MAX_CONNECTIONS = 256
MAX_PENDING = 32
MAX_TICKETS = 1024
TICKETS_PER_PEER = 64
TICKET_S = 10.0
HELLO_S = 2.0
TICKET_BYTES = 16
STOP_S = 1.0  #: how long a stop waits for each connection's last report and end, at most


@dataclass(frozen=True)
class _Ticket:
    expires: float
    peer: str
    kind: str  # "in": a link into an input port; "out": a subscription of an output port
    request: pb.OpenIpcWriterRequest | pb.OpenIpcReaderRequest
    policy: ConnPolicy
    heartbeat: float
    who: str


class Flavour:
    """The connections of a transport that rides on ipc's socket (``shm``: its large
    samples in shared memory): what a ticket asking for it (``request.shm``) opens."""

    def link_in(self, hub: Hub, sock: socket.socket, server: IpcServer, link: IncomingLink, known: bool) -> Conn:
        """A link coming in (default: ipc's own)."""
        return _LinkIn(hub, sock, server, link, known)

    def reader_out(self, hub: Hub, sock: socket.socket, server: IpcServer, served: Served, heartbeat: float) -> Conn:
        """A subscription going out (default: ipc's own)."""
        return _ReaderOut(hub, sock, server, served, heartbeat)


class IpcServer:
    """A deployer's ipc socket (see the module docstring). ``sinks`` are the deployer's
    incoming links; ``serve(task, port, policy, who, shm)`` makes the :class:`Served` writer
    end of a new subscription, ``unserve(served)`` ends it; ``shm``: the connections of
    tickets that ask for shared memory."""

    def __init__(self, boot_id: str, sinks: Sinks, serve: Callable[[str, str, ConnPolicy, str, bool], Served],
                 unserve: Callable[[Served], None], shm: Flavour | None = None) -> None:
        self.boot_id = boot_id
        self._plain = Flavour()
        self._shm = shm  # the shm transport's connections, when it is installed
        self.name = f"scart-{boot_id}-{secrets.token_hex(8)}"
        self.sinks = sinks
        self._serve = serve
        self._unserve = unserve
        self._lock = threading.Lock()
        self._tickets: dict[bytes, _Ticket] = {}
        self._conns: set[Conn] = set()
        self._pending: dict[socket.socket, float] = {}  # accepted, no ticket yet (oldest first)
        self._stopping = False
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        try:
            sock.bind("\0" + self.name)
            sock.listen(64)
        except BaseException:
            sock.close()
            raise
        self.hub = Hub.acquire()
        self._listener = _Listener(self.hub, sock, self)
        self._listener.start()

    @property
    def connections(self) -> int:
        with self._lock:
            return len(self._conns)

    def ticket(self, kind: str, request: pb.OpenIpcWriterRequest | pb.OpenIpcReaderRequest, policy: ConnPolicy,
               peer: str, heartbeat: float = 0.5, who: str = "") -> bytes:
        """A one-time ticket for a connection of ``kind`` (``in`` or ``out``) asked by
        ``request``, for ``peer`` (its key for the per-peer bounds; ``who``: its address).
        Raises ``OverflowError`` naming the bound past it."""
        now = time.monotonic()
        with self._lock:
            for key in [k for k, t in self._tickets.items() if t.expires < now]:
                del self._tickets[key]
            if len(self._tickets) >= MAX_TICKETS:
                raise OverflowError(f"{MAX_TICKETS} ipc tickets are pending")
            if sum(1 for t in self._tickets.values() if t.peer == peer) >= TICKETS_PER_PEER:
                raise OverflowError(f"{TICKETS_PER_PEER} ipc tickets of this peer are pending")
            if len(self._conns) >= MAX_CONNECTIONS:
                raise OverflowError(f"this deployer serves at most {MAX_CONNECTIONS} ipc connections")
            secret = secrets.token_bytes(TICKET_BYTES)
            self._tickets[secret] = _Ticket(now + TICKET_S, peer, kind, request, policy, heartbeat, who)
            return secret

    # ---- the io thread ------------------------------------------------------------------
    def accepted(self, conn: socket.socket) -> None:
        uid = struct.unpack("3i", conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i")))[1]
        if uid != os.getuid():  # an abstract socket has no permissions: ours only
            conn.close()
            return
        conn.setblocking(False)
        with self._lock:
            oldest = next(iter(self._pending)) if len(self._pending) >= MAX_PENDING else None
            if oldest is not None:
                del self._pending[oldest]
            self._pending[conn] = time.monotonic() + HELLO_S
        if oldest is not None:
            self._listener.forget_pending(oldest)
        self._listener.watch_pending(conn)

    def hello(self, conn: socket.socket) -> None:
        """A pending connection spoke: its ticket opens a link or a subscription."""
        with self._lock:
            self._pending.pop(conn, None)
        try:
            secret = conn.recv(64)
        except OSError:
            secret = b""
        with self._lock:
            ticket = self._tickets.pop(secret, None) if len(secret) == TICKET_BYTES else None
            full = len(self._conns) >= MAX_CONNECTIONS
        if ticket is None or ticket.expires < time.monotonic() or full or self._stopping:
            conn.close()
            return
        try:
            made = self._link_in(conn, ticket) if ticket.kind == "in" else self._reader_out(conn, ticket)
        except Exception as exc:  # noqa: BLE001 - the port went away meanwhile: the peer sees the close
            log.info("ipc: %s cannot be served: %s", ticket.request.task, exc)
            conn.close()
            return
        with self._lock:
            self._conns.add(made)
        made.start()

    def _link_in(self, sock: socket.socket, ticket: _Ticket) -> Conn:
        if not isinstance(ticket.request, pb.OpenIpcWriterRequest):
            raise TypeError("a link's ticket was not asked for by OpenIpcWriter")
        hello = ticket.request.hello
        try:
            link, known = self.sinks.open(hello, ticket.policy)
        except Refused as exc:
            sock.send(WHOLE + pb.LinkResponse(refused=str(exc)).SerializeToString())  # before the io thread owns it
            raise
        return self._flavour(ticket).link_in(Hub.acquire(), sock, self, link, known)

    def _reader_out(self, sock: socket.socket, ticket: _Ticket) -> Conn:
        request = ticket.request
        served = self._serve(request.task, request.port, ticket.policy, ticket.who, bool(request.shm))
        return self._flavour(ticket).reader_out(Hub.acquire(), sock, self, served, ticket.heartbeat)

    def _flavour(self, ticket: _Ticket) -> Flavour:
        return self._shm if ticket.request.shm and self._shm is not None else self._plain

    def housekeeping(self, now: float) -> None:
        with self._lock:
            late = [c for c, deadline in self._pending.items() if deadline < now]
            for conn in late:
                del self._pending[conn]
        for conn in late:
            self._listener.forget_pending(conn)

    def forget(self, conn: Conn) -> None:
        with self._lock:
            self._conns.discard(conn)

    def stop(self) -> None:
        """Close the socket and every connection (idempotent)."""
        with self._lock:
            if self._stopping:
                return
            self._stopping = True
            conns = list(self._conns)
            pending = list(self._pending)
            self._conns.clear()
            self._pending.clear()
            self._tickets.clear()
        for conn in conns:
            if isinstance(conn, _LinkIn):
                conn.stop()
            else:
                conn.close()
        for conn in conns:
            conn.ended.wait(STOP_S)
        for sock in pending:
            self._listener.forget_pending(sock)
        self._listener.close()


class _Listener(Conn):
    """The deployer's listening socket; pending connections until their ticket comes."""

    def __init__(self, hub: Hub, sock: socket.socket, server: IpcServer) -> None:
        super().__init__(hub, sock, f"listener {server.name}")
        self.server = server

    def readable(self) -> None:
        for _ in range(64):
            try:
                conn, _ = self.sock.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            self.server.accepted(conn)

    def watch_pending(self, conn: socket.socket) -> None:
        self.hub.call_soon(lambda: self.hub.watch(conn, _Pending(self.server, conn)))

    def forget_pending(self, conn: socket.socket) -> None:
        def drop() -> None:
            self.hub.unwatch(conn)
            conn.close()
        self.hub.call_soon(drop)

    def tick(self, now: float) -> None:
        self.server.housekeeping(now)


class _Pending:
    """A connection waiting for its ticket (not a :class:`Conn`: it holds no hub reference)."""

    def __init__(self, server: IpcServer, sock: socket.socket) -> None:
        self.server = server
        self.sock = sock
        self.ended = threading.Event()

    def readable(self) -> None:
        self.server.hub.unwatch(self.sock)
        self.server.hello(self.sock)

    def writable(self) -> None:
        pass

    def tick(self, now: float) -> None:
        pass


class _LinkIn(Conn):
    """A link coming in: frames into its reader end; reports back (see :mod:`~dataflow.transports.sinks`)."""

    def __init__(self, hub: Hub, sock: socket.socket, server: IpcServer, link: IncomingLink, known: bool) -> None:
        super().__init__(hub, sock, link.end.label)
        self.server = server
        self.link = link
        self.known = known
        self._unreported = 0
        self._reported: tuple[int, int, int] = (-1, -1, -1)
        self._reported_at = 0.0
        self._closing_at: float | None = None
        self._finished = False
        self.link.end.transport = "ipc"

    def start(self) -> None:
        self.put(frames.report_of(self.link.end, known=self.known).SerializeToString())  # the first message: accepted
        if self.link.waits:  # a read that frees room is reported at once: the writer waits for it
            self.link.on_room = self._on_room
        super().start()

    def message(self, data: bytes) -> None:
        frame = self.request(data)
        if frame is not None:
            self.took(frame)

    def request(self, data: bytes) -> pb.LinkRequest | None:
        """``data`` as the writer's link request; None, counted with the malformed, when it is not one."""
        try:
            return pb.LinkRequest.FromString(data)
        except Exception:  # noqa: BLE001 - not a frame: counted with the malformed ones
            self._assembler.dropped += 1
            return None

    def took(self, frame: pb.LinkRequest, values: dict[int, codec.Payload] | None = None) -> None:
        """One frame of the link (``values``: see :func:`~dataflow.transports.frames.feed`)."""
        self._unreported += frames.feed(self.link.end, frame, values) + 1
        if frame.closing:
            self._closing_at = time.monotonic() + LINGER_S
            self.tick(time.monotonic())
        elif self._unreported >= REPORT_EVERY or self.link.waits:  # a waiting writer: each sample reported
            self._report(time.monotonic())

    def _report(self, now: float, final: bool = False) -> None:
        end, pending = self.link.end, self.link.pending
        self.put(frames.report_of(end, final=final, pending=pending).SerializeToString())
        self._reported, self._reported_at, self._unreported = (end.last, end.lost, pending), now, 0

    def stop(self) -> None:
        """This deployer stops: a last report (the link's buffer counted already, see
        :meth:`~dataflow.transports.sinks.Sinks.close_all`), then the end (any thread)."""
        def last_report() -> None:
            if not self.ended.is_set():
                self._report(time.monotonic())
            self.close()
        self.hub.call_soon(last_report)

    def tick(self, now: float) -> None:
        if self._closing_at is not None:
            if self.link.pending and now < self._closing_at:
                return
            self._finished = True
            self.server.sinks.finish(self.link)  # what the task never read is counted now
            self._report(now, final=True)
            self._closing_at = None
            return
        end = self.link.end
        if (end.last, end.lost, self.link.pending) != self._reported and now - self._reported_at >= REPORT_S:
            self._report(now)  # a change the source would not know: the sink's buffer read too

    def _on_room(self) -> None:
        """The task read a sample of a link whose writer waits (its thread): report now."""
        self.hub.call_soon(lambda: None if self.ended.is_set() else self._report(time.monotonic()))

    def ended_hook(self) -> None:
        if self.link.on_room == self._on_room:  # a newer connection of the link keeps its own
            self.link.on_room = None
        if self.malformed:
            log.warning("ipc: %d malformed or oversized frame(s) for %s dropped", self.malformed, self.label)
        if not self._finished:
            self.server.sinks.carried(self.link)
        self.server.forget(self)


class _ReaderOut(Conn):
    """A subscription going out: the carrier of its writer end."""

    def __init__(self, hub: Hub, sock: socket.socket, server: IpcServer, served: Served, heartbeat: float) -> None:
        super().__init__(hub, sock, served.end.label)
        self.encode: Encode = frames.encoder(served.port.type)
        self.server = server
        self.served = served
        self.heartbeat = heartbeat

    def start(self) -> None:
        super().start()
        end = self.served.end  # "connected", first: from now on every write comes
        end.connected("ipc", self, new_peer=True, first=lambda: self.put(frames.connected(end, self.server.boot_id)))

    send = Conn.send_sample  # the carrier's send: the writer's thread (or the io thread's flush)

    def drained(self) -> None:
        self.served.end.flush()

    def tick(self, now: float) -> None:
        if now - self.sent_at >= self.heartbeat:
            sent_last, tail = self.served.end.tail_after()
            self.put(frames.heartbeat(dropped=tail, sent_last=sent_last))

    def ended_hook(self) -> None:
        self.server._unserve(self.served)
        self.server.forget(self)
