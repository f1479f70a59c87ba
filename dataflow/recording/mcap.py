"""MCAP files: reading those someone handed you, with bounds (what ``scart play``, ``info``
and ``record --recover`` share), and the output file ``record`` writes.

:class:`McapScan` reads a file record by record on its own (not through the ``mcap``
package's readers), so that nothing in the file decides how much is read, allocated or
decompressed:

* a record longer than what is left of the file ends the scan as *truncated* at its
  offset (a recording cut short by a crash or a full disk): what came before is read;
* a chunk declaring more than :data:`MAX_CHUNK_BYTES` uncompressed is refused before
  anything is decompressed, and decompression stops at the declared size (a chunk that
  holds more than it declares is refused too);
* a message longer than :data:`MAX_MESSAGE_BYTES`, not JSON, or nested deeper than
  :data:`MAX_JSON_DEPTH` is skipped and counted, never decoded further;
* the work of one file is bounded (:class:`Budget`), so that a few kilobytes cannot
  take seconds and hundreds of megabytes (a chunk of millions of identical tiny
  messages compresses to almost nothing): at most :data:`MAX_RATIO` bytes decompressed
  per byte of the file (a chunk declaring more is refused before it is decompressed;
  all chunks together likewise, with :data:`MIN_EXPANSION` bytes allowed whatever the
  file's size), at most one message per byte of the file (and :data:`MIN_MESSAGES`
  whatever its size), at most :data:`MAX_READ_SECONDS` of reading (the time spent in
  the scan, not what a caller does between two records). A chunk's messages are read
  one by one from its data, never all made at once.

Anything else malformed raises :class:`McapError`, whose text says what is wrong and
where (the caller names the file): one line for the user, never a traceback.
"""

from __future__ import annotations

import io
import json
import os
import stat
import struct
import time
from array import array
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypeVar

from dataflow.transports.limits import MAX_FRAME_BYTES
from scart_wire.bounds import nesting_depth

if TYPE_CHECKING:
    from types import ModuleType

    from mcap.opcode import Opcode
    from mcap.records import Channel, Chunk, McapRecord, Schema

R = TypeVar("R", bound="McapRecord")

__all__ = ["MAX_CHUNK_BYTES", "MAX_JSON_DEPTH", "MAX_MESSAGE_BYTES", "MAX_RATIO", "MAX_READ_SECONDS", "Budget",
           "McapError", "McapScan", "Sink", "decode_json", "open_output", "output_problem"]

MAGIC = b"\x89MCAP0\r\n"
MAX_CHUNK_BYTES = 64 << 20  #: a chunk's uncompressed size, at most
#: A message's size, at most: a chunk's (a recorded 1080p RGB frame is 8.3 MB of JSON).
MAX_MESSAGE_BYTES = MAX_CHUNK_BYTES
MAX_RECORD_BYTES = MAX_CHUNK_BYTES + (1 << 20)  #: a record of the file (a chunk and its header), at most
MAX_JSON_DEPTH = 64
MAX_RATIO = 1000  #: bytes decompressed per byte of the file, at most (a chunk, and all of them together)
MIN_EXPANSION = 64 << 20  #: bytes any file may decompress in all, whatever its size
MIN_MESSAGES = 1_000_000  #: messages any file may hold, whatever its size (else one per byte of it)
MAX_READ_SECONDS = 60.0  #: seconds of reading one file, at most
_HEAD = struct.Struct("<BQ")  # opcode, length
_LOG_TIME = struct.Struct("<Q")  # a Message record's log time, after its channel id (u16) and sequence (u32)
_CHECK_EVERY = 4096  # messages between two looks at the clock


@dataclass(frozen=True)
class Budget:
    """What reading one file may cost, at most (see the module docstring): decompressed
    bytes per byte of the file (``ratio``), messages in all, seconds of reading. ``of``
    makes the one for a file of a given size."""

    ratio: int = MAX_RATIO
    expansion: int = MIN_EXPANSION
    messages: int = MIN_MESSAGES
    seconds: float = MAX_READ_SECONDS

    @classmethod
    def of(cls, size: int) -> Budget:
        """The budget of a file of ``size`` bytes: everything scales with it, from a floor."""
        return cls(expansion=max(MIN_EXPANSION, MAX_RATIO * size), messages=max(MIN_MESSAGES, size))


class McapError(ValueError):
    """A file scart will not read further: what is wrong, and where (byte offset)."""


@dataclass
class McapScan:
    """One pass over an MCAP file (see the module docstring). Iterate :meth:`records` (or
    :meth:`messages`); afterwards :attr:`truncated_at` is the offset where a file cut
    short ends (None for a complete one) and :attr:`complete` says a footer was read."""

    path: str
    budget: Budget | None = None  #: None: :meth:`Budget.of` the file's size
    truncated_at: int | None = None
    complete: bool = False
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    count: int = 0  #: messages read so far
    expanded: int = 0  #: bytes decompressed so far
    spent: float = 0.0  #: seconds spent reading so far
    _budget: Budget = field(default_factory=Budget, init=False, repr=False)  # the one in force, once reading

    def records(self) -> Iterator[McapRecord]:
        """The file's Schema, Channel and Message records in file order (a chunk's messages
        in log-time order). Blocks on file reads only; raises :class:`McapError` (also when
        the file would cost more than its :class:`Budget`)."""
        resumed = time.monotonic()
        for record in self._records():
            self.spent += time.monotonic() - resumed
            yield record
            resumed = time.monotonic()
        self.spent += time.monotonic() - resumed

    def _records(self) -> Iterator[McapRecord]:
        with self._open() as fh:
            size = os.fstat(fh.fileno()).st_size
            self._budget = self.budget or Budget.of(size)
            if fh.read(len(MAGIC)) != MAGIC:
                raise McapError("not an MCAP file (it does not start with the MCAP magic)")
            pos = len(MAGIC)
            while True:
                head = fh.read(_HEAD.size)
                if len(head) < _HEAD.size:
                    self.truncated_at = pos
                    return
                opcode, length = _HEAD.unpack(head)
                if length > size - pos - _HEAD.size:
                    self.truncated_at = pos
                    return
                if length > MAX_RECORD_BYTES:
                    raise McapError(f"a record of {length} bytes at byte {pos}: more than scart reads "
                                    f"({MAX_RECORD_BYTES} bytes)")
                body = fh.read(length)
                if opcode == _opcodes().FOOTER:
                    self.complete = True
                    return
                yield from self._parse(opcode, body, pos)
                pos += _HEAD.size + length

    def _spend(self, messages: int, at: int, started: float) -> None:
        """Count ``messages`` more read (in the chunk at byte ``at``, this stretch of reading
        begun at ``started``); :class:`McapError` past the budget's messages or seconds."""
        budget = self._budget
        self.count += messages
        if self.count > budget.messages:
            raise McapError(f"more than {budget.messages} messages by byte {at}: more than scart reads from a file "
                            f"this size (one message per byte of it, {MIN_MESSAGES} at least)")
        if self.spent + time.monotonic() - started > budget.seconds:
            raise McapError(f"still reading after {budget.seconds:g} s, at byte {at} ({self.count} messages): more "
                            "than scart spends on one file")

    def messages(self) -> Iterator[tuple[str, int, dict[str, object] | None]]:
        """``(topic, log_time ns, JSON data or None)`` of each message (None: skipped, see
        :func:`decode_json`); a message of an unknown channel raises :class:`McapError`."""
        from mcap.records import Message

        for record in self.records():
            if isinstance(record, Message):
                channel = self.channels.get(record.channel_id)
                if channel is None:
                    raise McapError(f"a message of channel {record.channel_id}, which the file never declares")
                yield channel.topic, record.log_time, decode_json(record.data)

    def _open(self) -> io.BufferedReader:
        """The file, opened without blocking on a FIFO or a device (those are refused)."""
        try:
            fd = os.open(self.path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        except OSError as exc:
            raise McapError(exc.strerror or str(exc)) from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise McapError("not a regular file")
        return open(fd, "rb")  # noqa: SIM115 - closed by the caller's with

    def _parse(self, opcode: int, body: bytes, pos: int) -> Iterator[McapRecord]:
        """The records one top-level record holds (a chunk's, decompressed with bounds)."""
        ops, records = _opcodes(), _records()
        if opcode == ops.CHUNK:
            yield from self._chunk(_read(records.Chunk, body, pos), pos)
        elif opcode in (ops.SCHEMA, ops.CHANNEL, ops.MESSAGE):
            kinds: dict[int, type[McapRecord]] = {ops.SCHEMA: records.Schema, ops.CHANNEL: records.Channel,
                                                  ops.MESSAGE: records.Message}
            kind = kinds[opcode]
            if kind is records.Message:
                self._spend(1, pos, time.monotonic())
            record = _read(kind, body, pos)
            self._learn(record)
            yield record

    def _chunk(self, chunk: Chunk, pos: int) -> Iterator[McapRecord]:
        """A chunk's Schema and Channel records (learned), then its messages in log-time
        order, each made only when it is yielded."""
        records = _records()
        declared = chunk.uncompressed_size
        budget = self._budget
        if declared > max(MAX_FRAME_BYTES, budget.ratio * len(chunk.data)):  # one sample may be that big, however
            # well it compresses (a black camera frame); a bomb of many small ones stops at the messages budget
            raise McapError(f"the chunk at byte {pos} declares {declared} bytes from {len(chunk.data)} compressed "
                            f"({declared // max(1, len(chunk.data))}:1): more than scart expands ({budget.ratio}:1)")
        if self.expanded + declared > budget.expansion:
            raise McapError(f"the chunks up to byte {pos} declare {self.expanded + declared} bytes in all: more than "
                            f"scart expands from a file this size ({budget.ratio} bytes per byte of it)")
        self.expanded += declared
        data = _decompress(chunk, pos)
        times, offsets, ordered = array("Q"), array("Q"), True
        started = time.monotonic()
        for kind, offset, length in _chunk_records(data, pos):
            if kind is records.Message:
                if length < 22:
                    raise McapError(f"a malformed Message record at byte {pos}")
                log_time = _LOG_TIME.unpack_from(data, offset + 6)[0]
                ordered = ordered and (not times or log_time >= times[-1])
                times.append(log_time)
                offsets.append(offset)
                if len(offsets) % _CHECK_EVERY == 0:
                    self._spend(_CHECK_EVERY, pos, started)
            else:
                record = _read(kind, data[offset:offset + length], pos)
                self._learn(record)
                yield record
        self._spend(len(offsets) % _CHECK_EVERY, pos, started)
        order: Sequence[int] = range(len(offsets)) if ordered else sorted(range(len(offsets)), key=times.__getitem__)
        for i in order:
            offset = offsets[i]
            length = _HEAD.unpack_from(data, offset - _HEAD.size)[1]
            yield _read(records.Message, data[offset:offset + length], pos)

    def _learn(self, record: McapRecord) -> None:
        from mcap.records import Channel, Schema

        if isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            self.channels[record.id] = record


def decode_json(data: bytes) -> dict[str, object] | None:
    """A message's JSON object, or None when it is over :data:`MAX_MESSAGE_BYTES`, not JSON,
    not an object, or nested deeper than :data:`MAX_JSON_DEPTH`."""
    if len(data) > MAX_MESSAGE_BYTES:
        return None
    try:
        value = json.loads(data)
    except (ValueError, RecursionError):
        return None
    try:
        if not isinstance(value, dict) or nesting_depth(value, MAX_JSON_DEPTH, MAX_MESSAGE_BYTES) > MAX_JSON_DEPTH:
            return None
    except ValueError:
        return None
    return value


def _chunk_records(data: bytes, pos: int) -> Iterator[tuple[type[McapRecord], int, int]]:
    """``(kind, offset, length)`` of each Schema, Channel and Message record in a chunk's
    ``data`` (other kinds skipped), nothing parsed yet."""
    ops, records = _opcodes(), _records()
    kinds: dict[int, type[McapRecord]] = {ops.SCHEMA: records.Schema, ops.CHANNEL: records.Channel,
                                          ops.MESSAGE: records.Message}
    offset = 0
    while offset < len(data):
        if len(data) - offset < _HEAD.size:
            raise McapError(f"the chunk at byte {pos} ends inside a record")
        opcode, length = _HEAD.unpack_from(data, offset)
        offset += _HEAD.size
        if length > len(data) - offset:
            raise McapError(f"the chunk at byte {pos} holds a record longer than itself")
        kind = kinds.get(opcode)
        if kind is not None:
            yield kind, offset, length
        offset += length


def _decompress(chunk: Chunk, pos: int) -> bytes:
    """A chunk's data, decompressing at most its declared size (see the module docstring)."""
    declared = chunk.uncompressed_size
    if declared > MAX_CHUNK_BYTES:
        raise McapError(f"the chunk at byte {pos} declares {declared} bytes uncompressed: more than scart reads "
                        f"({MAX_CHUNK_BYTES} bytes)")
    try:
        if chunk.compression == "":
            data = bytes(chunk.data)
        elif chunk.compression == "zstd":
            data = _unzstd(chunk.data, declared)
        elif chunk.compression == "lz4":
            import lz4.frame

            data = lz4.frame.LZ4FrameDecompressor().decompress(chunk.data, max_length=declared + 1)
        else:
            raise McapError(f"the chunk at byte {pos} uses compression {chunk.compression[:40]!r}, which scart "
                            "does not read (zstd, lz4 or none)")
    except McapError:
        raise
    except Exception as exc:  # noqa: BLE001 - the decompressors' own errors: a corrupt chunk
        raise McapError(f"the chunk at byte {pos} does not decompress: {exc}") from None
    if len(data) != declared:
        raise McapError(f"the chunk at byte {pos} holds {'more' if len(data) > declared else 'less'} than the "
                        f"{declared} bytes it declares")
    return data


def _unzstd(data: bytes, declared: int) -> bytes:
    """zstd data, at most ``declared`` + 1 bytes of it (more is refused by the caller)."""
    import zstandard

    parts: list[bytes] = []
    got = 0
    with zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data)) as reader:
        while got <= declared:
            part = reader.read(min(1 << 20, declared + 1 - got))
            if not part:
                break
            parts.append(part)
            got += len(part)
    return b"".join(parts)


def _read(kind: type[R], body: bytes, pos: int) -> R:
    """One record of ``kind`` parsed from ``body`` (:class:`McapError` when malformed)."""
    from mcap.data_stream import ReadDataStream

    try:
        stream = ReadDataStream(io.BytesIO(body))
        read: Callable[..., R] = getattr(kind, "read")  # noqa: B009 - each record class's own (not the base's)
        if kind.__name__ == "Message":
            return read(stream, len(body))
        return read(stream)
    except Exception:  # noqa: BLE001 - struct, decoding and end-of-data errors alike: a malformed record
        raise McapError(f"a malformed {kind.__name__} record at byte {pos}") from None


def _opcodes() -> type[Opcode]:
    from mcap.opcode import Opcode

    return Opcode


def _records() -> ModuleType:
    from mcap import records

    return records


# ---- the file record writes -----------------------------------------------------------------

def output_problem(path: str, overwrite: bool) -> str | None:
    """Why ``path`` cannot be the file to write (a folder, a missing folder, an existing
    file without ``overwrite``), or None."""
    if path.endswith(os.sep) or os.path.isdir(path):
        return (f"-o {path}: a folder; scart record writes one .mcap file (not a folder as ros2 bag): "
                f"give -o {os.path.join(path, 'run.mcap')}")
    parent = os.path.dirname(path) or "."
    if not os.path.isdir(parent):
        return f"-o {path}: the folder {parent} does not exist"
    if os.path.exists(path) and not overwrite:
        return f"-o {path}: the file exists; give --overwrite to replace it, or another name"
    return None


def open_output(path: str, overwrite: bool) -> int:
    """The file descriptor of a new output file (exclusive unless ``overwrite``), readable
    and writable by its owner only (0600, as token files are: a recording holds what the
    robot did); raises ``ValueError`` with one line when it cannot be made."""
    flags = os.O_WRONLY | os.O_CREAT | (os.O_TRUNC if overwrite else os.O_EXCL)
    try:
        fd = os.open(path, flags, 0o600)
    except FileExistsError:
        raise ValueError(f"-o {path}: the file exists; give --overwrite to replace it") from None
    except OSError as exc:
        raise ValueError(f"-o {path}: {exc.strerror}") from None
    try:
        os.fchmod(fd, 0o600)  # a file overwritten keeps its mode otherwise
    except OSError:
        pass  # a file system without modes: nothing more to do
    return fd


class Sink:
    """What the MCAP writer writes to: the file descriptor, unbuffered, so that the bytes
    on disk are exactly :attr:`pos` after each write (a failed write is cut back cleanly)."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.pos = 0

    def write(self, data: bytes) -> int:
        view = memoryview(data)
        while view:
            n = os.write(self.fd, view)
            self.pos += n
            view = view[n:]
        return len(data)

    def tell(self) -> int:
        return self.pos

    def flush(self) -> None:
        """Nothing is held back: every write went to the file."""
