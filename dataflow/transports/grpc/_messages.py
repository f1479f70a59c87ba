"""gRPC's messages of the sample path (private to the ``grpc`` transport, both halves):
frames joined into messages up to :data:`BATCH_BYTES`, a frame larger than
:data:`PART_BYTES` in parts (:func:`messages_of`, :class:`Parts`), and the bound of a
carrier's queue (:func:`room`)."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from typing import Generic, TypeVar

from dataflow.transports import frames
from dataflow.transports.limits import MAX_FRAME_BYTES

__all__ = ["BATCH_BYTES", "PART_BYTES", "Parts", "ROOM", "ROOM_BYTES", "messages_of", "passthrough", "room"]

ROOM = 256  #: frames a gRPC link or subscription holds for its stream's thread, at most ...
ROOM_BYTES = 4 * 1024 * 1024  #: ... and encoded bytes (then the writer end's own queue, by its policy)
BATCH_BYTES = 1024 * 1024  #: encoded samples sent in one message, at most
PART_BYTES = 1024 * 1024  #: a frame larger than this goes in parts of this size (gRPC's messages: 4 MiB at most)


def passthrough(data: bytes) -> bytes:
    """A gRPC serializer for frames that are bytes already."""
    return data


def messages_of(batch: list[bytes]) -> Iterator[bytes]:
    """The gRPC messages carrying ``batch`` (encoded frames, oldest first): frames joined
    end to end up to :data:`BATCH_BYTES` a message (one frame holding their samples), a
    frame larger than :data:`PART_BYTES` in parts, each a message holding nothing else
    (protobuf would merge a part joined to a frame)."""
    joined: list[bytes] = []
    size = 0
    for data in batch:
        if len(data) > PART_BYTES or (joined and size + len(data) > BATCH_BYTES):
            if joined:
                yield b"".join(joined)
                joined, size = [], 0
            if len(data) > PART_BYTES:
                yield from _parts_of(data)
                continue
        joined.append(data)
        size += len(data)
    if joined:
        yield b"".join(joined)


_PART = b"\x72"  # field 14 (part), length-delimited: the same number in LinkRequest and SubscribeResponse
_MORE = b"\x78\x01"  # field 15 (more) = true


def _parts_of(data: bytes) -> Iterator[bytes]:
    """``data`` as part messages (see :func:`messages_of`): one copy of each part."""
    view = memoryview(data)
    for start in range(0, len(data), PART_BYTES):
        chunk = view[start:start + PART_BYTES]
        more = _MORE if start + PART_BYTES < len(data) else b""
        yield b"".join((_PART, frames.varint(len(chunk)), chunk, more))


M = TypeVar("M")


class Parts(Generic[M]):
    """A frame sent in parts (:func:`messages_of`), whole again: :meth:`whole` returns each
    message as it is, or None while the parts of one come; the last part gives the frame
    parsed with ``parse``. A frame over :data:`~dataflow.transports.limits.MAX_FRAME_BYTES`
    is dropped whole and counted in :attr:`dropped` (a writer refuses one before it
    leaves). One receiving thread."""

    def __init__(self, parse: Callable[[bytes], M]) -> None:
        self._parse = parse
        self._parts: list[bytes] = []
        self._size = 0
        self._skipping = False
        self.dropped = 0

    def whole(self, message: M) -> M | None:
        part: bytes = message.part  # type: ignore[attr-defined]  # LinkRequest and SubscribeResponse alike
        if not part and not self._parts and not self._skipping:
            return message  # the common case: a message of its own
        more = message.more  # type: ignore[attr-defined]  # (as above)
        if not self._skipping:
            self._parts.append(part)
            self._size += len(part)
            if self._size > MAX_FRAME_BYTES:
                self.dropped += 1
                self._parts, self._size, self._skipping = [], 0, True
        if more:
            return None
        if self._skipping:
            self._skipping = False
            return None
        data = b"".join(self._parts)
        self._parts, self._size = [], 0
        return self._parse(data)


def room(queue: deque[bytes], size: list[int], data: bytes) -> bool:
    """Whether a frame of ``data`` fits in a carrier's queue (:data:`ROOM`, :data:`ROOM_BYTES`)."""
    return not queue or (len(queue) < ROOM and size[0] + len(data) <= ROOM_BYTES)
