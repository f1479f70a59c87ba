"""The same-host fast path, transport ``ipc`` (private; used by the deployer server, its
cross-deployer links and gRPC subscriptions).

gRPC stays the control plane: a peer asks for a one-time ticket with ``OpenIpcWriter``
(samples *into* an input port; role ``operate``) or ``OpenIpcReader`` (samples *out of*
an output port; role ``read``), connects to the deployer's abstract Unix socket
(``SOCK_SEQPACKET``, Linux only), sends the ticket as its first frame and waits for the
deployer's first frame (an acknowledgement, or for a reader the "connected" heartbeat).
Messages are the gRPC path's own: ``WritePortStreamRequest`` (a value) into a port,
``SubscribeResponse`` (a sample with its write number, heartbeats, the drop count) out of
one. Each frame starts with one byte: 0 a whole message, 1 a part with more to come, 2
the last part; parts are at most :data:`CHUNK` bytes, a message at most
:data:`MAX_MESSAGE` (gRPC's limit; a larger one is dropped and counted).

Why a socket and not a shared-memory ring: a ring still needs a kernel wake-up per
sample in Python (no spinning under the GIL), and a datagram socket is a bounded kernel
ring with that wake-up built in. It also costs nothing to clean: an abstract socket has
no file (nothing in ``/dev/shm`` or on disk) and the kernel closes it with its process,
even a killed one; the other side then sees the end of its stream (or, for a frozen
peer, no heartbeat) and reconnects, over gRPC if ipc no longer works.

The writer never blocks: a sample is sent from the writing thread with ``MSG_DONTWAIT``,
and the writer never waits for a lock another thread holds (that thread sends for it).
A write less than :data:`SOON_S` after the last send is left to another thread (the
link's, or the io thread for a reader), which sends what came meanwhile in one message:
a periodic writer pays one send per sample and no thread hand-off, a fast one pays for
storing a sample and shares the sends.
When the socket is full (a slow or frozen reader), the samples wait in the connection's
policy storage — the link's input port, or a subscription's policy-shaped inbox, the same
as on the gRPC path — which keeps, overwrites or drops them as the policy says and counts
the drops, and go once the socket has room again.

Bounds: only processes of this deployer's user may connect (``SO_PEERCRED``); at most
:data:`MAX_PENDING` connections without a ticket yet (the oldest is closed for a new one),
each closed after :data:`HELLO_S` s; at most :data:`MAX_CONNECTIONS` connections;
:data:`MAX_TICKETS` tickets pending (:data:`TICKETS_PER_PEER` per peer), each valid
:data:`TICKET_S` s, used once.
"""

from __future__ import annotations

import errno
import logging
import os
import secrets
import selectors
import socket
import struct
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any

import grpc

from dataflow.policy import ConnPolicy
from dataflow.remote._proto import df as pb
from dataflow.remote._rpc import MAX_MESSAGE_BYTES

__all__ = ["REFUSED", "IpcServer", "IpcUnavailable", "Outbox", "available", "close_quietly", "connect", "host_id",
           "messages_in", "open_with"]

log = logging.getLogger(__name__)

CHUNK = 64 * 1024  #: bytes of a message in one frame, at most (well inside a socket's buffer)
BATCH_BYTES = 48 * 1024  #: samples sent to a reader together, at most (one frame)
#: A write this soon (s) after the last send to a reader (or an ipc link's sink) leaves
#: the send to another thread, which sends what came meanwhile together (writers faster
#: than 5 kHz); a slower, periodic writer sends from its own thread at once.
SOON_S = 200e-6
MAX_MESSAGE = MAX_MESSAGE_BYTES  #: bytes of one message, as on gRPC
MAX_CONNECTIONS = 256
MAX_PENDING = 32
MAX_TICKETS = 1024
TICKETS_PER_PEER = 64
TICKET_S = 10.0
HELLO_S = 2.0
TICKET_BYTES = 16
WHOLE, PART, LAST = b"\x00", b"\x01", b"\x02"
#: What ``OpenIpc*`` may answer that means "use gRPC" under transport ``auto``: an old
#: deployer, another host or platform, a deployer out of ipc room.
REFUSED = frozenset({"UNIMPLEMENTED", "FAILED_PRECONDITION", "RESOURCE_EXHAUSTED"})


class IpcUnavailable(Exception):
    """The fast path cannot be used between these two ends (another host or network
    namespace, another platform, a peer without it, a deployer out of room): use gRPC."""


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


def frames_of(message: bytes) -> list[bytes]:
    """The frames carrying ``message`` (see the module docstring)."""
    if len(message) <= CHUNK:
        return [WHOLE + message]
    parts = [message[i:i + CHUNK] for i in range(0, len(message), CHUNK)]
    return [PART + p for p in parts[:-1]] + [LAST + parts[-1]]


class Reassembler:
    """Messages out of frames, in order; a message too large, or a frame cut short
    (``MSG_TRUNC``) or out of place, is dropped and counted in :attr:`dropped`."""

    def __init__(self) -> None:
        self.dropped = 0
        self._parts: list[bytes] = []
        self._size = 0
        self._skipping = False  # the rest of a message already dropped

    def feed(self, frame: bytes, truncated: bool = False) -> bytes | None:
        kind, body = frame[:1], frame[1:]
        if truncated or kind not in (WHOLE, PART, LAST):
            self._drop(kind)
            return None
        if kind == WHOLE:
            if self._parts or self._skipping:  # the last message's end never came
                self.dropped += 1 if self._parts else 0
                self._parts, self._size, self._skipping = [], 0, False
            return body
        if self._skipping:
            if kind == LAST:
                self._skipping = False
            return None
        self._parts.append(body)
        self._size += len(body)
        if self._size > MAX_MESSAGE:
            self._drop(kind)
            return None
        if kind == PART:
            return None
        message = b"".join(self._parts)
        self._parts, self._size = [], 0
        return message

    def _drop(self, kind: bytes) -> None:
        self.dropped += 1
        self._parts, self._size = [], 0
        self._skipping = kind == PART


def messages_in(sock: socket.socket, timeout: float | None, assembler: Reassembler | None = None) -> Iterator[bytes]:
    """The messages a socket receives, until the peer closes (``TimeoutError`` after
    ``timeout`` s of silence: a frozen peer)."""
    assembler = assembler or Reassembler()
    sock.settimeout(timeout)
    while True:
        frame, _, flags, _ = sock.recvmsg(CHUNK + 1)
        if not frame:
            return
        message = assembler.feed(frame, bool(flags & socket.MSG_TRUNC))
        if message is not None:
            yield message


def connect(name: str, ticket: bytes, timeout: float = 2.0) -> tuple[socket.socket, bytes]:
    """Connect to a deployer's socket ``name``, present ``ticket`` and wait for its first
    message; the connected socket (blocking) and that message. Raises
    :class:`IpcUnavailable` when it cannot be reached from here or the deployer refuses."""
    if not available() or not name:
        raise IpcUnavailable("no ipc on this platform")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    try:
        sock.settimeout(timeout)
        sock.connect("\0" + name)
        sock.send(ticket)
        first = next(messages_in(sock, timeout), None)
        if first is None:
            raise IpcUnavailable("the deployer closed the connection (out of room, or the ticket expired)")
        sock.settimeout(None)
        return sock, first
    except (OSError, IpcUnavailable) as exc:
        sock.close()
        if isinstance(exc, IpcUnavailable):
            raise
        raise IpcUnavailable(f"cannot reach the deployer's socket: {exc}") from None


def open_with(ask: Callable[[], Any], transport: str, what: str,
              address: str = "") -> tuple[socket.socket, bytes, Any] | None:
    """Ask a deployer for a ticket (``ask()``: the ``OpenIpc*`` call, returning its reply)
    and connect with it: the socket, the deployer's first message and its reply. None when ipc does
    not work between the two ends and ``transport`` (``auto``) lets gRPC do; with ``ipc``
    that raises :class:`~dataflow.remote.errors.UnavailableError` naming ``what`` and why.
    Other failures of ``ask`` (the deployer unreachable, a refused token) propagate."""
    from dataflow.remote import errors

    try:
        if not available():
            raise IpcUnavailable("no ipc on this platform")
        try:
            reply = ask()
        except grpc.RpcError as exc:
            if exc.code().name not in REFUSED:  # type: ignore[attr-defined]
                raise
            raise IpcUnavailable(exc.details() or exc.code().name) from None  # type: ignore[attr-defined]
        sock, first = connect(reply.ticket.socket, reply.ticket.secret)
        return sock, first, reply
    except IpcUnavailable as exc:
        if transport == "ipc":
            raise errors.UnavailableError(f"transport ipc to {what}: {exc}", "FAILED_PRECONDITION", address) from None
        return None


def shutdown_quietly(sock: socket.socket) -> None:
    """Shut ``sock`` down, which wakes a thread blocked reading it (that thread closes it)."""
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass


def close_quietly(sock: socket.socket) -> None:
    """Shut down (wakes a thread blocked in ``recv`` on it) and close."""
    shutdown_quietly(sock)
    sock.close()


class Outbox:
    """Messages sent over ``sock`` without ever blocking the writer.

    ``take()`` returns the next samples waiting in the connection's policy storage (at
    most 64; empty when none), ``encode(samples)`` their messages. :meth:`pump` — called
    in the writer's thread after each write, and by the owner when the socket has room
    again — sends until the storage is empty or the socket full. Whoever finds another
    thread pumping leaves the work to it and returns at once. When the socket is full,
    the frames made so far are held (at most one batch) and ``want_write`` is called once;
    the rest waits in the storage. A message larger than :data:`MAX_MESSAGE`, and the
    messages held when the socket breaks, are dropped and counted in :attr:`dropped`; a
    broken socket calls ``on_broken`` once and leaves the storage alone.

    The writer calls :meth:`offer`: with ``defer`` (the owner has a thread of its own), a
    write less than :data:`SOON_S` after the last send calls ``defer`` (once per round)
    and leaves the send to that thread's :meth:`pump_deferred`, which sends what came
    meanwhile together."""

    def __init__(self, sock: socket.socket, take: Callable[[], list[Any]], encode: Callable[[list[Any]], list[bytes]],
                 want_write: Callable[[], None], on_broken: Callable[[], None],
                 defer: Callable[[], None] | None = None) -> None:
        self.sock = sock
        self.dropped = 0
        self.broken = False
        self.blocked = False
        self.closed = False
        self._take = take
        self._encode = encode
        self._want_write = want_write
        self._on_broken = on_broken
        self._defer = defer
        self._deferred = False  # defer was called, pump_deferred not yet
        self._held: deque[bytes] = deque()
        self.sent_at = 0.0  #: ``time.monotonic()`` of the last frame sent
        self._more = False
        self._warned = False
        self.lock = threading.Lock()

    @property
    def pending(self) -> int:
        """Messages made and not sent yet (waiting for room)."""
        return sum(1 for frame in self._held if frame[:1] != PART)

    def pump(self) -> None:
        """Send what is held, then what the storage holds, until empty or full (see the class)."""
        self._more = True  # before trying the lock: a holder re-checks it after releasing
        for _ in range(1000):  # bounded: each round is another thread's write meanwhile
            if not self.lock.acquire(blocking=False):
                return  # the holder sends it
            try:
                self._more = False
                self._pump_locked()
            finally:
                self.lock.release()
            if not self._more:
                return

    def offer(self) -> None:
        """The writer's call after a write: :meth:`pump` now, or leave it to the owner's
        thread when the last send was less than :data:`SOON_S` ago (see the class)."""
        if self._defer is not None and time.monotonic() - self.sent_at < SOON_S:
            if not self._deferred:  # one wake-up per round, however many writes
                self._deferred = True
                self._defer()
            return
        self.pump()

    def pump_deferred(self) -> None:
        """The owner's thread: send what the writer left to it (nothing when it left nothing)."""
        if self._deferred:
            self._deferred = False  # before pumping: a write after this defers again
            self.pump()

    def _pump_locked(self) -> None:
        held = self._held
        for _ in range(10_000):
            if self.closed or self.broken:
                return
            while held:
                if not self._send(held[0]):
                    return
                held.popleft()
            items = self._take()
            if not items:
                return
            for message in self._encode(items):
                if len(message) > MAX_MESSAGE:
                    self.dropped += 1
                    if not self._warned:
                        self._warned = True
                        log.warning("a sample of %d bytes encoded is larger than a message may be (%d); dropped",
                                    len(message), MAX_MESSAGE)
                    continue
                held.extend(frames_of(message))

    def send_now(self, message: bytes) -> None:
        """Send one control message (a heartbeat) unless samples are waiting for room or
        another thread is sending (then it is not needed)."""
        if self.lock.acquire(blocking=False):
            try:
                if not self._held and not self.closed and not self.broken:
                    self._send(WHOLE + message)
            finally:
                self.lock.release()

    def _send(self, frame: bytes) -> bool:
        """True when ``frame`` went; False when the socket is full (:attr:`blocked`) or broke."""
        try:
            self.sock.send(frame, socket.MSG_DONTWAIT)
            self.blocked = False
            self.sent_at = time.monotonic()
            return True
        except OSError as exc:
            # the reader is behind (its socket is full), or the kernel is short of memory: wait for room
            if isinstance(exc, (BlockingIOError, InterruptedError)) or exc.errno == errno.ENOBUFS:
                if not self.blocked:
                    self.blocked = True
                    self._want_write()
                return False
            self.broken = True  # the peer is gone: what is held is lost, the storage is kept
            self.dropped += self.pending
            self._held.clear()
            self._on_broken()
            return False

    def close(self) -> None:
        """No more sending (waits for a pump in progress); the held messages count as dropped."""
        with self.lock:
            self.closed = True
            self.dropped += self.pending
            self._held.clear()


class _ReaderEnd:
    """An output port's samples going to one reader over a socket: the subscription's
    policy-shaped inbox (``stream``, the gRPC path's own, tagging each sample with its
    write number as it is written) drained by an :class:`Outbox`."""

    def __init__(self, server: IpcServer, sock: socket.socket, stream: Any, heartbeat: float) -> None:
        self.sock = sock
        self.stream = stream
        self.heartbeat = heartbeat
        self.outbox = Outbox(sock, lambda: stream.take(64), self._messages, lambda: server.want_write(self),
                             lambda: server.detach_later(self), defer=lambda: server.pump_later(self))
        self.outbox.send_now(pb.SubscribeResponse(heartbeat=True, boot_id=server.boot_id).SerializeToString())
        stream.inp.add_data_callback(self._on_data)  # the sample is in the inbox (tagged) by then
        self.outbox.pump()  # what the inbox got before (an init=True policy's sample)

    @property
    def dropped(self) -> int:
        return self.stream.dropped + self.outbox.dropped

    def _messages(self, items: list[tuple[int, int, Any]]) -> list[bytes]:
        """The samples waiting, as few messages as fit in :data:`BATCH_BYTES` each (one
        sample alone when it is larger): one send, one wake-up for a burst."""
        dropped = self.dropped
        return [pb.SubscribeResponse(samples=samples, dropped=dropped).SerializeToString()
                for samples in self.stream.batches(items, len(items), BATCH_BYTES, MAX_MESSAGE - 64)]

    def _on_data(self, _inp: Any) -> None:  # the writer's thread: never blocks
        self.outbox.offer()

    def beat(self, now: float) -> None:
        """A heartbeat when nothing was sent for :attr:`heartbeat` s."""
        if now - self.outbox.sent_at >= self.heartbeat and not self.outbox.blocked:
            self.outbox.send_now(pb.SubscribeResponse(heartbeat=True, dropped=self.dropped).SerializeToString())

    def close(self) -> None:
        self.stream.inp.remove_data_callback(self._on_data)
        self.outbox.close()
        self.stream.close()
        close_quietly(self.sock)


class IpcServer:
    """A deployer's ipc socket: tickets, connections, and one io thread that accepts,
    reads tickets, notices readers gone, gives room to readers that were full and sends
    their heartbeats. Connections carrying samples *in* each get a thread of their own
    (blocking reads: the lowest latency).

    ``write_in(task, port, policy)`` makes the sink of such a connection (a callable
    taking each ``Value`` message, and a ``close``); ``stream_out(task, port, policy, who)``
    the policy-shaped inbox of a reader (the gRPC path's ``_Stream``; ``who``: the
    ticket's, for listings)."""

    def __init__(self, boot_id: str,
                 write_in: Callable[[str, str, ConnPolicy], tuple[Callable[[Any], None], Callable[[], None]]],
                 stream_out: Callable[[str, str, ConnPolicy, str], Any]) -> None:
        self.boot_id = boot_id
        self.name = f"scart-{boot_id}-{secrets.token_hex(8)}"
        self._write_in = write_in
        self._stream_out = stream_out
        self._lock = threading.Lock()
        self._tickets: dict[bytes, tuple[float, str, str, str, str, ConnPolicy, float, str]] = {}
        self._readers: dict[socket.socket, _ReaderEnd] = {}
        self._pending: dict[socket.socket, float] = {}  # accepted, ticket not read yet (insertion order: oldest first)
        self._pumps: dict[socket.socket, threading.Thread] = {}
        self._broken: list[_ReaderEnd] = []
        self._blocked: list[_ReaderEnd] = []
        self._deferred: list[_ReaderEnd] = []
        self._stopping = threading.Event()
        self._listener = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self._wake_r, self._wake_w = socket.socketpair()
        try:
            self._listener.bind("\0" + self.name)
            self._listener.listen(64)
            self._listener.setblocking(False)
            self._wake_w.setblocking(False)
            self._selector = selectors.DefaultSelector()
            self._selector.register(self._listener, selectors.EVENT_READ, "accept")
            self._selector.register(self._wake_r, selectors.EVENT_READ, "wake")
        except BaseException:
            for sock in (self._listener, self._wake_r, self._wake_w):
                sock.close()
            raise
        self._thread = threading.Thread(target=self._run, name="scart-ipc", daemon=True)
        self._thread.start()

    @property
    def connections(self) -> int:
        with self._lock:
            return self._connections()

    def _connections(self) -> int:
        """Connections carrying samples (the caller holds the lock)."""
        return len(self._readers) + len(self._pumps)

    def ticket(self, kind: str, task: str, port: str, policy: ConnPolicy, peer: str, heartbeat: float = 0.5,
               who: str = "") -> bytes:
        """A one-time ticket for a connection of ``kind`` (``in``: into the input port
        ``task.port``; ``out``: out of the output port) for ``peer`` (its key for the
        per-peer bounds; ``who``: its address, as listings show it). Raises
        ``OverflowError`` past the bounds."""
        now = time.monotonic()
        with self._lock:
            for key in [k for k, t in self._tickets.items() if t[0] < now]:
                del self._tickets[key]
            if len(self._tickets) >= MAX_TICKETS:
                raise OverflowError(f"{MAX_TICKETS} ipc tickets are pending")
            if sum(1 for t in self._tickets.values() if t[1] == peer) >= TICKETS_PER_PEER:
                raise OverflowError(f"{TICKETS_PER_PEER} ipc tickets of this peer are pending")
            if self._connections() >= MAX_CONNECTIONS:
                raise OverflowError(f"this deployer serves at most {MAX_CONNECTIONS} ipc connections")
            ticket = secrets.token_bytes(TICKET_BYTES)
            self._tickets[ticket] = (now + TICKET_S, peer, kind, task, port, policy, heartbeat, who)
            return ticket

    def readers(self) -> list[tuple[Any, int]]:
        """Each reader's inbox (``stream_out``'s) and the samples it lost (the inbox's and
        the socket's), for listings."""
        with self._lock:
            ends = list(self._readers.values())
        return [(end.stream, end.dropped) for end in ends]

    # ---- the io thread -------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stopping.is_set():
            try:
                with self._lock:
                    beats = [end.heartbeat for end in self._readers.values()]
                events = self._selector.select(timeout=min([0.5, *beats]) / 2)
                for key, mask in events:
                    what = key.data
                    if what == "accept":
                        self._accept()
                    elif what == "hello":
                        self._hello(key.fileobj)  # type: ignore[arg-type]
                    elif what == "reader":
                        self._reader_event(key.fileobj, mask)  # type: ignore[arg-type]
                    elif what == "wake":
                        self._wake_r.recv(4096)
                self._housekeeping()
            except Exception:  # noqa: BLE001 - the io thread must not die
                if self._stopping.is_set():
                    return
                log.exception("ipc: the io thread hit an error; going on")

    def _accept(self) -> None:
        for _ in range(64):
            try:
                conn, _ = self._listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            uid = struct.unpack("3i", conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i")))[1]
            if uid != os.getuid():  # an abstract socket has no permissions: ours only
                conn.close()
                continue
            with self._lock:
                oldest = next(iter(self._pending)) if len(self._pending) >= MAX_PENDING else None
                if oldest is not None:
                    del self._pending[oldest]
                self._pending[conn] = time.monotonic() + HELLO_S
            if oldest is not None:
                self._unregister(oldest)
                oldest.close()
            conn.setblocking(False)
            self._selector.register(conn, selectors.EVENT_READ, "hello")

    def _hello(self, conn: socket.socket) -> None:
        self._unregister(conn)
        with self._lock:
            self._pending.pop(conn, None)
        try:
            ticket = conn.recv(64)
        except OSError:
            ticket = b""
        with self._lock:
            entry = self._tickets.pop(ticket, None) if len(ticket) == TICKET_BYTES else None
            full = self._connections() >= MAX_CONNECTIONS
        if entry is None or entry[0] < time.monotonic() or full or self._stopping.is_set():
            conn.close()
            return
        _, _, kind, task, port, policy, heartbeat, who = entry
        end: _ReaderEnd | None = None
        try:
            conn.setblocking(True)
            if kind == "out":
                end = _ReaderEnd(self, conn, self._stream_out(task, port, policy, who), heartbeat)
                with self._lock:
                    self._readers[conn] = end
                self._selector.register(conn, selectors.EVENT_READ, "reader")
            else:
                write, close = self._write_in(task, port, policy)
                pump = threading.Thread(target=self._pump_in, args=(conn, write, close, f"{task}.{port}"),
                                        daemon=True, name=f"scart-ipc-in-{task}.{port}")
                with self._lock:
                    self._pumps[conn] = pump
                conn.send(WHOLE + pb.WritePortStreamResponse().SerializeToString())  # acknowledged: samples may come
                pump.start()
        except Exception as exc:  # noqa: BLE001 - the port went away meanwhile: the peer sees the close
            log.info("ipc: %s.%s cannot be served: %s", task, port, exc)
            with self._lock:
                self._readers.pop(conn, None)
                self._pumps.pop(conn, None)
            self._unregister(conn)
            if end is not None:
                end.close()
            else:
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

    def _live(self, end: _ReaderEnd) -> bool:
        """Whether ``end`` is still one of the readers (not detached meanwhile)."""
        with self._lock:
            return end.sock in self._readers

    def pump_later(self, end: _ReaderEnd) -> None:
        """Send what ``end``'s inbox holds from the io thread (its writer writes faster than
        :data:`SOON_S` apart: one send carries what came meanwhile)."""
        with self._lock:
            self._deferred.append(end)
        self._wake()

    def want_write(self, end: _ReaderEnd) -> None:
        """``end``'s socket is full: the io thread pumps it again once writable."""
        with self._lock:
            self._blocked.append(end)
        self._wake()

    def detach_later(self, end: _ReaderEnd) -> None:
        """Detach ``end`` from the io thread (its socket broke in a writer's thread, which
        must not disconnect ports while it writes)."""
        with self._lock:
            self._broken.append(end)
        self._wake()

    def _wake(self) -> None:
        try:
            self._wake_w.send(b"x")
        except OSError:  # full: a wake-up is pending anyway
            pass

    def detach(self, end: _ReaderEnd) -> None:
        """Stop serving a reader (gone, or its socket broke). Idempotent; the io thread."""
        with self._lock:
            if self._readers.pop(end.sock, None) is None:
                return
        self._unregister(end.sock)
        end.close()

    def _unregister(self, sock: socket.socket) -> None:
        try:
            self._selector.unregister(sock)
        except (KeyError, ValueError, OSError):
            pass

    def _housekeeping(self) -> None:
        now = time.monotonic()
        with self._lock:
            late = [c for c, deadline in self._pending.items() if deadline < now]
            for conn in late:
                del self._pending[conn]
            ends = list(self._readers.values())
            broken, self._broken = self._broken, []
            blocked, self._blocked = self._blocked, []
            deferred, self._deferred = self._deferred, []
        for conn in late:
            self._unregister(conn)
            conn.close()
        for end in broken:
            self.detach(end)
        for end in blocked:
            if self._live(end):
                self._selector.modify(end.sock, selectors.EVENT_READ | selectors.EVENT_WRITE, "reader")
        for end in deferred:
            if self._live(end):
                end.outbox.pump_deferred()
        for end in ends:
            end.beat(now)

    def _pump_in(self, conn: socket.socket, write: Callable[[Any], None], close: Callable[[], None],
                 where: str) -> None:
        """Messages into an input port until the peer closes (or the server stops)."""
        assembler = Reassembler()
        refused = 0
        try:
            for message in messages_in(conn, None, assembler):
                if self._stopping.is_set():
                    break
                try:
                    request = pb.WritePortStreamRequest.FromString(message)
                except Exception:  # noqa: BLE001 - not a message: counted with the malformed frames
                    assembler.dropped += 1
                    continue
                for value in request.values or (request.value,):  # several: a batch, oldest first
                    try:
                        write(value)
                    except Exception as exc:  # noqa: BLE001 - one bad sample never ends the link; said once
                        refused += 1
                        if refused == 1:
                            log.warning("ipc: a sample for %s refused: %s", where, exc)
        except OSError:
            pass
        finally:
            if assembler.dropped:
                log.warning("ipc: %d malformed or oversized message(s) for %s dropped", assembler.dropped, where)
            close()
            with self._lock:
                self._pumps.pop(conn, None)
            conn.close()

    def stop(self) -> None:
        """Close the socket and every connection; end the threads (idempotent)."""
        if self._stopping.is_set():
            return
        self._stopping.set()
        self._wake()
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
            shutdown_quietly(conn)  # wakes its pump
            thread.join(timeout=5.0)
        self._selector.close()
        self._listener.close()
        self._wake_r.close()
        self._wake_w.close()
