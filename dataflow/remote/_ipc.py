"""The same-host fast path, transport ``ipc`` (private; used by the deployer server, its
cross-deployer links and gRPC subscriptions).

gRPC stays the control plane: a peer asks for a one-time ticket with ``OpenIpcWriter``
(samples *into* an input port; role ``operate``) or ``OpenIpcReader`` (samples *out of*
an output port; role ``read``), connects to the deployer's abstract Unix socket
(``SOCK_SEQPACKET``: one frame per datagram, Linux only) and sends the ticket as its first
frame. Frames are the gRPC path's own messages: ``WritePortStreamRequest`` (a value) into
a port, ``SubscribeResponse`` (samples with their write numbers, heartbeats, the drop
count) out of one.

Why a socket and not a shared-memory ring: a ring still needs a kernel wake-up per
sample in Python (no spinning under the GIL), and a datagram socket is a bounded kernel
ring with that wake-up built in. It also costs nothing to clean: an abstract socket has
no file (nothing in ``/dev/shm`` or on disk) and the kernel closes it with its process,
even a killed one; the other side then sees the end of its stream (or, for a frozen
peer, no heartbeat) and reconnects, over gRPC if ipc no longer works.

The writer never blocks: a sample is sent from the writing thread with ``MSG_DONTWAIT``.
When the socket is full (a slow or frozen reader), the samples stay in the connection's
policy storage, which keeps, overwrites or drops them as the policy says and counts the
drops (one place, as for a local connection), and go once the socket has room again.
Frames larger than :data:`MAX_FRAME` are dropped and counted (say ``transport="grpc"``
for such ports).

Bounds: at most :data:`MAX_CONNECTIONS` connections per deployer, :data:`MAX_TICKETS`
tickets pending, each valid :data:`TICKET_S` s, used once; a connection that sends no
valid ticket within :data:`HELLO_S` s is closed.
"""

from __future__ import annotations

import logging
import secrets
import selectors
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from dataflow import codec
from dataflow.policy import ConnPolicy, FlowStatus
from dataflow.ports import InputPort, OutputPort
from dataflow.remote._proto import df as pb

__all__ = ["IpcServer", "IpcUnavailable", "Outbox", "available", "close_quietly", "connect", "frames_in", "host_id"]

log = logging.getLogger(__name__)

MAX_FRAME = 200 * 1024  #: bytes of one frame (below the default socket buffer, so a frame always fits)
MAX_CONNECTIONS = 256
MAX_TICKETS = 1024
TICKET_S = 10.0
HELLO_S = 2.0
TICKET_BYTES = 16
_NEW = FlowStatus.NEW_DATA


class IpcUnavailable(Exception):
    """The fast path cannot be used between these two ends (another host or network
    namespace, another platform, a peer without it): use gRPC."""


def available() -> bool:
    """Whether this platform has the fast path (Linux abstract Unix sockets)."""
    return sys.platform.startswith("linux")


def host_id() -> str:
    """This host's identity (its kernel boot id): two ends with the same one may use ipc."""
    try:
        with open("/proc/sys/kernel/random/boot_id", encoding="ascii") as f:
            return f.read(64).strip()
    except OSError:
        return ""


def connect(name: str, ticket: bytes, timeout: float = 2.0) -> socket.socket:
    """Connect to a deployer's socket ``name`` and present ``ticket``; the connected socket
    (blocking). Raises :class:`IpcUnavailable` when it cannot be reached from here."""
    if not available() or not name:
        raise IpcUnavailable("no ipc on this platform")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    try:
        sock.settimeout(timeout)
        sock.connect("\0" + name)
        sock.send(ticket)
        sock.settimeout(None)
        return sock
    except OSError as exc:
        sock.close()
        raise IpcUnavailable(f"cannot reach the deployer's socket: {exc}") from None


def close_quietly(sock: socket.socket) -> None:
    """Shut down (wakes a thread blocked in ``recv`` on it) and close."""
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    sock.close()


class Outbox:
    """The samples of ``inp`` (a free InputPort whose connection has the link's policy:
    the one place where DATA / BUFFER / CIRCULAR_BUFFER keep, overwrite and count) sent
    as frames over ``sock`` without ever blocking the writer. :meth:`pump` runs in the
    writer's thread; when the socket is full it keeps the frames made so far, leaves the
    rest to the policy's storage and calls ``want_write`` (the owner calls :meth:`pump`
    again once the socket is writable). ``encode(values)`` makes the frames; a frame
    larger than :data:`MAX_FRAME`, or one for a broken socket, is dropped and counted in
    :attr:`dropped`; a broken socket calls ``on_broken`` once."""

    def __init__(self, inp: InputPort, sock: socket.socket, encode: Callable[[list[Any]], list[bytes]],
                 want_write: Callable[[], None], on_broken: Callable[[], None]) -> None:
        self.inp = inp
        self.sock = sock
        self.dropped = 0
        self.broken = False
        self.blocked = False
        self._encode = encode
        self._want_write = want_write
        self._on_broken = on_broken
        self._held: deque[bytes] = deque()
        self.lock = threading.Lock()

    def pump(self) -> None:
        """Send what is held, then what the port's storage holds, until empty or full."""
        read = self.inp.read
        held = self._held
        with self.lock:
            for _ in range(10_000):
                while held:
                    if not self._send(held[0]):
                        self._want_write()
                        return
                    held.popleft()
                status, value = read()
                if status is not _NEW:
                    return
                values = [value]
                for _ in range(63):
                    status, value = read()
                    if status is not _NEW:
                        break
                    values.append(value)
                frames = self._encode(values)
                if len(frames) == 1 and self._send(frames[0]):  # the usual case: one sample, room
                    continue
                held.extend(frames)

    @property
    def pending(self) -> int:
        """Frames made and not sent yet (waiting for room)."""
        return len(self._held)

    def send_now(self, frame: bytes) -> None:
        """Send one control frame (a heartbeat) unless samples are waiting for room."""
        with self.lock:
            if not self._held:
                self._send(frame)

    def _send(self, frame: bytes) -> bool:
        """True when ``frame`` is done with (sent, or dropped and counted); False when the
        socket is full (:attr:`blocked`)."""
        if self.broken:
            self.dropped += 1
            return True
        if len(frame) > MAX_FRAME:
            self.dropped += 1
            log.warning("a sample of %d bytes encoded is larger than an ipc frame (%d); dropped "
                        "(use transport 'grpc' for such ports)", len(frame), MAX_FRAME)
            return True
        try:
            self.sock.send(frame, socket.MSG_DONTWAIT)
            self.blocked = False
            return True
        except BlockingIOError:  # the reader is behind: its socket is full
            self.blocked = True
            return False
        except OSError:  # the peer is gone
            self.dropped += 1
            self.broken = True
            self._on_broken()
            return True


class _ReaderEnd:
    """An output port's samples going to one reader over a socket: a free InputPort with
    the reader's policy, connected to the port; its data callback (the writer's thread)
    sends what it reads at once, through an :class:`Outbox`."""

    def __init__(self, server: IpcServer, sock: socket.socket, port: OutputPort, policy: ConnPolicy) -> None:
        self.server = server
        self.sock = sock
        self.port = port
        self.sent_at = time.monotonic()
        self._seq = 0
        self.inp: InputPort = InputPort(port.type, name=f"ipc_{port.name}")
        self.outbox = Outbox(self.inp, sock, self._frames, lambda: server.want_write(self),
                             lambda: server.detach_later(self))
        with self.outbox.lock:  # the "connected" heartbeat goes before any sample
            self.connection = port.connect_to(self.inp, policy)
            self.outbox._send(pb.SubscribeResponse(heartbeat=True, boot_id=server.boot_id).SerializeToString())
        self.inp.add_data_callback(self._on_data)
        self._on_data(self.inp)  # an init=True policy may have handed a sample over already

    @property
    def dropped(self) -> int:
        return self.connection.dropped + self.outbox.dropped

    def _frames(self, values: list[Any]) -> list[bytes]:
        """Frames of ``values`` just read: called right after the writes, so the newest is
        the port's latest write number (as :class:`~dataflow.remote._inbox.Inbox` tags them)."""
        newest = max(self.port.last_sample()[0], self._seq + len(values))
        self._seq = newest
        now = time.time_ns()
        return [pb.SubscribeResponse(samples=[pb.Sample(value=codec.encode(value, self.port.type),
                                                         sequence=newest - len(values) + 1 + k, source_time_ns=now)],
                                     dropped=self.dropped).SerializeToString()
                for k, value in enumerate(values)]

    def _on_data(self, _inp: InputPort) -> None:  # the writer's thread: never blocks for long
        self.outbox.pump()
        self.sent_at = time.monotonic()

    def heartbeat(self) -> None:
        self.outbox.send_now(pb.SubscribeResponse(heartbeat=True, dropped=self.dropped).SerializeToString())
        self.sent_at = time.monotonic()

    def close(self) -> None:
        self.port.disconnect(self.inp)
        self.inp.remove_data_callback(self._on_data)
        close_quietly(self.sock)


class IpcServer:
    """A deployer's ipc socket: tickets, connections, and one thread that accepts, reads
    tickets, notices readers gone and sends their heartbeats. Connections that carry
    samples *in* each get a thread of their own (blocking reads: the lowest latency).
    ``write_in(task, port, policy)`` makes the sink of such a connection: a callable
    taking each frame's ``Value`` message, and a ``close``."""

    def __init__(self, boot_id: str, heartbeat: float,
                 write_in: Callable[[str, str, ConnPolicy], tuple[Callable[[Any], None], Callable[[], None]]],
                 output_port: Callable[[str, str], OutputPort]) -> None:
        self.boot_id = boot_id
        self.name = f"scart-{boot_id}-{secrets.token_hex(8)}"
        self.heartbeat = heartbeat
        self._write_in = write_in
        self._output_port = output_port
        self._lock = threading.Lock()
        self._tickets: dict[bytes, tuple[float, str, str, str, ConnPolicy]] = {}
        self._readers: dict[socket.socket, _ReaderEnd] = {}
        self._pending: dict[socket.socket, float] = {}  # accepted, ticket not read yet
        self._pumps: dict[socket.socket, threading.Thread] = {}
        self._broken: list[_ReaderEnd] = []
        self._blocked: list[_ReaderEnd] = []
        self._stopping = threading.Event()
        self._listener = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self._listener.bind("\0" + self.name)
        self._listener.listen(64)
        self._listener.setblocking(False)
        self._wake_r, self._wake_w = socket.socketpair()
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._listener, selectors.EVENT_READ, "accept")
        self._selector.register(self._wake_r, selectors.EVENT_READ, "wake")
        self._thread = threading.Thread(target=self._run, name="scart-ipc", daemon=True)
        self._thread.start()

    @property
    def connections(self) -> int:
        with self._lock:
            return len(self._readers) + len(self._pumps) + len(self._pending)

    def ticket(self, kind: str, task: str, port: str, policy: ConnPolicy) -> bytes:
        """A one-time ticket for a connection of ``kind`` (``in``: into the input port
        ``task.port``; ``out``: out of the output port). Raises ``OverflowError`` past the bounds."""
        now = time.monotonic()
        with self._lock:
            for key in [k for k, t in self._tickets.items() if t[0] < now]:
                del self._tickets[key]
            if len(self._tickets) >= MAX_TICKETS:
                raise OverflowError(f"{MAX_TICKETS} ipc tickets are pending")
            if len(self._readers) + len(self._pumps) >= MAX_CONNECTIONS:
                raise OverflowError(f"this deployer serves at most {MAX_CONNECTIONS} ipc connections")
            ticket = secrets.token_bytes(TICKET_BYTES)
            self._tickets[ticket] = (now + TICKET_S, kind, task, port, policy)
            return ticket

    # ---- the io thread -------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stopping.is_set():
            try:
                events = self._selector.select(timeout=self.heartbeat / 2)
            except OSError:
                return
            for key, mask in events:
                what = key.data
                try:
                    if what == "accept":
                        self._accept()
                    elif what == "hello":
                        self._hello(key.fileobj)  # type: ignore[arg-type]
                    elif what == "reader":
                        self._reader_event(key.fileobj, mask)  # type: ignore[arg-type]
                    elif what == "wake":
                        self._wake_r.recv(64)
                except Exception:  # noqa: BLE001 - the io thread must not die
                    log.exception("ipc: handling a connection failed")
            self._housekeeping()

    def _accept(self) -> None:
        for _ in range(64):
            try:
                conn, _ = self._listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            with self._lock:
                full = len(self._pending) + len(self._readers) + len(self._pumps) >= MAX_CONNECTIONS + 16
                if not full:
                    self._pending[conn] = time.monotonic() + HELLO_S
            if full:
                conn.close()
                continue
            conn.setblocking(False)
            self._selector.register(conn, selectors.EVENT_READ, "hello")

    def _hello(self, conn: socket.socket) -> None:
        self._selector.unregister(conn)
        with self._lock:
            self._pending.pop(conn, None)
        try:
            ticket = conn.recv(64)
        except OSError:
            ticket = b""
        with self._lock:
            entry = self._tickets.pop(ticket, None) if len(ticket) == TICKET_BYTES else None
        if entry is None or entry[0] < time.monotonic() or self._stopping.is_set():
            conn.close()
            return
        _, kind, task, port, policy = entry
        try:
            if kind == "out":
                conn.setblocking(True)
                end = _ReaderEnd(self, conn, self._output_port(task, port), policy)
                with self._lock:
                    self._readers[conn] = end
                self._selector.register(conn, selectors.EVENT_READ, "reader")
            else:
                write, close = self._write_in(task, port, policy)
                conn.setblocking(True)
                pump = threading.Thread(target=self._pump, args=(conn, write, close), daemon=True,
                                        name=f"scart-ipc-in-{task}.{port}")
                with self._lock:
                    self._pumps[conn] = pump
                pump.start()
        except Exception as exc:  # noqa: BLE001 - the port went away meanwhile: the peer sees the close
            log.info("ipc: %s.%s cannot be served: %s", task, port, exc)
            conn.close()

    def _reader_event(self, conn: socket.socket, mask: int) -> None:
        """A reader sends nothing after its ticket: readable means gone (or misbehaving);
        writable means room for what its outbox holds."""
        with self._lock:
            end = self._readers.get(conn)
        if end is None:
            return
        if mask & selectors.EVENT_READ:
            self.detach(end)
            return
        self._selector.modify(conn, selectors.EVENT_READ, "reader")
        end.outbox.pump()  # full again: want_write registers it again

    def detach_later(self, end: _ReaderEnd) -> None:
        """Detach ``end`` from the io thread (its socket broke in a writer's thread, which
        must not disconnect ports while it writes)."""
        with self._lock:
            self._broken.append(end)
        try:
            self._wake_w.send(b"x", socket.MSG_DONTWAIT)
        except OSError:
            pass

    def want_write(self, end: _ReaderEnd) -> None:
        """``end``'s socket is full: the io thread pumps it again once writable."""
        with self._lock:
            self._blocked.append(end)
        try:
            self._wake_w.send(b"x", socket.MSG_DONTWAIT)
        except OSError:
            pass

    def detach(self, end: _ReaderEnd) -> None:
        """Stop serving a reader (gone, or its socket broke). Idempotent, any thread."""
        with self._lock:
            if self._readers.pop(end.sock, None) is None:
                return
        try:
            self._selector.unregister(end.sock)
        except (KeyError, ValueError, OSError):
            pass
        end.close()

    def _housekeeping(self) -> None:
        now = time.monotonic()
        with self._lock:
            late = [c for c, deadline in self._pending.items() if deadline < now]
            for conn in late:
                del self._pending[conn]
            idle = [e for e in self._readers.values() if now - e.sent_at >= self.heartbeat and not e.outbox.blocked]
            broken, self._broken = self._broken, []
            blocked, self._blocked = self._blocked, []
        for end in broken:
            self.detach(end)
        for end in blocked:
            with self._lock:
                live = end.sock in self._readers
            if live:
                self._selector.modify(end.sock, selectors.EVENT_READ | selectors.EVENT_WRITE, "reader")
        for conn in late:
            try:
                self._selector.unregister(conn)
            except (KeyError, ValueError):
                pass
            conn.close()
        for end in idle:
            end.heartbeat()

    def _pump(self, conn: socket.socket, write: Callable[[Any], None], close: Callable[[], None]) -> None:
        """Frames into an input port until the peer closes (or the server stops)."""
        try:
            while not self._stopping.is_set():
                try:
                    frame = conn.recv(MAX_FRAME)
                except OSError:
                    break
                if not frame:
                    break
                try:
                    msg = pb.WritePortStreamRequest.FromString(frame)
                    if msg.value.type_name:
                        write(msg.value)
                except Exception as exc:  # noqa: BLE001 - one bad frame never ends the link; said once per ...
                    log.warning("ipc: a sample refused: %s", exc)
        finally:
            close()
            with self._lock:
                self._pumps.pop(conn, None)
            conn.close()

    def stop(self) -> None:
        """Close the socket and every connection; end the threads (idempotent)."""
        if self._stopping.is_set():
            return
        self._stopping.set()
        try:
            self._wake_w.send(b"x")
        except OSError:
            pass
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=5.0)
        with self._lock:
            readers = list(self._readers.values())
            pumps = dict(self._pumps)
            pending = list(self._pending)
            self._readers.clear()
            self._pending.clear()
            self._tickets.clear()
        for end in readers:
            end.close()
        for conn in pending:
            conn.close()
        for conn, thread in pumps.items():
            try:
                conn.shutdown(socket.SHUT_RDWR)  # wakes its pump
            except OSError:
                pass
            thread.join(timeout=5.0)
        self._selector.close()
        self._listener.close()
        self._wake_r.close()
        self._wake_w.close()


def frames_in(sock: socket.socket, timeout: float | None) -> Any:
    """The frames a reader receives, until the peer closes (or ``socket.timeout`` after
    ``timeout`` s of silence: a frozen peer)."""
    sock.settimeout(timeout)
    while True:
        frame = sock.recv(MAX_FRAME)
        if not frame:
            return
        yield frame

