"""YARP's port protocol on a TCP stream (YARP 3.5's ``Protocol``, ``AbstractCarrier``,
``TcpCarrier``, ``TextCarrier`` and ``PortCommand``, read from its sources): what a
connection's first bytes say, how each message is framed, and what is acknowledged.

A connection opens with 8 bytes naming its carrier:

============  ==========================  =============================================
carrier       first 8 bytes               then
============  ==========================  =============================================
``tcp``       ``YA`` int32 7777+3+128     the sender's name (int32 length, bytes, NUL);
              ``RP``                      the receiver answers ``YA`` int32 port ``RP``;
                                          each message is acknowledged (``YA`` 0 ``RP``)
``fast_tcp``  ``YA`` int32 7777+3 ``RP``  as ``tcp``, without acknowledgements
``text``      ``CONNECT ``                the sender's name and CRLF; the receiver
                                          answers ``Welcome NAME`` CRLF; messages are
                                          lines (``d``, then the bottle's text)
``text_ack``  ``CONNACK ``                as ``text``; each message is answered (the
                                          reply's lines, then ``<ACK>``)
``udp``       ``YA`` int32 7777+0 ``RP``  the sender's name; the receiver answers the
                                          port of a datagram socket, the TCP connection
                                          closes, and messages go as datagrams
                                          (:mod:`.dgram`)
============  ==========================  =============================================

A binary message is an index — ``YA`` int32 10 ``RP``, a byte with the number of blocks,
a byte 1, eight bytes 0xFF, the blocks' lengths (int32 each) and an int32 0 — then the
blocks: first the port command (8 bytes: int32 length of its text, ``~``, a key, 0, 1;
``d``: data for the owner, ``D``: the same with no reply wanted, ``a``: an administrative
bottle, ``\\0``: a text command follows, such as ``q`` to close), then the bottle.
All integers are little-endian. Pure functions and one parser class, no sockets.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from types import MappingProxyType

__all__ = ["ACK", "CARRIERS", "QUIT_BINARY", "Frame", "IncomingParser", "ProtocolError", "carrier_header", "carrier_of",
           "command_block", "data_frame", "data_parts", "read_number", "sender_specifier", "text_frame", "yarp_number"]

_I32 = struct.Struct("<i")
_NUMBER = struct.Struct("<2si2s")
_INDEX = struct.Struct("<2si2sBB")  # a message's index: YA 10 RP, its blocks, its reply blocks
#: A data message's index (2 blocks and 1 reply block; their lengths) and port command
#: (its length 0, ``~``, its key, 0, 1): 38 bytes, then the bottle.
_DATA_MESSAGE = struct.Struct("<2si2sBB8xiii4xcc2x")
TCP_SPECIFIER, UDP_SPECIFIER, MCAST_SPECIFIER = 3, 0, 1
ACK_FLAG = 128
#: The carriers scart speaks natively, and whether each acknowledges every message.
CARRIERS = MappingProxyType({"tcp": True, "fast_tcp": False, "text": False, "text_ack": True, "udp": False})
MAX_NAME = 1000  #: bytes of a sender's name (YARP clamps it there too)
MAX_LINE = 1 << 20  #: bytes of one line on a text connection


class ProtocolError(ValueError):
    """A peer broke the port protocol (a wrong magic, a bad index, a message over the limit)."""


def yarp_number(n: int) -> bytes:
    """``YA`` + int32 ``n`` + ``RP``: the framing of headers, indexes and acknowledgements."""
    return _NUMBER.pack(b"YA", n, b"RP")


def read_number(data: bytes | memoryview) -> int | None:
    """The int32 of a ``YA..RP`` 8-byte frame, or None when ``data`` is not one."""
    a, n, b = _NUMBER.unpack(data)
    return n if a == b"YA" and b == b"RP" else None


ACK = yarp_number(0)


def carrier_header(carrier: str) -> bytes:
    """The 8 bytes that open a connection of ``carrier``; ``ValueError`` for one scart
    does not speak (``mcast``: scart sends no multicast)."""
    if carrier == "udp":
        return yarp_number(7777 + UDP_SPECIFIER)
    if carrier == "tcp":
        return yarp_number(7777 + TCP_SPECIFIER + ACK_FLAG)
    if carrier == "fast_tcp":
        return yarp_number(7777 + TCP_SPECIFIER)
    if carrier == "text":
        return b"CONNECT "
    if carrier == "text_ack":
        return b"CONNACK "
    if carrier == "mcast":
        raise ValueError("carrier 'mcast': scart sends no multicast (it would leave this host); a port connects to "
                         "it with tcp, fast_tcp, text or udp")
    raise ValueError(f"carrier {carrier!r}: scart speaks {', '.join(CARRIERS)}")


def carrier_of(header: bytes) -> str:
    """The carrier an incoming connection's first 8 bytes name; :class:`ProtocolError` otherwise."""
    if header == b"CONNECT ":
        return "text"
    if header == b"CONNACK ":
        return "text_ack"
    n = read_number(header)
    if n is None:
        raise ProtocolError(f"not a YARP connection (first bytes {bytes(header)!r})")
    spec = n - 7777
    if spec % 16 == TCP_SPECIFIER:
        return "tcp" if spec & ACK_FLAG else "fast_tcp"
    if spec % 16 == UDP_SPECIFIER:
        return "udp"
    if spec % 16 == MCAST_SPECIFIER:
        raise ProtocolError("carrier mcast asked: scart sends no multicast (tcp, fast_tcp, text and udp it speaks)")
    raise ProtocolError(f"unknown carrier specifier {spec}")


def sender_specifier(name: str) -> bytes:
    """What a binary carrier sends after its header: the sender's name."""
    raw = name.encode("utf-8") + b"\0"
    return _I32.pack(len(raw)) + raw


def command_block(key: str, text: str = "") -> bytes:
    """A port command (``d``, ``D``, ``a``; or ``\\0`` with ``text`` such as ``q``)."""
    if key == "\0":
        raw = text.encode("utf-8") + b"\0"
        return _I32.pack(len(raw)) + b"~\0\0\x01" + raw
    return b"\0\0\0\0~" + key.encode("ascii") + b"\0\x01"


def data_frame(blocks: list[bytes]) -> list[bytes]:
    """A binary message of ``blocks`` (the port command first) as the parts to send."""
    index = yarp_number(10) + bytes((len(blocks), 1)) + b"\xff" * 8
    lengths = struct.pack(f"<{len(blocks) + 1}i", *(len(b) for b in blocks), 0)
    return [index + lengths, *blocks]


_DATA_HEAD = yarp_number(10) + bytes((2, 1)) + b"\xff" * 8
_DATA_LENGTHS = struct.Struct("<3i")
_DATA_COMMAND = command_block("D")


def data_parts(bottle: bytes) -> tuple[bytes, bytes]:
    """``data_frame([command_block("D"), bottle])`` as two parts, the header one: what a
    port writes for each sample, built with one pack (the bottle is not copied)."""
    return _DATA_HEAD + _DATA_LENGTHS.pack(8, len(bottle), 0) + _DATA_COMMAND, bottle


def text_frame(key: str, line: str) -> bytes:
    """A text-carrier message: the command line, then the bottle's text."""
    return f"{key}\r\n{line}\r\n".encode("utf-8")


QUIT_BINARY = b"".join(data_frame([command_block("\0", "q")]))


@dataclass
class Frame:
    """One message from a peer: its port command ``key`` (``d``, ``D``, ``a``, or the first
    character of a text command), the command's ``text``, and the bottle's ``payload``
    (bytes on a binary carrier, the text line on a text one)."""

    key: str
    text: str
    payload: bytes | str


class IncomingParser:
    """The receiving side of one connection, fed bytes as they come (:meth:`feed`): the
    header, the sender's name, then messages. Bounded: ``max_message`` bytes per
    message, :data:`MAX_NAME` per name, :data:`MAX_LINE` per text line. Raises
    :class:`ProtocolError` when the peer breaks the protocol (nothing here decodes a
    bottle). Not thread-safe (one io thread feeds it)."""

    def __init__(self, max_message: int) -> None:
        self.max_message = max_message
        self.carrier = ""
        self.sender = ""
        self._buf = bytearray()
        self._need = 0  # bytes of the message body being waited for (binary)
        self._key = ""
        self._pending_text: str | None = None  # a text-mode 'd' waiting for its bottle line

    @property
    def greeted(self) -> bool:
        """The header and the sender's name have been read."""
        return bool(self.sender)

    @property
    def buffered(self) -> int:
        """Bytes received and not yet parsed."""
        return len(self._buf)

    def feed(self, data: bytes) -> list[Frame]:
        """Take ``data``; every whole message now read, in order."""
        if not self._buf and self._need == 0 and self.sender and not self.carrier.startswith("text"):
            if len(data) >= _DATA_MESSAGE.size:  # the commonest: one data message, as YARP and scart write it
                ya, ten, rp, blocks, replies, command, size, reply, tilde, key = _DATA_MESSAGE.unpack_from(data)
                if size == len(data) - _DATA_MESSAGE.size and ya == b"YA" and rp == b"RP" and ten == 10 and \
                        blocks == 2 and replies == 1 and command == 8 and reply == 0 and tilde == b"~" and \
                        key != b"\0" and size + 8 <= self.max_message:
                    return [Frame(key.decode("latin-1"), "", data[_DATA_MESSAGE.size:])]
            frames, used = self._whole(data)  # the common case: whole messages, read where they are
            if used == len(data):
                return frames
            data = data[used:]
            self._buf += data
            return frames + self._more()
        self._buf += data
        return self._more()

    def _whole(self, data: bytes) -> tuple[list[Frame], int]:
        """The whole binary messages at the start of ``data``, read in place, and how many
        bytes they took (a partial one is left for the buffer)."""
        frames: list[Frame] = []
        pos, size = 0, len(data)
        while size - pos >= 18:
            ya, ten, rp, blocks, replies = _INDEX.unpack_from(data, pos)
            if ya != b"YA" or rp != b"RP" or ten != 10:
                break  # not an index: the slow path says what is wrong
            blocks += replies
            start = pos + 18 + 4 * blocks
            if size < start:
                break
            lengths = struct.unpack_from(f"<{blocks}i", data, pos + 18)
            total = sum(lengths)
            if min(lengths, default=0) < 0 or total > self.max_message or size - start < total:
                break
            frames.append(_command(data, start, start + total))
            pos = start + total
        return frames, pos

    def _more(self) -> list[Frame]:
        """Every whole message the buffer holds now."""
        frames: list[Frame] = []
        while True:
            if not self.sender:
                if not self._greeting():
                    return frames
                continue
            frame = self._text() if self.carrier.startswith("text") else self._binary()
            if frame is None:
                return frames
            frames.append(frame)

    def _greeting(self) -> bool:
        buf = self._buf
        if not self.carrier:
            if len(buf) < 8:
                return False
            self.carrier = carrier_of(bytes(buf[:8]))
            del buf[:8]
        if self.carrier.startswith("text"):
            line = self._line()
            if line is None:
                return False
            self.sender = line.strip() or "/anonymous"
            return True
        if len(buf) < 4:
            return False
        (n,) = _I32.unpack_from(buf)
        if not 0 < n <= MAX_NAME:
            raise ProtocolError(f"a sender name of {n} bytes (at most {MAX_NAME})")
        if len(buf) < 4 + n:
            return False
        self.sender = bytes(buf[4:4 + n]).split(b"\0", 1)[0].decode("utf-8", errors="replace") or "/anonymous"
        del buf[:4 + n]
        return True

    def _line(self) -> str | None:
        buf = self._buf
        end = buf.find(b"\n")
        if end < 0:
            if len(buf) > MAX_LINE:
                raise ProtocolError(f"a text line of over {MAX_LINE} bytes")
            return None
        line = bytes(buf[:end]).rstrip(b"\r").decode("utf-8", errors="replace")
        del buf[:end + 1]
        return line

    def _text(self) -> Frame | None:
        while True:
            line = self._line()
            if line is None:
                return None
            if self._pending_text is not None:
                key, self._pending_text = self._pending_text, None
                return Frame(key, "", line)
            if not line.strip():
                continue
            key = line.strip()[0]
            if line.strip() in ("d", "D", "do", "a"):  # the bottle is the next line
                self._pending_text = "D" if line.strip() == "do" else key
                continue
            return Frame(key, line.strip(), "")

    def _binary(self) -> Frame | None:
        buf = self._buf
        if not self._need:
            if len(buf) < 18:
                return None
            if read_number(bytes(buf[:8])) != 10:
                raise ProtocolError(f"a broken index (first bytes {bytes(buf[:8])!r})")
            blocks = buf[8] + buf[9]
            if len(buf) < 18 + 4 * blocks:
                return None
            lengths = struct.unpack_from(f"<{blocks}i", buf, 18)
            total = sum(lengths)
            if any(n < 0 for n in lengths) or total > self.max_message:
                raise ProtocolError(f"a message of {total} bytes (the limit is {self.max_message})")
            del buf[:18 + 4 * blocks]
            self._need = total if total else -1
        need = max(self._need, 0)
        if len(buf) < need:
            return None
        body = bytes(buf[:need])
        del buf[:need]
        self._need = 0
        return _command(body)


def _command(data: bytes, start: int = 0, end: int | None = None) -> Frame:
    """Split the binary message ``data[start:end]`` into its port command and the bottle
    after it (the bottle's bytes copied once)."""
    end = len(data) if end is None else end
    if end - start < 8 or data[start + 4:start + 5] != b"~":
        raise ProtocolError("a message without a port command")
    key = chr(data[start + 5])
    (n,) = _I32.unpack_from(data, start)
    if key != "\0":
        return Frame(key, "", data[start + 8:end])
    if not 0 <= n <= end - start - 8:
        raise ProtocolError(f"a port command of {n} bytes in a message of {end - start}")
    text = data[start + 8:start + 8 + n].split(b"\0", 1)[0].decode("utf-8", errors="replace")
    return Frame(text[:1] or "\0", text, data[start + 8 + n:end])
