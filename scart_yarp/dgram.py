"""YARP's ``udp`` carrier (``UdpCarrier`` and ``DgramTwoWayStream``, read from YARP 3.5's
sources): the connection is agreed over TCP — the writer's header names ``udp``
(``YA`` int32 7777+0 ``RP``), the reader opens a datagram socket and answers its port
number — and then the TCP connection closes and every message travels as datagrams.

A message (its index and blocks, as on ``tcp``) is cut into datagrams of at most
:data:`MAX_PAYLOAD` bytes, each prefixed by 8 bytes: the CRC-32 of what follows and the
datagram's number within its message (0, 1, ...). Nothing is acknowledged: a datagram
lost, out of order or damaged loses its message, which the reader counts and skips (the
next datagram numbered 0 starts the next one). Pure functions and one reader class.
"""

from __future__ import annotations

import struct
import zlib

from .wire import Frame, IncomingParser, ProtocolError

__all__ = ["DatagramReader", "MAX_PAYLOAD", "datagrams"]

HEADER = struct.Struct("<Ii")
MAX_PAYLOAD = 65507 - HEADER.size  #: bytes of a message in one datagram, at most (YARP's limit)


def datagrams(parts: list[bytes]) -> list[bytes]:
    """A binary message (``data_frame``'s parts) as the datagrams that carry it."""
    data = b"".join(parts)
    out = []
    for number, start in enumerate(range(0, max(len(data), 1), MAX_PAYLOAD)):
        chunk = data[start:start + MAX_PAYLOAD]
        out.append(HEADER.pack(zlib.crc32(chunk), number) + chunk)
    return out


class DatagramReader:
    """The reading side of a ``udp`` connection: :meth:`feed` one datagram at a time, get
    the messages it completes; ``lost`` counts the messages a lost, damaged or
    out-of-order datagram cost. Bounded by ``max_message`` bytes per message. Not
    thread-safe (one io thread feeds it)."""

    def __init__(self, sender: str, max_message: int) -> None:
        self.sender = sender
        self.max_message = max_message
        self.lost = 0
        self._parser = self._fresh()
        self._next = 0  # the number the next datagram of the message under way must have

    def _fresh(self) -> IncomingParser:
        parser = IncomingParser(self.max_message)
        parser.carrier, parser.sender = "udp", self.sender  # agreed over TCP: messages only from here
        return parser

    def feed(self, datagram: bytes) -> list[Frame]:
        """Take one datagram; the whole messages it completed."""
        if len(datagram) < HEADER.size:
            return self._broken()
        crc, number = HEADER.unpack_from(datagram)
        if number == -1:  # YARP's keep-alive: no data
            return []
        payload = datagram[HEADER.size:]
        if zlib.crc32(payload) != crc or number != self._next:
            if number == 0 and zlib.crc32(payload) == crc:  # a new message: the one under way is lost
                self._broken()
                return self.feed(datagram)
            return self._broken()
        self._next += 1
        try:
            frames = self._parser.feed(payload)
        except ProtocolError:
            return self._broken()
        if frames and not self._parser.buffered:
            self._next = 0  # the message ended with this datagram: the next one starts a new one
        return frames

    def _broken(self) -> list[Frame]:
        if self._next or self._parser.buffered:
            self.lost += 1
        self._parser = self._fresh()
        self._next = 0
        return []
