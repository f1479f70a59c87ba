"""ipc's one io thread per process (private): RTT's mqueue dispatcher.

Every ipc socket of a process — a deployer's listener, the links it sends and receives,
the subscriptions it serves and the ones it reads — is watched by one selector in one
thread, the :class:`Hub`'s. It reads every incoming frame and hands it to its
connection (a reader end checks and stores it: one hand-over to the task or observer);
it gives room back to writers whose socket was full, and runs each connection's
periodic work (heartbeats, reports) every :data:`TICK_S`.

Samples go out from the writer's own thread (``send`` with ``MSG_DONTWAIT``): the io
thread sends only what had to wait for room (joined, many samples per message: see
:attr:`Conn.batch_bytes`), and control frames. The hub starts with
its first connection and ends with its last (:meth:`Hub.acquire`, :meth:`Hub.release`).
"""

from __future__ import annotations

import errno
import logging
import socket
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeAlias

from dataflow.threads import OwnedThread
from dataflow.transports._poll import GONE, IN, OUT, READABLE, WRITABLE, Poller
from dataflow.transports.ipc._wire import CHUNK, WHOLE, Reassembler, frames_of, shutdown_quietly

if TYPE_CHECKING:
    from dataflow.transports.ends import OutSample

__all__ = ["Conn", "Encode", "Hub", "TICK_S"]

#: How a carrier makes a sample's frame: its bytes, or (shm) the sample itself, kept for a
#: slot of shared memory when it is large.
Encode: TypeAlias = "Callable[[OutSample[object]], bytes | OutSample[object]]"

log = logging.getLogger(__name__)

_get_ident = threading.get_ident
_monotonic = time.monotonic
_TRUNC = int(socket.MSG_TRUNC)  # a plain int: ``flags & socket.MSG_TRUNC`` builds an enum member per frame

TICK_S = 0.05  #: how often each connection's periodic work runs (heartbeats, reports)
READS_PER_WAKE = 256  #: datagrams one connection may read per wake-up before the others' turn
INLINE_SENDS = 2  #: connections a sample is sent to from the writer's own thread; the io thread sends to the rest


class Hub:
    """The process's ipc io thread (see the module docstring). Thread-safe."""

    _the: Hub | None = None
    _the_lock = threading.Lock()

    def __init__(self) -> None:
        self._poller = Poller()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._poller.register(self._wake_r, IN, self)  # the hub itself: a wake-up
        self._calls: deque[Callable[[], None]] = deque()
        self._conns: set[Conn] = set()
        self._to_flush: set[Conn] = set()  # connections whose writer end has samples for this thread to send
        self._flush_lock = threading.Lock()
        self._users = 0
        self._ident = -1  # the io thread's, once it runs
        self._thread = OwnedThread(self._run, "scart-ipc", wake=self.wake)

    # ---- one per process ----------------------------------------------------------------
    @classmethod
    def acquire(cls) -> Hub:
        """The process's hub, started if needed; each call is matched by one :meth:`release`."""
        with cls._the_lock:
            hub = cls._the
            if hub is None:
                hub = cls._the = Hub()
                hub._thread.start()
            hub._users += 1
            return hub

    def release(self) -> None:
        """One user less; the last one stops the thread and closes the selector."""
        with Hub._the_lock:
            self._users -= 1
            if self._users > 0:
                return
            if Hub._the is self:
                Hub._the = None
        self._thread.stop()
        if not self._thread.in_thread():
            self._shut()

    def _shut(self) -> None:
        self._run_calls()
        for conn in list(self._conns):
            self.forget(conn)
            conn.sock.close()
        self._poller.close()
        self._wake_r.close()
        self._wake_w.close()

    # ---- from any thread --------------------------------------------------------------
    def wake(self) -> None:
        """Wake the io thread (never blocks)."""
        try:
            self._wake_w.send(b"x")
        except OSError:  # full: a wake-up is pending anyway; closed: stopping
            pass

    def call_soon(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` in the io thread, soon (at once when called from it)."""
        if self._thread.in_thread():
            fn()
            return
        self._calls.append(fn)
        self.wake()

    def flush_soon(self, conn: Conn) -> None:
        """Have the io thread send what ``conn``'s writer end holds (:meth:`Conn.drained`),
        soon: many connections asking at once cost one wake-up (any thread; never blocks)."""
        with self._flush_lock:
            first = not self._to_flush
            self._to_flush.add(conn)
        if first:
            self.wake()

    def call_later(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` in the io thread after what it does now (also when called from it:
        never inside the caller, which may hold locks ``fn`` needs)."""
        self._calls.append(fn)
        self.wake()

    def add(self, conn: Conn) -> None:
        """Watch ``conn``'s socket (it reads; it writes when it asks)."""
        def register() -> None:
            if conn.ended.is_set():
                return
            self._conns.add(conn)
            wanted = OUT if conn._blocked else 0  # it filled up before it was watched
            self._poller.register(conn.sock, IN | wanted, conn)
        self.call_soon(register)

    def want_write(self, conn: Conn, wanted: bool) -> None:
        """Watch ``conn`` for room to write (True) or not any more (False)."""
        def modify() -> None:
            if conn in self._conns:
                self._poller.modify(conn.sock, IN | (OUT if wanted else 0), conn)
        self.call_soon(modify)

    def watch(self, sock: socket.socket, handler: object) -> None:
        """Watch a socket for reading with a handler that is not a :class:`Conn` (the io thread)."""
        self._poller.register(sock, IN, handler)

    def unwatch(self, sock: socket.socket) -> None:
        """Stop watching a socket given to :meth:`watch` (the io thread; idempotent)."""
        self._poller.unregister(sock)

    def forget(self, conn: Conn) -> None:
        """Stop watching ``conn`` (the io thread; :meth:`Conn.close` calls it)."""
        if conn in self._conns:
            self._conns.discard(conn)
            self._poller.unregister(conn.sock)

    # ---- the io thread ------------------------------------------------------------------
    def _run(self, stopping: threading.Event) -> None:
        self._ident = threading.get_ident()
        next_tick = time.monotonic() + TICK_S
        while not stopping.is_set():
            try:
                timeout = max(0.0, next_tick - time.monotonic())
                watched = self._poller.watched
                for fd, events in self._poller.poll(timeout):
                    _, conn, wanted = watched.get(fd, GONE)
                    if conn is None:
                        continue
                    if conn is self:
                        self._drain_wake()
                        continue
                    if events & READABLE:
                        conn.readable()
                    if events & WRITABLE and wanted & OUT and not conn.ended.is_set():
                        conn.writable()
                self._run_calls()
                self._run_flushes()
                now = time.monotonic()
                if now >= next_tick:
                    next_tick = now + TICK_S
                    for conn in list(self._conns):
                        conn.tick(now)
            except Exception:  # noqa: BLE001 - the io thread must not die
                if stopping.is_set():
                    break
                log.exception("ipc: the io thread hit an error; going on")
        if self._thread.in_thread() and Hub._the is not self:
            self._shut()

    def _drain_wake(self) -> None:
        try:
            while self._wake_r.recv(4096):
                pass
        except OSError:
            pass

    def _run_flushes(self) -> None:
        if not self._to_flush:  # the common case, read without the lock (a flush_soon wakes the loop again)
            return
        with self._flush_lock:
            conns, self._to_flush = self._to_flush, set()
        for conn in conns:
            if not conn.ended.is_set():
                conn.drained()

    def _run_calls(self) -> None:
        if not self._calls:
            return
        for _ in range(len(self._calls)):
            try:
                fn = self._calls.popleft()
            except IndexError:
                return
            try:
                fn()
            except Exception:  # noqa: BLE001
                log.exception("ipc: a call in the io thread failed")


class Conn:
    """One ipc socket watched by the hub. Subclasses say what a message means
    (:meth:`message`), what to do when there is room again (:meth:`drained`), what runs
    every tick (:meth:`tick`) and when it ends (:meth:`ended_hook`).

    :meth:`put` may be called from any thread; it never blocks: False when the socket
    is full (the hub calls :meth:`drained` once it has room) or another thread is
    sending on it, or it broke (the hub closes it).
    """

    def __init__(self, hub: Hub, sock: socket.socket, label: str) -> None:
        sock.setblocking(False)
        self.hub = hub
        self.sock = sock
        self.label = label
        self.ended = threading.Event()
        self.sent_at = time.monotonic()
        self._assembler = Reassembler()
        self._held: deque[bytes] = deque()  # the rest of a chunked message, waiting for room
        self._lock = threading.Lock()
        self._blocked = False
        self._closed = False  # ended, as a plain flag for the hot path
        self._reset = False  # the peer reset the connection (said once by the kernel)
        self._closing = threading.Lock()

    def start(self) -> None:
        """Begin watching the socket (after the subclass is ready for messages)."""
        self.hub.add(self)

    # ---- sending ---------------------------------------------------------------------------
    def put(self, message: bytes) -> bool:
        """Send one message without blocking (see the class); True once it is committed."""
        if not self._lock.acquire(blocking=False):
            return False
        try:
            if self._held or self._closed:
                return False
            if len(message) <= CHUNK:
                return self._out([WHOLE, message])
            frames = frames_of(message)
            if not self._out([frames[0]]):
                return False
            self._held.extend(frames[1:])
            self._push_held()
            return True
        finally:
            self._lock.release()

    #: A carrier's batch (see ``Carrier``): samples that waited for room leave joined
    #: into messages of up to this many bytes (scart's frames join into one). A reader
    #: that fell behind then catches up hundreds of small samples per read, while one
    #: message stays a few milliseconds of its io thread's work at most.
    batch_bytes = 16 * 1024

    def send_sample(self, sample: OutSample, data: bytes) -> bool:
        """A carrier's ``send``: from the writer's thread for the first :data:`INLINE_SENDS`
        connections a sample goes to (one reader, one link: no thread hand-over at all),
        else left to the io thread (False: the writer end keeps the sample, as its policy
        says, and the io thread sends it with :meth:`drained`). A writer's cost thus does
        not grow with its readers; the io thread sends to the rest."""
        if _get_ident() != self.hub._ident:  # the writer's thread
            if sample.inline >= INLINE_SENDS:
                self.hub.flush_soon(self)
                return False
            sample.inline += 1
        if len(data) > CHUNK or not self._lock.acquire(blocking=False):
            if self.put(data):
                return True
            if not (self._blocked or self._closed):  # another thread was sending on it: what waits goes next
                self.hub.flush_soon(self)
            return False
        try:  # put(), inlined for the hot case: one small message, nothing held
            if self._held or self._closed:
                return False
            try:
                self.sock.sendmsg((WHOLE, data), (), socket.MSG_DONTWAIT)
            except OSError:
                return self._failed_send()
            self.sent_at = _monotonic()
            return True
        finally:
            self._lock.release()

    def _out(self, parts: list[bytes]) -> bool:
        try:
            self.sock.sendmsg(parts, (), socket.MSG_DONTWAIT)
        except OSError:
            return self._failed_send()
        self.sent_at = _monotonic()
        return True

    def _failed_send(self) -> bool:
        """A send that raised (called in its ``except``): no room (wait for it), or the peer
        is gone (closed after this send's caller let go of its locks). False."""
        exc = sys.exc_info()[1]
        if isinstance(exc, (BlockingIOError, InterruptedError)) or getattr(exc, "errno", None) == errno.ENOBUFS:
            self._block()  # the reader is behind, or the kernel is short of memory: wait for room
            return False
        self.hub.call_later(self.close)
        return False

    def _block(self) -> None:
        if not self._blocked:
            self._blocked = True
            self.hub.want_write(self, True)

    def _push_held(self) -> None:
        held = self._held
        while held:
            if not self._out([held[0]]):
                return
            held.popleft()

    # ---- the io thread -------------------------------------------------------------------
    def writable(self) -> None:
        with self._lock:
            self._blocked = False
            self._push_held()
            if self._held:
                return
        self.hub.want_write(self, False)
        self.drained()
        if self._blocked:  # drained() filled it again
            self.hub.want_write(self, True)

    def readable(self) -> None:
        for _ in range(READS_PER_WAKE):
            try:
                frame, _, flags, _ = self.sock.recvmsg(CHUNK + 1)
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionResetError:  # the peer closed with what this side sent unread: the kernel
                if not self._reset:  # says so once, before what the peer sent last (a final report)
                    self._reset = True
                    continue  # read that next
                frame = b""
            except OSError:
                frame = b""
            if not frame:
                self.close()
                return
            message = self._assembler.feed(frame, bool(flags & _TRUNC))
            if message is not None:
                try:
                    self.message(message)
                except Exception:  # noqa: BLE001 - one bad message never ends the io thread
                    log.exception("ipc %s: a message could not be handled", self.label)

    def message(self, data: bytes) -> None:
        """One message arrived (the io thread)."""

    def drained(self) -> None:
        """The socket has room again (the io thread)."""

    def tick(self, now: float) -> None:
        """Periodic work (the io thread, every :data:`TICK_S`)."""

    def ended_hook(self) -> None:
        """The connection is over (called once, from the thread that closed it)."""

    @property
    def malformed(self) -> int:
        """Frames dropped as malformed or oversized."""
        return self._assembler.dropped

    def close(self) -> None:
        """End the connection (idempotent, any thread): the socket is shut at once (the
        peer sees its end) and closed by the io thread, which stops watching it first."""
        with self._closing:
            if self.ended.is_set():
                return
            self._closed = True
            self.ended.set()
        shutdown_quietly(self.sock)

        def finish() -> None:
            self.hub.forget(self)
            self.sock.close()

        self.hub.call_soon(finish)
        with self._lock:
            self._held.clear()
        try:
            self.ended_hook()
        finally:
            self.hub.release()
