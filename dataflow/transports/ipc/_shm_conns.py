"""shm's connections at the side that asked for them, and what both sides share
(private): ipc's, with a large sample's bytes in a shared-memory slot instead of on the
socket. The deployer's side (a link coming in, a subscription served) is
:mod:`._shm_serve`.

* The writer's side (:class:`SlotSender`, mixed into a link going out and a subscription
  served): a sample whose value is at least :data:`LARGE_BYTES` is written into a free
  slot of the channel's :class:`~._slots.SlotPool` (its one copy), announced to the reader
  with the slot's descriptor the first time, and sent as a small frame naming the slot.
  With no free slot (the reader holds them all) it goes on the socket as on ipc.
* The reader's side (:class:`SlotReader`, mixed into a link coming in and a
  subscription read): announced slots are mapped read-only; a sample naming one is handed
  over as a :class:`~scart_wire.codec.Payload` over the slot's bytes (an array type is
  decoded as a read-only view of them), and the slot is given back to the writer once
  the last value made of it is gone.
"""

from __future__ import annotations

import array
import logging
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from dataflow.policy import ConnPolicy, ConnType
from dataflow.ports import OutputPort
from dataflow.transports import frames
from dataflow.transports._shared import SharedFeed
from dataflow.transports.ends import OutSample, WriterEnd
from dataflow.transports.ipc._conns import LinkOut, SubIn
from dataflow.transports.ipc._hub import READS_PER_WAKE, Conn, Hub
from dataflow.transports.ipc._wire import CHUNK, WHOLE
from dataflow.transports.limits import MAX_FRAME_BYTES, SampleTooLarge
from dataflow.transports.ipc._slots import Slot, SlotMaps, SlotPool
from scart_wire import codec
from scart_wire.arrays import ArraySpec
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from scart_wire.types import registry

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

__all__ = ["LARGE_BYTES", "ShmLinkOut", "ShmSubIn", "SlotReader", "SlotSender", "carries_large", "large_size"]

log = logging.getLogger(__name__)

LARGE_BYTES = 64 * 1024  #: a value this large goes in shared memory; a smaller one on the socket
EXTRA_SLOTS = 3  #: slots beyond the policy's buffer: the task's sample, the last one read, one on its way
MAX_FDS = 4  #: descriptors one message may carry
_TRUNC = int(socket.MSG_TRUNC)
_CTRUNC = int(socket.MSG_CTRUNC)


def large_size(value: Any) -> int:
    """How many bytes ``value``'s wire form takes, when it is a large kind (``bytes`` or a
    numpy array; 0 for any other: those go on the socket)."""
    kind = type(value)
    if kind is bytes:
        return len(value)
    if kind.__name__ == "ndarray" and kind.__module__ == "numpy":
        return int(value.nbytes) + 1 + 8 * value.ndim
    return 0


def carries_large(py_type: object) -> bool:
    """Whether a port of ``py_type`` may carry samples of :data:`LARGE_BYTES` or more:
    ``bytes``, or an array type whose fixed size (if any) is that large."""
    if py_type is bytes:
        return True
    size = getattr(py_type, "fixed_bytes", 0)
    return hasattr(py_type, "fixed_bytes") and (size is None or size >= LARGE_BYTES)


def slots_for(policy: ConnPolicy) -> int:
    """The slots a channel of ``policy`` may have: its buffer, and :data:`EXTRA_SLOTS`."""
    return (1 if policy.type is ConnType.DATA else policy.size) + EXTRA_SLOTS


# ---- the writer's side ----------------------------------------------------------------
class SlotSender(Conn):
    """The carrier of a writer end on an shm connection (see the module docstring)."""

    batch_bytes = 0  # a large sample's frame is not bytes: queued samples go one by one
    pool: SlotPool
    plain: Callable[[OutSample], bytes]  # the frame encoder of the port's type (small samples)

    def init_slots(self, port: OutputPort, policy: ConnPolicy) -> None:
        self.plain = frames.encoder(port.type)
        self.pool = SlotPool(slots_for(policy))

    def encode_large(self, sample: OutSample) -> bytes | OutSample:
        """The carrier's ``encode``: a small sample's frame (bytes), or the sample itself:
        written into a slot when sent. Raises :class:`~dataflow.transports.limits.SampleTooLarge` over the limit."""
        size = large_size(sample.value)
        if size < LARGE_BYTES:
            return self.plain(sample)
        if size > MAX_FRAME_BYTES:
            raise SampleTooLarge(size)
        return sample

    def send(self, sample: OutSample, data: bytes | OutSample) -> bool:
        if isinstance(data, bytes):
            return self.send_sample(sample, data)
        value, py_type = sample.value, sample.type
        if type(value) is bytes:
            body: bytes | None = value
        else:  # an array: written as it is into the slot; any other type: its wire bytes
            body = None if isinstance(py_type, ArraySpec) else registry.encode(value, py_type).data
        size = len(body) if body is not None else large_size(value)
        slot = self.pool.take(size)
        if slot is None:  # every slot held by the reader: on the socket, as ipc sends it
            return self.send_sample(sample, frames.sample_frame(sample))
        _fill(slot, value, body)
        name = registry.type_name(py_type)
        frame = pb.SubscribeResponse()
        frame.samples.add(sequence=sample.n, source_time_ns=sample.t_ns, slot=slot.id, slot_size=size).value.type_name = name
        if self._put_slot(slot, frame.SerializeToString()):
            return True
        self.pool.give_back(slot)
        return False

    def _put_slot(self, slot: Slot, frame: bytes) -> bool:
        """Send ``frame`` (the slot's announcement first, with its descriptor, the first
        time) without blocking; False when there is no room (the writer end keeps the sample)."""
        if not self._lock.acquire(blocking=False):
            return False
        try:
            if self._held or self._closed:
                return False
            if slot.fd is not None:
                retired = [pb.ShmSlot(id=i, size=0) for i in self.pool.retired]
                announce = pb.SubscribeResponse(slots=[*retired, pb.ShmSlot(id=slot.id, size=slot.size)])
                try:
                    self.sock.sendmsg([WHOLE, announce.SerializeToString()],
                                      [(socket.SOL_SOCKET, socket.SCM_RIGHTS, array.array("i", [slot.fd]))],
                                      socket.MSG_DONTWAIT)
                except OSError:
                    return self._failed_send()
                self.pool.retired.clear()
                slot.announced()
            try:
                self.sock.sendmsg((WHOLE, frame), (), socket.MSG_DONTWAIT)
            except OSError:
                return self._failed_send()
            self.sent_at = time.monotonic()
            return True
        finally:
            self._lock.release()

    def released(self, report: pb.LinkResponse) -> bool:
        """A reader's message giving slots back (True: that is all it is)."""
        if not report.released:
            return False
        self.pool.release(report.released)
        return True

    def close_slots(self) -> None:
        self.pool.close()


def _fill(slot: Slot, value: Any, body: bytes | None) -> None:
    """Write a value's wire form into ``slot`` (its one copy): ``body`` (its bytes), or
    for an array, its shape then its data."""
    import numpy as np

    memory = slot.memory
    if body is not None:
        memory[:len(body)] = np.frombuffer(body, dtype=np.uint8)
        return
    head = np.frombuffer(_array_head(value), dtype=np.uint8)
    memory[:head.size] = head
    target = memory[head.size:head.size + value.nbytes].view(value.dtype.newbyteorder("<")).reshape(value.shape)
    np.copyto(target, value, casting="no" if value.dtype.byteorder != ">" else "equiv")


def _array_head(value: Any) -> bytes:
    import struct

    return struct.pack(f"<B{value.ndim}Q", value.ndim, *value.shape)


class ShmLinkOut(SlotSender, LinkOut):
    """A link going out on shm: ipc's, with its large samples in slots."""

    def __init__(self, hub: Hub, sock: socket.socket, end: WriterEnd) -> None:
        LinkOut.__init__(self, hub, sock, end)
        self.init_slots(end.port, end.policy)
        self.encode = self.encode_large  # the instance's own: slots are this channel's

    def message(self, data: bytes) -> None:
        if not self.released(pb.LinkResponse.FromString(data)):
            super().message(data)

    def ended_hook(self) -> None:
        super().ended_hook()
        self.close_slots()


# ---- the reader's side ----------------------------------------------------------------
class SlotReader(Conn):
    """The reader's side of an shm connection (see the module docstring): it reads the
    descriptors that come with announcements, and gives slots back."""

    maps: SlotMaps

    def init_maps(self) -> None:
        self.maps = SlotMaps(self._release)
        self._fds: deque[int] = deque()
        self._released: deque[int] = deque()
        self._release_asked = False
        self._release_lock = threading.Lock()

    def readable(self) -> None:
        ancillary = socket.CMSG_SPACE(MAX_FDS * array.array("i").itemsize)
        for _ in range(READS_PER_WAKE):
            try:
                frame, anc, flags, _ = self.sock.recvmsg(CHUNK + 1, ancillary)
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionResetError:  # said once, before what the peer sent last: read that next
                if not self._reset:
                    self._reset = True
                    continue
                frame, anc, flags = b"", [], 0
            except OSError:
                frame, anc, flags = b"", [], 0
            for level, kind, data in anc:
                if level == socket.SOL_SOCKET and kind == socket.SCM_RIGHTS:
                    fds = array.array("i")
                    fds.frombytes(data[:len(data) - len(data) % fds.itemsize])
                    self._fds.extend(fds)
            if not frame:
                self.close()
                return
            message = self._assembler.feed(frame, bool(flags & _TRUNC) or bool(flags & _CTRUNC))
            if message is not None:
                try:
                    self.message(message)
                except Exception:  # noqa: BLE001 - one bad message never ends the io thread
                    log.exception("shm %s: a message could not be handled", self.label)
            self._close_stray_fds()

    def slot_values(self, message: pb.SubscribeResponse | pb.LinkRequest) -> dict[int, codec.Payload] | None:
        """Map the slots ``message`` announces; the values of its samples that name one
        (a :class:`~scart_wire.codec.Payload` over the slot's bytes, or an empty one that
        fails its check for a slot that is not there: refused and counted)."""
        for slot in message.slots:
            if slot.size == 0:
                self.maps.retire(slot.id)
                continue
            if not self._fds:
                raise ValueError(f"slot {slot.id} announced without its memory")
            self.maps.add(slot.id, slot.size, self._fds.popleft())
        values: dict[int, codec.Payload] | None = None
        for i, sample in enumerate(message.samples):
            if sample.slot:
                data: NDArray[np.uint8] | bytes
                try:
                    data = self.maps.view(sample.slot, sample.slot_size)
                except ValueError:
                    data = b""
                if values is None:
                    values = {}
                values[i] = codec.Payload(sample.value.type_name, data)
        return values

    def _close_stray_fds(self) -> None:
        """Descriptors no announcement took (a malformed message): closed."""
        import os

        while self._fds:
            os.close(self._fds.popleft())

    def _release(self, slot_id: int) -> None:  # any thread: the last view of a sample went
        with self._release_lock:
            self._released.append(slot_id)
            asked, self._release_asked = self._release_asked, True
        if not asked and not self.ended.is_set():
            self.hub.call_later(self._send_released)

    def _send_released(self) -> None:  # the io thread
        with self._release_lock:
            ids = list(self._released)
            self._released.clear()
            self._release_asked = False
        if ids and not self.ended.is_set() and not self.put(pb.LinkResponse(released=ids).SerializeToString()):
            with self._release_lock:  # no room now: again once there is (drained)
                self._released.extendleft(reversed(ids))

    def drained(self) -> None:
        super().drained()
        if self._released:
            self._send_released()

    def ended_hook(self) -> None:
        super().ended_hook()
        self.maps.close()


class ShmSubIn(SlotReader, SubIn):
    """A subscription read on shm: ipc's, with large samples viewed in shared memory."""

    def __init__(self, hub: Hub, sock: socket.socket, feed: SharedFeed, label: str) -> None:
        SubIn.__init__(self, hub, sock, feed, label)
        self.init_maps()

    def readable(self) -> None:
        self.feed.alive()  # any byte: alive
        SlotReader.readable(self)

    def message(self, data: bytes) -> None:
        message = pb.SubscribeResponse.FromString(data)
        values = self.slot_values(message) if message.slots or message.samples else None
        if message.samples or not message.slots:
            self.feed.feed(message, values)
