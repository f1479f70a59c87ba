"""The node's one io thread: every TCPROS socket it receives on, read through a selector.

* :class:`IoLoop` owns the thread, the selector and every socket registered with it;
  :meth:`IoLoop.close` ends the thread and closes them all (idempotent).
* :class:`Conn` is a non-blocking socket with a bounded send queue. :meth:`Conn.send`
  may be called from any thread: it writes straight to the socket when the queue is
  empty and the kernel takes the bytes, and otherwise queues them for the io thread;
  past the queue's bounds (messages, bytes) the oldest message still unsent is dropped
  and counted. A stalled peer therefore never blocks the sender or other peers.
* :class:`FrameReader` cuts a byte stream into TCPROS frames, dropping (and skipping
  the bytes of) a frame larger than its bound.
* :class:`Listener` accepts connections; :class:`InboundConn` reads a peer's connection
  header (bounded in bytes and time) and hands it to a router.

Handlers run on the io thread; one that raises is logged and its connection closed —
the thread goes on.
"""

from __future__ import annotations

import collections
import heapq
import itertools
import logging
import socket
import struct
import threading
import time
from collections.abc import Callable
from typing import Any

from ._threads import OwnedThread
from ._poll import GONE, IN, OUT, READABLE, WRITABLE, Poller
from .tcpros import LEN, HeaderError, decode_header

__all__ = ["Conn", "Counters", "FrameReader", "InboundConn", "IoLoop", "Listener"]

log = logging.getLogger(__name__)

#: Bytes asked of one ``recv``: under glibc malloc's mmap threshold (128 KiB until a large
#: block is freed). A bigger request maps and unmaps a fresh block for every message, and the
#: unmap (a TLB shoot-down across the process's CPUs) doubled a 1 kHz hop in a process that
#: had not happened to raise the threshold by importing something large (grpc, lxml).
RECV_BYTES = 64 * 1024
#: Bytes asked of one ``recv`` while the rest of a message larger than :data:`RECV_BYTES`
#: is due (:meth:`FrameReader.missing`): a quarter of the calls, and the mapped block is
#: a small price next to such a message (6.2 MB: 2.7-3.1 ms p50 against 3.5-3.7 at 64 KiB).
RECV_LARGE = 256 * 1024


class Counters(dict):
    """Named event counts (a ``dict`` of int); :meth:`snapshot` copies them."""

    def __init__(self, *names: str) -> None:
        super().__init__(dict.fromkeys(names, 0))

    def snapshot(self) -> dict[str, int]:
        return dict(self)


class IoLoop:
    """One poll thread (:mod:`._poll`): readiness callbacks, calls from
    other threads, and timers."""

    def __init__(self, name: str) -> None:
        self._sel = Poller()
        self._closed = False
        self._wake_r, self._wake_w = socket.socketpair()
        for sock in (self._wake_r, self._wake_w):
            sock.setblocking(False)
        self._sel.register(self._wake_r, IN, self)  # the loop itself: a wake-up
        self._calls: collections.deque[tuple[Callable[..., object], tuple]] = collections.deque()
        self._timers: list[tuple[float, int, Callable[..., object], tuple]] = []
        self._seq = itertools.count()
        self._ids = itertools.count(1)
        self._stopping = False
        self._owned: set[Conn] = set()
        self._thread = OwnedThread(lambda _stopping: self._run(), f"ros1-io {name}")

    def start(self) -> None:
        self._thread.start()

    def in_loop(self) -> bool:
        """True on the io thread (or once it has ended: then the caller may act directly)."""
        return self._thread.in_thread() or not self._thread.alive

    def adopt(self, conn: Conn) -> None:
        """Own ``conn`` until it closes: :meth:`close` closes it if it is still open."""
        self._owned.add(conn)

    def disown(self, conn: Conn) -> None:
        self._owned.discard(conn)

    def next_id(self) -> int:
        """A connection id unique in this loop (getBusInfo's connectionId)."""
        return next(self._ids)

    def owned(self) -> int:
        """How many connections are open (or not yet closed) on this loop."""
        return len(self._owned)

    def connections(self) -> list[Conn]:
        """The connections open now (the io thread's view)."""
        return list(self._owned)

    def call_soon(self, fn: Callable[..., object], *args: object) -> None:
        """Run ``fn(*args)`` on the io thread (thread-safe; never blocks)."""
        self._calls.append((fn, args))
        try:
            self._wake_w.send(b"\0")
        except (BlockingIOError, OSError):
            pass  # already awake (pipe full) or closing

    def call_later(self, delay: float, fn: Callable[..., object], *args: object) -> None:
        """Run ``fn(*args)`` on the io thread after ``delay`` seconds (thread-safe)."""
        entry = (time.monotonic() + delay, next(self._seq), fn, args)
        if self.in_loop():
            heapq.heappush(self._timers, entry)
        else:
            self.call_soon(heapq.heappush, self._timers, entry)

    def register(self, sock: socket.socket, handler: object, events: int = IN) -> None:
        """Watch ``sock`` for ``handler`` (io thread only); the loop now owns ``sock``."""
        self._sel.register(sock, events, handler)

    def modify(self, sock: socket.socket, handler: object, events: int) -> None:
        self._sel.modify(sock, events, handler)

    def unregister(self, sock: socket.socket) -> None:
        self._sel.unregister(sock)

    def close(self, timeout: float = 5.0) -> None:
        """Stop the thread, then close every registered handler (idempotent; blocks ≤ timeout)."""
        self._stopping = True
        self.call_soon(lambda: None)
        self._thread.join(timeout)  # (not from the loop itself)
        if self._thread.alive:
            return  # called from the loop itself: it closes everything as it ends
        self._close_all()

    def _close_all(self) -> None:
        if self._closed:
            return
        self._closed = True
        handlers = {handler for handler in self._sel.handlers() if handler is not self}
        for handler in handlers | set(self._owned):
            handler.close("node closing")
        self._sel.close()
        self._wake_r.close()
        self._wake_w.close()

    def _run(self) -> None:
        watched = self._sel.watched
        while not self._stopping:
            for fd, events in self._sel.poll(self._timeout()):
                _, handler, wanted = watched.get(fd, GONE)
                if handler is self:
                    self._drain_wake()
                elif handler is not None:
                    self._dispatch(handler, events, wanted)
            self._run_calls()
            self._run_timers()
        self._close_all()

    def _timeout(self) -> float | None:
        if self._calls:
            return 0.0
        if self._timers:
            return max(0.0, self._timers[0][0] - time.monotonic())
        return None

    def _drain_wake(self) -> None:
        try:
            while self._wake_r.recv(4096):
                pass
        except (BlockingIOError, OSError):
            pass

    @staticmethod
    def _dispatch(handler: Any, events: int, wanted: int) -> None:
        try:
            if events & READABLE:
                handler.on_readable()
            if events & WRITABLE and wanted & OUT and not handler.closed:
                handler.on_writable()
        except Exception as exc:  # a handler's bug must not end the io thread
            log.exception("ROS 1 io: %s failed", handler)
            handler.close(f"internal error: {exc}")

    def _run_calls(self) -> None:
        for _ in range(len(self._calls)):
            fn, args = self._calls.popleft()
            self._safely(fn, args)

    def _run_timers(self) -> None:
        now = time.monotonic()
        while self._timers and self._timers[0][0] <= now:
            _, _, fn, args = heapq.heappop(self._timers)
            self._safely(fn, args)

    @staticmethod
    def _safely(fn: Callable[..., object], args: tuple) -> None:
        try:
            fn(*args)
        except Exception:
            log.exception("ROS 1 io: %s failed", getattr(fn, "__qualname__", fn))


class Conn:
    """A registered non-blocking socket with a bounded send queue (see the module doc).

    ``on_close(conn, reason)`` runs once, on the io thread, when the connection ends.
    """

    def __init__(self, loop: IoLoop, sock: socket.socket, peer: str) -> None:
        sock.setblocking(False)
        self.loop, self.sock, self.peer = loop, sock, peer
        self.conn_id = loop.next_id()
        self.peer_id, self.topic, self.direction = peer, "", "b"  # for getBusInfo, set by the owner
        self.closed = False
        self.reason = ""
        self.max_queue, self.max_queue_bytes = 1000, 64 << 20
        #: how it may be idle (:meth:`idle_for`): "" never, "service" (no request for a
        #: while), "subscriber" (a subscriber taking none of what waits for it)
        self.idle_kind = ""
        self.pending = 0  #: requests in hand (a service connection): not idle meanwhile
        self._moved, self._still_since = -1, 0.0
        self.on_close: Callable[[Conn, str], None] | None = None
        self.stats = Counters("messages_sent", "bytes_sent", "dropped", "messages_received", "bytes_received")
        self._lock = threading.Lock()
        self._queue: collections.deque[list[Any]] = collections.deque()  # [data, droppable], data cut as sent
        self._queued_bytes = 0
        self._protected = 0  # entries at the queue's head that must not be dropped
        self._writing = False
        self._close_when_flushed = False
        loop.adopt(self)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.peer})"

    def set_nodelay(self, on: bool) -> None:
        try:
            self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1 if on else 0)
        except OSError:
            pass

    # -- sending (any thread) -------------------------------------------------------------
    def send(self, data: bytes | bytearray | memoryview, droppable: bool = True) -> bool:
        """Send ``data`` or queue it (never blocks); False if the connection is closed.

        ``droppable=False`` (a header, a service answer) is never dropped and not
        counted in ``messages_sent``.
        """
        with self._lock:
            if self.closed:
                return False
            if not self._queue:
                try:
                    sent = self.sock.send(data)
                except (BlockingIOError, InterruptedError):
                    sent = 0
                except OSError as exc:
                    self._fail_later(f"send failed: {exc}")
                    return False
                self.stats["bytes_sent"] += sent
                if sent == len(data):
                    self.stats["messages_sent"] += droppable
                    return True
                if sent:
                    data = memoryview(data)[sent:]
                    self._protected = 1
            self._enqueue(data, droppable)
            return True

    def _enqueue(self, data: Any, droppable: bool) -> None:
        self._queue.append([data, droppable])
        self._queued_bytes += len(data)
        if not droppable:
            self._protected = len(self._queue)
        while len(self._queue) > self._protected + 1 and (
            len(self._queue) > self.max_queue or self._queued_bytes > self.max_queue_bytes
        ):
            victim = self._queue[self._protected]
            del self._queue[self._protected]
            self._queued_bytes -= len(victim[0])
            self.stats["dropped"] += 1
        if not self._writing:
            self._writing = True
            self._apply_events()

    def close_when_flushed(self) -> None:
        """Close once everything queued has been sent (any thread)."""
        with self._lock:
            self._close_when_flushed = True
            empty = not self._queue
        if empty:
            self.close("done")

    def on_writable(self) -> None:
        with self._lock:
            while self._queue:
                entry = self._queue[0]
                try:
                    sent = self.sock.send(entry[0])
                except (BlockingIOError, InterruptedError):
                    return
                except OSError as exc:
                    self._fail_later(f"send failed: {exc}")
                    return
                self.stats["bytes_sent"] += sent
                self._queued_bytes -= sent
                if sent < len(entry[0]):
                    entry[0] = memoryview(entry[0])[sent:]
                    self._protected = max(self._protected, 1)
                    return
                self._queue.popleft()
                self._protected = max(0, self._protected - 1)
                self.stats["messages_sent"] += entry[1]
            self._writing = False
            self._apply_events()
            done = self._close_when_flushed
        if done:
            self.close("done")

    def _apply_events(self) -> None:
        if self.loop.in_loop():
            self._set_events()
        else:
            self.loop.call_soon(self._set_events)

    def _set_events(self) -> None:
        if not self.closed:
            self.loop.modify(self.sock, self, IN | OUT if self._writing else IN)

    def idle_for(self, now: float) -> float:
        """Seconds this connection has been idle in its :attr:`idle_kind`'s sense (0 when
        it is not), measured between calls (the io thread's sweep calls it)."""
        stats = self.stats
        moved = stats["bytes_sent"] + stats["bytes_received"]
        idle = (self.idle_kind == "service" and not self.pending) or (self.idle_kind == "subscriber" and self._writing)
        if moved != self._moved or not idle:
            self._moved, self._still_since = moved, now
            return 0.0
        return now - self._still_since

    def _fail_later(self, reason: str) -> None:
        self.loop.call_soon(self.close, reason)

    # -- receiving and closing (io thread) ------------------------------------------------
    def recv(self, size: int = RECV_BYTES) -> bytes | None:
        """Bytes the peer sent (at most ``size``); ``None`` if nothing now. Closes the
        connection at EOF/error."""
        try:
            data = self.sock.recv(size)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError as exc:
            self.close(f"receive failed: {exc}")
            return None
        if not data:
            self.close("peer closed the connection")
            return None
        self.stats["bytes_received"] += len(data)
        return data

    def on_readable(self) -> None:
        self.recv()  # a peer that should not talk: its bytes are read and dropped

    def close(self, reason: str = "closed") -> None:
        """End the connection (any thread; idempotent): unregister, close, tell ``on_close``.

        Messages still queued are counted in ``dropped``.
        """
        if not self.loop.in_loop():
            with self._lock:
                self.closed = True
            self.loop.call_soon(self.close, reason)
            return
        if self.sock.fileno() < 0:
            return
        with self._lock:
            self.closed = True
            self.reason = self.reason or reason
            self.stats["dropped"] += sum(entry[1] for entry in self._queue)  # never sent: lost, counted
            self._queue.clear()
        self.loop.unregister(self.sock)
        self.sock.close()
        self.loop.disown(self)
        if self.on_close is not None:
            self.on_close(self, self.reason)


class FrameReader:
    """Cuts bytes into frames; ``on_frame(payload: bytes)`` per frame (io thread).

    A frame longer than ``max_bytes`` is skipped, its bytes never buffered, and
    ``on_oversized(size)`` told.
    """

    __slots__ = ("_buf", "_skip", "max_bytes", "on_frame", "on_oversized")

    def __init__(self, max_bytes: int, on_frame: Callable[[bytes], None], on_oversized: Callable[[int], None]) -> None:
        self.max_bytes, self.on_frame, self.on_oversized = max_bytes, on_frame, on_oversized
        self._buf: bytes | bytearray = b""
        self._skip = 0

    def missing(self) -> int:
        """Bytes still due of the message begun (its rest, or the rest of one skipped); 0
        between messages, or when its length is not known yet."""
        if self._skip:
            return self._skip
        buf = self._buf
        return LEN.unpack_from(buf)[0] + 4 - len(buf) if len(buf) >= 4 else 0

    def feed(self, data: bytes) -> None:
        if not self._buf and not self._skip and len(data) >= 4:  # the hot case: one whole frame, alone
            (size,) = LEN.unpack_from(data)
            if len(data) == size + 4 and size <= self.max_bytes:
                self.on_frame(data[4:])
                return
        if self._skip:
            cut = min(self._skip, len(data))
            self._skip -= cut
            data = data[cut:]
        if self._buf:  # a frame cut short last time: gather (amortised), deliver copies
            buf = self._buf
            buf += data
            rest = self._cut(buf, lambda a, b: bytes(memoryview(buf)[a:b]))
        else:
            rest = self._cut(data, lambda a, b: data[a:b])
        self._buf = rest if isinstance(rest, bytearray) else bytearray(rest) if rest else b""

    def _cut(self, data: Any, piece: Callable[[int, int], bytes]) -> Any:
        """Deliver each whole frame in ``data``; return what is left (``data`` itself if none)."""
        pos, end, unpack = 0, len(data), LEN.unpack_from
        while end - pos >= 4:
            (size,) = unpack(data, pos)
            if size > self.max_bytes:
                self.on_oversized(size)
                cut = min(size, end - pos - 4)
                pos += 4 + cut
                self._skip = size - cut
                continue
            if end - pos - 4 < size:
                break
            self.on_frame(piece(pos + 4, pos + 4 + size))
            pos += 4 + size
        if pos == 0:
            return data
        return data[pos:] if pos < end else b""


class Listener:
    """A listening socket on the io loop; ``on_accept(sock, addr)`` per connection."""

    def __init__(self, loop: IoLoop, host: str, port: int, on_accept: Callable[[socket.socket, object], None]) -> None:
        self.loop, self.on_accept = loop, on_accept
        self.closed = False
        self.sock = socket.create_server((host, port), family=_family(host), backlog=128)
        self.sock.setblocking(False)
        self.port: int = self.sock.getsockname()[1]

    def start(self) -> None:
        self.loop.call_soon(self.loop.register, self.sock, self)

    def on_readable(self) -> None:
        for _ in range(64):  # bounded per wake-up: other sockets get their turn
            try:
                sock, addr = self.sock.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                log.warning("ROS 1: accept failed: %s", exc)
                return
            self.on_accept(sock, addr)

    def close(self, reason: str = "") -> None:
        if not self.closed:
            self.closed = True
            self.loop.unregister(self.sock)
            self.sock.close()


def _family(host: str) -> socket.AddressFamily:
    return socket.AF_INET6 if ":" in host else socket.AF_INET


class InboundConn(Conn):
    """An accepted connection: reads the peer's header, then becomes what the router says.

    ``route(conn, header)`` runs on the io thread once the header is in; it answers the
    peer and sets :attr:`on_data` (or closes the connection). ``counters`` (the node's)
    count ``malformed_headers`` and ``stalled_peers``.
    """

    def __init__(self, loop: IoLoop, sock: socket.socket, peer: str, max_header: int,
                 route: Callable[[InboundConn, dict[str, str]], None], counters: Counters) -> None:
        super().__init__(loop, sock, peer)
        self.max_header, self.route, self.counters = max_header, route, counters
        self.header: dict[str, str] | None = None
        self.address = peer.rpartition(":")[0]  #: the peer's address (per-peer limits)
        self.on_data: Callable[[bytes], None] = self._header_data
        self._buf = b""

    def expect_header_within(self, seconds: float) -> None:
        self.loop.call_later(seconds, self._check_header, seconds)

    def _check_header(self, seconds: float) -> None:
        if self.header is None and not self.closed:
            self.counters["stalled_peers"] += 1
            log.warning("ROS 1: peer %s sent no connection header within %.1f s: dropped", self.peer, seconds)
            self.close("no header in time")

    def on_readable(self) -> None:
        data = self.recv()
        if data:
            self.on_data(data)

    def _header_data(self, data: bytes) -> None:
        buf = self._buf + data
        if len(buf) < 4:
            self._buf = buf
            return
        (size,) = struct.unpack_from("<I", buf)
        if size > self.max_header:
            return self._malformed(f"header of {size} bytes is larger than the {self.max_header}-byte limit")
        if len(buf) < 4 + size:
            self._buf = buf
            return
        try:
            header = decode_header(buf[4 : 4 + size])
        except HeaderError as exc:
            return self._malformed(str(exc))
        self.header, self._buf = header, b""
        self.route(self, header)
        rest = buf[4 + size :]
        if rest and not self.closed:
            self.on_data(rest)

    def _malformed(self, why: str) -> None:
        self.counters["malformed_headers"] += 1
        log.warning("ROS 1: malformed connection header from %s: %s; dropped", self.peer, why)
        self.close(f"malformed header: {why}")
