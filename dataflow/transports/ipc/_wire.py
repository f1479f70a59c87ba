"""ipc's socket and frames (private): abstract Unix ``SOCK_SEQPACKET`` sockets, one
datagram per frame.

Each frame starts with one byte: 0 a whole message, 1 a part with more to come, 2 the
last part; parts are at most :data:`CHUNK` bytes, a message at most :data:`MAX_MESSAGE`
(a sample of 64 MiB and its frame; a writer refuses a larger one at ``write()``, and a
reader drops and counts one that comes all the same). An abstract socket has no file
(nothing in ``/dev/shm`` or on disk) and the kernel closes it with its process, even a
killed one: the other side then sees the end of its stream and reconnects.
"""

from __future__ import annotations

import selectors
import socket
import sys
import threading
import time
from collections.abc import Iterator

from dataflow.transports.limits import MAX_FRAME_BYTES

__all__ = ["CHUNK", "MAX_MESSAGE", "Reassembler", "available", "connect", "frames_of", "host_id",
           "IpcUnavailable", "messages_in", "shutdown_quietly"]

CHUNK = 64 * 1024  #: bytes of a message in one frame, at most (well inside a socket's buffer)
MAX_MESSAGE = MAX_FRAME_BYTES  #: bytes of one message, at most (a sample of 64 MiB, framed)
WHOLE, PART, LAST = b"\x00", b"\x01", b"\x02"


class IpcUnavailable(Exception):
    """The fast path cannot be used between these two ends (another host or network
    namespace, another platform, a peer without it, a deployer out of room)."""


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
    """The messages a blocking socket receives, until the peer closes (``TimeoutError``
    after ``timeout`` s of silence)."""
    assembler = assembler or Reassembler()
    sock.settimeout(timeout)
    while True:
        frame, _, flags, _ = sock.recvmsg(CHUNK + 1)
        if not frame:
            return
        message = assembler.feed(frame, bool(flags & socket.MSG_TRUNC))
        if message is not None:
            yield message


def connect(name: str, ticket: bytes, timeout: float = 2.0,
            cancelled: threading.Event | None = None) -> tuple[socket.socket, bytes]:
    """Connect to a deployer's socket ``name``, present ``ticket`` and wait for its first
    message (at most ``timeout`` s, or until ``cancelled`` is set); the connected socket
    (non-blocking) and that message. Raises :class:`IpcUnavailable` when it cannot be
    reached from here or the deployer refuses (``TimeoutError`` when it says nothing)."""
    if not available() or not name:
        raise IpcUnavailable("no ipc on this platform")
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    try:
        sock.settimeout(timeout)
        sock.connect("\0" + name)
        sock.send(ticket)
        _await_readable(sock, timeout, cancelled)
        first = next(messages_in(sock, timeout), None)
        if first is None:
            raise IpcUnavailable("the deployer closed the connection (out of room, or the ticket expired)")
        sock.setblocking(False)
        return sock, first
    except (OSError, IpcUnavailable) as exc:
        sock.close()
        if isinstance(exc, IpcUnavailable):
            raise
        raise IpcUnavailable(f"cannot reach the deployer's socket: {exc}") from None


def _await_readable(sock: socket.socket, timeout: float, cancelled: threading.Event | None) -> None:
    """Wait until ``sock`` has something to read, in short slices so that ``cancelled``
    ends the wait (an owner closing a subscription while it connects); bounded by ``timeout``."""
    deadline = time.monotonic() + timeout
    with selectors.DefaultSelector() as selector:
        selector.register(sock, selectors.EVENT_READ)
        while not selector.select(min(0.1, max(0.0, deadline - time.monotonic()))):
            if cancelled is not None and cancelled.is_set():
                raise IpcUnavailable("cancelled while connecting")
            if time.monotonic() >= deadline:
                raise TimeoutError(f"the deployer said nothing within {timeout:g} s")


def shutdown_quietly(sock: socket.socket) -> None:
    """Shut ``sock`` down, which wakes a thread blocked reading it."""
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
