"""scart's own frames, shared by the ``ipc`` and ``grpc`` transports (``proto/``:
``SubscribeResponse``, ``LinkRequest``, ``LinkResponse``).

A sample is encoded once per write (:func:`sample_frame`): a ``SubscribeResponse``
holding that one sample. ``LinkRequest`` numbers its first four fields as
``SubscribeResponse`` does, so the same bytes go to a subscriber and to a link; and
protobuf merges repeated fields of concatenated messages, so frames joined end to end
are one frame holding their samples in order (a batch costs a ``join``, not a re-encode).
"""

from __future__ import annotations

from typing import Any

from scart_wire import codec
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from dataflow.transports.ends import OutSample, ReaderEnd, WriterEnd

__all__ = ["feed", "heartbeat", "report_of", "sample_frame"]


def sample_frame(sample: OutSample) -> bytes:
    """``sample`` as an encoded frame (see the module docstring); raises ``TypeError``
    (a :class:`~dataflow.PortTypeError`) when the value cannot be encoded."""
    value = codec.encode(sample.value, sample.type)
    return pb.SubscribeResponse(samples=[pb.Sample(value=value, sequence=sample.n,
                                                   source_time_ns=sample.t_ns)]).SerializeToString()


def heartbeat(boot_id: str = "", dropped: int = 0) -> bytes:
    """A frame without samples: the writer is alive (and who it is, and ``dropped``: its
    tail, the samples it could not send since the last one it sent)."""
    return pb.SubscribeResponse(heartbeat=True, boot_id=boot_id, dropped=dropped).SerializeToString()


def connected(end: WriterEnd, boot_id: str) -> bytes:
    """A subscription's first frame: who writes, and up to which write number the stream
    will not carry (see ``SubscribeResponse.written``). Made under ``end``'s lock (its
    ``first`` hook), so no write slips in between."""
    return pb.SubscribeResponse(heartbeat=True, boot_id=boot_id, written=end.port.last_sample()[0]).SerializeToString()


def feed(end: ReaderEnd, message: Any) -> int:
    """Hand the samples of one parsed frame (``SubscribeResponse`` or ``LinkRequest``) to
    ``end``; returns how many it stored."""
    if end.on_frame is not None:
        end.on_frame(message)
    if message.boot_id:
        end.writer(message.boot_id)
    written = getattr(message, "written", 0)  # a subscription's first frame (a link's hello says it instead)
    if written:
        end.loss.began(written, end.init)
    stored = 0
    for s in message.samples:
        if end.receive(s.sequence, s.source_time_ns, s.value):
            stored += 1
    if message.heartbeat:
        end.loss.report(message.dropped)
    return stored


def report_of(end: ReaderEnd, *, known: bool = True, final: bool = False, pending: int = 0) -> Any:
    """The ``LinkResponse`` a link's reader end sends back."""
    return pb.LinkResponse(last=end.last, lost=end.lost, known=known, final=final, pending=pending)
