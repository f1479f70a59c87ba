"""TCPROS's wire pieces: the connection header and framed messages, bounded.

A connection header is a 4-byte little-endian length, then fields, each a 4-byte length
and ``key=value`` in UTF-8. A message is a 4-byte length and its ROS 1 bytes. A service
response is an ok byte (1 ok, 0 error), then a frame: the response, or the error text.

The blocking helpers (:func:`read_header`, :func:`recv_exact`) serve the node's control
thread and the service client; they read exactly what they need (a latched message
following a header stays in the socket) and stop at a deadline.
"""

from __future__ import annotations

import socket
import struct
import time
from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["HeaderError", "Limits", "decode_header", "encode_header", "frame", "read_header", "recv_exact"]

LEN = struct.Struct("<I")
MAX_FIELDS = 64  #: header fields a peer may send


@dataclass(frozen=True)
class Limits:
    """A node's bounds on what peers send and on how long it waits for them."""

    max_header: int = 256 * 1024  #: bytes of one connection header
    max_message: int = 64 << 20  #: bytes of one message (a larger one is skipped and counted)
    header_timeout: float = 5.0  #: s an accepted peer has to send its header
    connect_timeout: float = 3.0  #: s to ask a publisher for its topic and shake hands
    max_connections: int = 1000  #: accepted connections open at once (more are refused)
    max_per_peer: int = 250  #: accepted connections open at once from one address (below max_connections)
    idle_seconds: float = 120.0  #: s a service connection may wait for a request, or a subscriber take none
    queue_size: int = 100  #: messages a publisher queues per slow subscriber (oldest dropped)
    queue_bytes: int = 32 << 20  #: bytes a publisher queues per slow subscriber
    xmlrpc_bytes: int = 1 << 20  #: bytes of one request to the node's XML-RPC API
    xmlrpc_seconds: float = 5.0  #: s one XML-RPC request may take, first byte to last

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (isinstance(value, (int, float)) and value > 0 and value == value and value != float("inf")):
                raise ValueError(f"Limits.{name} must be a finite number > 0, not {value!r}")
        if self.max_per_peer > self.max_connections:
            raise ValueError(f"Limits.max_per_peer ({self.max_per_peer}) must not exceed max_connections "
                             f"({self.max_connections}): one peer would take them all")


class HeaderError(ValueError):
    """A malformed, oversized or unreadable TCPROS connection header."""


def encode_header(fields: Mapping[str, str]) -> bytes:
    """A connection header with its 4-byte length prefix."""
    parts = []
    for key, value in fields.items():
        item = f"{key}={value}".encode()
        parts += [LEN.pack(len(item)), item]
    body = b"".join(parts)
    return LEN.pack(len(body)) + body


def decode_header(body: bytes | bytearray | memoryview) -> dict[str, str]:
    """The fields of a header ``body`` (without its length prefix).

    Raises :class:`HeaderError` for a field overrunning the body, a field without
    ``=``, an empty key, text that is not UTF-8, or more than :data:`MAX_FIELDS` fields.
    """
    fields: dict[str, str] = {}
    view, pos, end = memoryview(body), 0, len(body)
    while pos < end:
        if end - pos < 4:
            raise HeaderError(f"header field length cut short at byte {pos}")
        (size,) = LEN.unpack_from(view, pos)
        pos += 4
        if size > end - pos:
            raise HeaderError(f"header field of {size} bytes overruns the header ({end - pos} left)")
        key, sep, value = _text(view[pos : pos + size]).partition("=")
        if not sep or not key:
            raise HeaderError(f"header field {key[:40]!r} is not key=value")
        fields[key] = value
        pos += size
        if len(fields) > MAX_FIELDS:
            raise HeaderError(f"header has more than {MAX_FIELDS} fields")
    return fields


def _text(raw: memoryview) -> str:
    try:
        return str(raw, "utf-8")
    except UnicodeDecodeError as exc:
        raise HeaderError(f"header field is not UTF-8 ({exc.reason})") from None


def frame(payload: bytes | bytearray | memoryview) -> bytes:
    """``payload`` with its 4-byte length prefix."""
    return LEN.pack(len(payload)) + bytes(payload)


def recv_exact(sock: socket.socket, size: int, deadline: float) -> bytearray:
    """Exactly ``size`` bytes from a blocking ``sock`` by ``deadline`` (``time.monotonic``).

    Raises ``TimeoutError`` at the deadline, ``ConnectionError`` if the peer closes.
    """
    buf = bytearray(size)
    view, got = memoryview(buf), 0
    while got < size:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError(f"peer sent {got} of {size} bytes before the deadline")
        sock.settimeout(left)
        n = sock.recv_into(view[got:])
        if n == 0:
            raise ConnectionError(f"peer closed the connection after {got} of {size} bytes")
        got += n
    return buf


def read_header(sock: socket.socket, deadline: float, max_bytes: int) -> dict[str, str]:
    """Read one connection header from ``sock`` by ``deadline``; at most ``max_bytes``.

    Raises :class:`HeaderError` (malformed or too large), ``TimeoutError``, ``ConnectionError``.
    """
    (size,) = LEN.unpack(recv_exact(sock, 4, deadline))
    if size > max_bytes:
        raise HeaderError(f"header of {size} bytes is larger than the {max_bytes}-byte limit")
    return decode_header(recv_exact(sock, size, deadline))


def read_frame(sock: socket.socket, deadline: float, max_bytes: int) -> bytearray:
    """Read one framed message from ``sock`` by ``deadline``; at most ``max_bytes``.

    Raises ``ValueError`` (too large), ``TimeoutError``, ``ConnectionError``.
    """
    (size,) = LEN.unpack(recv_exact(sock, 4, deadline))
    if size > max_bytes:
        raise ValueError(f"message of {size} bytes is larger than the {max_bytes}-byte limit")
    return recv_exact(sock, size, deadline)
