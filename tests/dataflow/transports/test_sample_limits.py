"""No silent limit: a sample over its transport's limit is refused at ``write()``
(``WRITE_FAILURE``), counted in the channel's drops and said once with its size and the
limit; gRPC carries a large frame in parts, each within its own message limit."""

from __future__ import annotations

import logging

from dataflow import ConnPolicy, OutputPort
from dataflow.transports import frames
from dataflow.transports.ends import OutSample, WriterEnd, attach, detach
from dataflow.transports.grpc import PART_BYTES, Parts, messages_of
from dataflow.transports.limits import MAX_FRAME_BYTES, MAX_SAMPLE_BYTES
from scart_wire import rpc
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb


class Kept:
    """A carrier that keeps what it is sent."""

    def __init__(self, port: OutputPort) -> None:
        self.encode = frames.encoder(port.type)
        self.sent: list[bytes] = []

    def send(self, sample: OutSample, data: bytes) -> bool:
        self.sent.append(data)
        return True


def test_a_sample_over_the_limit_is_refused_at_write_counted_and_said_once(caplog) -> None:
    port: OutputPort[bytes] = OutputPort(bytes, name="frames")
    end = WriterEnd(port, ConnPolicy.buffer(4), "link l")
    carrier = Kept(port)
    attach(port, end)
    end.connected("ipc", carrier, new_peer=True)
    caplog.set_level(logging.WARNING, logger="dataflow.transports.ends")
    try:
        assert MAX_SAMPLE_BYTES >= 64 * 1024 * 1024
        assert port.write(bytes(MAX_SAMPLE_BYTES)).name == "WRITE_SUCCESS"  # 64 MiB of value: carried
        too_large = bytes(MAX_FRAME_BYTES + 1)
        assert port.write(too_large).name == "WRITE_FAILURE"
        assert port.write(too_large).name == "WRITE_FAILURE"
        assert port.write(b"small").name == "WRITE_SUCCESS"
        assert end.dropped == 2 and end.unsent == 2  # counted in the channel's drops
        assert [len(d) > MAX_SAMPLE_BYTES for d in carrier.sent] == [True, False]
        said = [r.getMessage() for r in caplog.records if "limit" in r.getMessage()]
        assert len(said) == 1, said  # once, however many
        size = int(said[0].split(" bytes encoded")[0].rsplit(" ", 1)[1])  # the sample's size, and the limit
        assert "link l" in said[0] and "sample 2" in said[0] and str(MAX_FRAME_BYTES) in said[0], said[0]
        assert MAX_FRAME_BYTES < size < MAX_FRAME_BYTES + 100
    finally:
        detach(port, end)


def test_grpc_carries_a_large_frame_in_parts_within_its_message_limit() -> None:
    def frame(n: int, size: int) -> bytes:
        return frames.sample_frame(OutSample(n, 1, b"\x01" * size, bytes))

    batch = [frame(1, 10), frame(2, 20), frame(3, 3 * PART_BYTES + 7), frame(4, 30), frame(5, 40)]
    messages = list(messages_of(batch))
    assert all(len(m) <= rpc.MAX_MESSAGE_BYTES for m in messages)
    parsed = [pb.LinkRequest.FromString(m) for m in messages]
    assert [len(p.samples) for p in parsed if not p.part] == [2, 2]  # small frames joined, never with a part
    assert all(not p.samples for p in parsed if p.part)
    assert sum(1 for p in parsed if p.part) == 4 and sum(1 for p in parsed if p.more) == 3

    parts = Parts(pb.SubscribeResponse.FromString)
    whole = [w for w in (parts.whole(pb.SubscribeResponse.FromString(m)) for m in messages) if w is not None]
    assert [s.sequence for w in whole for s in w.samples] == [1, 2, 3, 4, 5]
    assert whole[1].samples[0].value.data == b"\x01" * (3 * PART_BYTES + 7)


def test_grpc_drops_and_counts_a_frame_sent_in_parts_over_the_limit() -> None:
    parts = Parts(pb.SubscribeResponse.FromString)
    chunk = pb.SubscribeResponse(part=b"\x00" * PART_BYTES, more=True)
    rounds = MAX_FRAME_BYTES // PART_BYTES + 2
    assert all(parts.whole(chunk) is None for _ in range(rounds))
    assert parts.whole(pb.SubscribeResponse(part=b"\x00", more=False)) is None  # the end of the oversized one
    assert parts.dropped == 1
    after = pb.SubscribeResponse(heartbeat=True)
    assert parts.whole(after) is after  # the stream goes on
