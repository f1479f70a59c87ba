"""One TCP connection of a YARP port, either way: an *inbound* one (a writer, an RPC
client or an administrator connected to us) parsed as it comes, or an *outbound* one
(we write to a reader) whose acknowledgements are counted.

Sending is thread-safe and never blocks (:meth:`Connection.send`): what the kernel does
not take at once waits, bounded in messages, and the io thread sends it when the socket
has room. Reading happens in the io thread only (:meth:`Connection.readable`).
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

from .dgram import DatagramReader
from .wire import ACK, CARRIERS, Frame, IncomingParser, ProtocolError, read_number, yarp_number

if TYPE_CHECKING:
    from .port import Port

__all__ = ["Connection"]

log = logging.getLogger("scart_yarp")

RECV_CHUNK = 1 << 16  #: bytes asked of one recv: under malloc's mmap threshold (a bigger one maps and unmaps each time)
#: Acknowledgements a tcp writer lets pile up before its io thread wakes to read them,
#: unless someone waits for them (:meth:`Connection.batch_acks`): a wake-up per message
#: would cost the writer's process CPU while its reader is taking the message.
ACK_BATCH = 64


class Connection:
    """A connection of ``port``: ``inbound`` (a peer connected to us) or outbound (to
    ``peer``, a reader, over ``carrier``). Counts: ``sent`` messages handed to the
    kernel, ``acked`` (tcp: acknowledged by the reader; read in batches while no one
    waits for them, see :meth:`batch_acks`), ``dropped`` (no room), ``received``
    (inbound messages)."""

    def __init__(self, port: Port, sock: socket.socket, *, inbound: bool, carrier: str = "", peer: str = "",
                 queue: int = 1) -> None:
        self.port = port
        self.sock = sock
        self.inbound = inbound
        self.carrier = carrier
        self.peer = peer
        self.queue = max(1, queue)  #: messages that may wait for room, at most
        self.parser = IncomingParser(port.limits.message) if inbound else None
        #: What an outbound connection's messages are: ``binary``, ``text`` or ``udp`` (datagrams).
        self.kind = "text" if carrier.startswith("text") else "udp" if carrier == "udp" else "binary"
        #: A ``udp`` connection's datagram reader (inbound), once the TCP greeting is done.
        self.dgram: DatagramReader | None = None
        self.opened = time.monotonic()
        self.address = _peer_address(sock)
        self.sent = self.acked = self.dropped = self.received = 0
        self.closed = False
        self.paused = False  #: not read for now (the reader's buffer is full: the writer is held back)
        self.held: deque[Frame] = deque()  #: messages received and not yet taken by the owner (io thread)
        self.closing = 0.0  #: when closing once what waits is sent: the deadline (monotonic)
        self._out: deque[tuple[memoryview, bool]] = deque()  # parts, and whether each ends a message
        self._waiting = 0  # messages not wholly handed to the kernel
        self._lock = threading.Lock()
        self._ack_buf = b""
        #: Called (io thread) once the connection is gone, with why.
        self.on_close: Callable[[Connection, str], None] | None = None
        self.batch_acks(True)

    # ---- what it is ---------------------------------------------------------------------
    @property
    def greeted(self) -> bool:
        return not self.inbound or self.dgram is not None or (self.parser is not None and self.parser.greeted)

    @property
    def acks(self) -> bool:
        """Each message is acknowledged on this connection."""
        return CARRIERS.get(self.carrier, False)

    @property
    def idle(self) -> bool:
        """Nothing waits to be sent, and every message sent was acknowledged (tcp)."""
        return self._waiting == 0 and (not self.acks or self.inbound or self.acked >= self.sent)

    @property
    def sending(self) -> bool:
        """Bytes wait for room in the socket."""
        return bool(self._out)

    @property
    def datagrams(self) -> bool:
        return self.carrier == "udp"

    @property
    def text(self) -> bool:
        return self.carrier.startswith("text")

    def batch_acks(self, on: bool) -> None:
        """An outbound tcp connection's acknowledgements: ``on``, the io thread is woken
        once :data:`ACK_BATCH` of them wait (the socket's ``SO_RCVLOWAT``; a closed or
        broken connection wakes it at once); off, by each one (someone waits for them:
        YARP's flow control, :meth:`Port.wait_sent`). Any thread."""
        if self.inbound or not self.acks or self.closed:
            return
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVLOWAT, len(ACK) * ACK_BATCH if on else 1)
        except OSError:  # closed meanwhile: the io thread forgets it
            pass

    # ---- sending (any thread) -----------------------------------------------------------
    def send(self, parts: list[bytes] | tuple[bytes, ...], force: bool = False) -> bool:
        """Send one message made of ``parts`` without blocking; False (counted in
        ``dropped``) when :attr:`queue` messages already wait for room, unless ``force``
        (a reply or an acknowledgement, which must not be lost). Gathered from ``parts``
        with no copy, in the caller's thread when nothing waits before it: what the kernel
        does not take at once waits for the io thread."""
        with self._lock:
            if self.closed:
                return False
            if self._waiting >= self.queue and not force:
                self.dropped += 1
                return False
            if not self._out:
                try:
                    n = self.sock.sendmsg(parts)
                except OSError:  # would block, or broken: the io thread sees the error and closes
                    n = 0
                if n == sum(map(len, parts)):  # the common case: the kernel took it all
                    self.sent += 1
                    return True
                left = _after(parts, n)
            else:
                left = list(parts)
            self._waiting += 1
            views = [memoryview(p) for p in left if len(p)]
            for i, view in enumerate(views):
                self._out.append((view, i == len(views) - 1))
        self.port.network.watch_write(self)
        return True

    def send_datagrams(self, datagrams: list[bytes] | tuple[bytes, ...]) -> bool:
        """Send one message as ``datagrams`` (a ``udp`` output), never blocking: what the
        kernel does not take at once is lost (counted in ``dropped``), as YARP's udp loses it."""
        with self._lock:
            if self.closed:
                return False
            try:
                for datagram in datagrams:
                    self.sock.send(datagram)
            except OSError:  # no room, or the reader's socket is gone: the message is lost
                self.dropped += 1
                return False
            self.sent += 1
            return True

    def writable(self) -> bool:
        """The io thread: send what waits; True when nothing is left."""
        with self._lock:
            while self._out:
                view, last = self._out[0]
                try:
                    n = self.sock.send(view)
                except (BlockingIOError, InterruptedError):
                    return False
                if n < len(view):
                    self._out[0] = (view[n:], last)
                    return False
                self._out.popleft()
                if last:
                    self._waiting -= 1
                    self.sent += 1
            return True

    # ---- reading (io thread) --------------------------------------------------------------
    def readable(self) -> list[Frame] | None:
        """Read what came; the whole messages it completed (inbound), or None when the
        peer closed. Raises :class:`ProtocolError` for a peer that broke the protocol."""
        try:
            data = self.sock.recv(RECV_CHUNK)
        except (BlockingIOError, InterruptedError):
            return []
        except OSError:
            return None
        if not data:
            return None if self.dgram is None else []  # an empty datagram is no end
        if self.dgram is not None:
            return self.dgram.feed(data)
        if self.parser is not None:
            frames = self.parser.feed(data)
            if not self.carrier and self.parser.greeted:
                self.carrier, self.peer = self.parser.carrier, self.parser.sender
                if self.carrier != "udp":  # udp answers with its datagram socket's port (the network does)
                    self._welcome()
            return frames
        self._acks(data)
        return []

    def _acks(self, data: bytes) -> None:
        """Outbound: count the reader's acknowledgements (``YA`` 0 ``RP``; a longer one's
        extra bytes skipped)."""
        buf = self._ack_buf + data
        while len(buf) >= 8:
            n = read_number(buf[:8])
            if n is None:
                raise ProtocolError(f"a reader sent {bytes(buf[:8])!r} where an acknowledgement was due")
            if len(buf) < 8 + max(n, 0):
                break
            buf = buf[8 + max(n, 0):]
            self.acked += 1
        self._ack_buf = buf

    def _welcome(self) -> None:
        """Answer a writer's greeting: ``Welcome NAME`` (text) or our TCP port number."""
        if self.text:
            self.send((f"Welcome {self.peer}\r\n".encode("utf-8"),), force=True)
        else:
            self.send((yarp_number(self.port.tcp_port),), force=True)

    def ack(self) -> None:
        """Acknowledge one message received (tcp: ``YA 0 RP``; text_ack: ``<ACK>``)."""
        if self.carrier == "tcp":
            self.send((ACK,), force=True)
        elif self.carrier == "text_ack":
            self.send((b"<ACK>\r\n",), force=True)

    def close(self) -> None:
        """Close the socket (idempotent; the io thread forgets it)."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            self._out.clear()
        try:
            self.sock.close()
        except OSError:
            pass

    def __repr__(self) -> str:
        way = f"from {self.peer or '?'}" if self.inbound else f"to {self.peer}"
        return f"<Connection {self.port.name} {way} {self.carrier or '?'}>"


def _after(parts: list[bytes] | tuple[bytes, ...], n: int) -> list[bytes | memoryview]:
    """What is left of ``parts`` once their first ``n`` bytes are sent (no copy)."""
    left: list[bytes | memoryview] = []
    for part in parts:
        if n >= len(part):
            n -= len(part)
            continue
        left.append(memoryview(part)[n:] if n else part)
        n = 0
    return left


def _peer_address(sock: socket.socket) -> str:
    try:
        host, port = sock.getpeername()[:2]
        return f"{host}:{port}"
    except OSError:
        return "?"
