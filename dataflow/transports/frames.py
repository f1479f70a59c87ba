"""scart's own frames, shared by the ``ipc`` and ``grpc`` transports (``proto/``:
``SubscribeResponse``, ``LinkRequest``, ``LinkResponse``).

A sample is encoded once per write (:func:`sample_frame`): a ``SubscribeResponse``
holding that one sample. ``LinkRequest`` numbers its first four fields as
``SubscribeResponse`` does, so the same bytes go to a subscriber and to a link; and
protobuf merges repeated fields of concatenated messages, so frames joined end to end
are one frame holding their samples in order (a batch costs a ``join``, not a re-encode).
A frame is at most :data:`~dataflow.transports.limits.MAX_FRAME_BYTES`: a larger sample is
refused as it is encoded (:class:`~dataflow.transports.limits.SampleTooLarge`), at ``write()``.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, TypeAlias, TypeVar

from scart_wire import codec
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from scart_wire.types import registry
from dataflow.transports.ends import OutSample, ReaderEnd, WriterEnd
from dataflow.transports.limits import MAX_FRAME_BYTES, SampleTooLarge

if TYPE_CHECKING:
    from dataflow.transports import Peer

__all__ = ["encoder", "feed", "heartbeat", "link_hello", "report_of", "sample_frame", "varint"]

_Frame = pb.SubscribeResponse
T = TypeVar("T")
#: A parsed frame of samples: a subscription's or a link's.
Frame: TypeAlias = "pb.SubscribeResponse | pb.LinkRequest"
#: How the samples of one port's type become a frame's bytes (:func:`encoder`).
Encoder: TypeAlias = "Callable[[OutSample[object]], bytes]"


def sample_frame(sample: OutSample[object]) -> bytes:
    """``sample`` as an encoded frame (see the module docstring); raises ``TypeError``
    (a :class:`~dataflow.PortTypeError`) when the value cannot be encoded, and
    :class:`~dataflow.transports.limits.SampleTooLarge` when it is over the limit."""
    frame = _Frame()  # built in place: half the time of nested constructors (the hot path of every write)
    frame.samples.add(sequence=sample.n, source_time_ns=sample.t_ns).value.CopyFrom(
        codec.encode(sample.value, sample.type))
    data = frame.SerializeToString()
    if len(data) > MAX_FRAME_BYTES:
        raise SampleTooLarge(len(data))
    return data


def varint(x: int) -> bytes:
    """``x`` (0 <= x < 2**64) as a protobuf varint."""
    out = bytearray()
    while x > 0x7F:
        out.append((x & 0x7F) | 0x80)
        x >>= 7
    out.append(x)
    return bytes(out)


def _number_frame(type_name: str, pack: Callable[[object], bytes]) -> Encoder:
    """A :func:`sample_frame` for a port of a number type: the same bytes as the
    generated code makes (a test holds the two equal), put together directly. A
    periodic writer pays for every step cold, at each write: building the message
    costs half as much again as these few joins."""
    name = type_name.encode()
    width = len(pack(0))
    value_field = bytes((0x0A, len(name) + width + 4, 0x0A, len(name))) + name + bytes((0x12, width))  # Sample.value

    def number_frame(sample: OutSample[object]) -> bytes:
        value, n, t_ns = sample.value, sample.n, sample.t_ns
        if type(value) is not sample.type or not (0 < n < 1 << 63 and 0 < t_ns < 1 << 63):
            return sample_frame(sample)  # a subclass, or a field the generated code would leave out
        body = value_field + pack(value) + b"\x10" + varint(n) + b"\x18" + varint(t_ns)
        return b"\x12" + bytes((len(body),)) + body  # SubscribeResponse.samples: one, under 128 bytes
    return number_frame


_NUMBER_FRAMES: Mapping[object, Encoder] = MappingProxyType({py_type: _number_frame(registry.type_name(py_type), struct.Struct(code).pack)
                                   for py_type, code in ((float, "<d"), (int, "<q"))})


def encoder(py_type: object) -> Encoder:
    """The frame encoder for samples of ``py_type`` (one function per type: a sample is
    encoded once for every carrier of its port that uses it)."""
    return _NUMBER_FRAMES.get(py_type, sample_frame)


def heartbeat(boot_id: str = "", dropped: int = 0, sent_last: int = 0) -> bytes:
    """A frame without samples: the writer is alive (and who it is, and ``dropped``: its
    tail, the samples it could not send since ``sent_last``, the last one it sent)."""
    return pb.SubscribeResponse(heartbeat=True, boot_id=boot_id, dropped=dropped,
                                sent_last=sent_last).SerializeToString()


def connected(end: WriterEnd[Any], boot_id: str) -> bytes:
    """A subscription's first frame: who writes, and up to which write number the stream
    will not carry (see ``SubscribeResponse.written``). Made under ``end``'s lock (its
    ``first`` hook), so no write slips in between."""
    return pb.SubscribeResponse(heartbeat=True, boot_id=boot_id, written=end.port.last_sample()[0]).SerializeToString()


def feed(end: ReaderEnd[T], message: Frame, values: Mapping[int, object] | None = None) -> int:
    """Hand the samples of one parsed frame (``SubscribeResponse`` or ``LinkRequest``) to
    ``end``; returns how many it stored. ``values``: the value of a sample whose bytes
    are elsewhere (shared memory), by its index in the frame. (Every sample of every
    channel comes through here: each step is one the hot path needs.)"""
    if end.on_frame is not None:
        end.on_frame(message)
    boot_id = message.boot_id
    if boot_id and boot_id != end.boot_id:
        end.writer(boot_id)
    stored = 0
    receive = end.receive
    if values:
        for i, s in enumerate(message.samples):
            if receive(s.sequence, s.source_time_ns, values.get(i, s.value)):
                stored += 1
    else:
        for s in message.samples:
            if receive(s.sequence, s.source_time_ns, s.value):
                stored += 1
    if message.heartbeat:
        if type(message) is _Frame and message.written:  # a subscription's first frame (a link's hello says it)
            end.loss.began(message.written, end.init)
        end.loss.report(message.dropped, message.sent_last if type(message) is _Frame else 0)
    return stored


def report_of(end: ReaderEnd[Any], *, known: bool = True, final: bool = False, pending: int = 0) -> pb.LinkResponse:
    """The ``LinkResponse`` a link's reader end sends back."""
    return pb.LinkResponse(last=end.last, lost=end.lost, known=known, final=final, pending=pending)


def link_hello(end: WriterEnd[Any], peer: Peer) -> pb.LinkHello:
    """What a link's reader end is told when its channel opens (on every transport that
    carries links to a deployer): where it goes, with the policy the control plane
    negotiated, and from which write number on it counts."""
    return pb.LinkHello(task=peer.task, port=peer.port, policy=peer.policy_msg, channel=peer.channel,
                        after=end.peer_last or end.start, boot_id=peer.boot_id, source=end.port.qualname,
                        type_name=end.port.type_name, name=peer.name, source_ns=peer.source_ns)
