"""A writer end under two threads: a sample written while another thread holds the end
(a transport's flush, or a second writer) is sent by that thread once it lets go, in
order, and never left waiting with no one to send it (a lost wake-up otherwise: the
next writes queue behind it and nothing sends them until the channel ends)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

from scart_wire import codec
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb
from dataflow import ConnPolicy, OutputPort, TaskContext
from dataflow.transports import frames
from dataflow.transports.ends import WriterEnd, attach, detach


class Src(TaskContext):
    out = OutputPort(int)


class GatedCarrier:
    """Sends everything; the send of ``hold_at`` blocks until released (the lock held)."""

    def __init__(self, hold_at: int) -> None:
        self.sent: list[int] = []
        self.hold_at = hold_at
        self.holding = threading.Event()
        self.release = threading.Event()

    @staticmethod
    def encode(sample) -> bytes:
        return b"x"

    def send(self, sample, data) -> bool:
        if sample.n == self.hold_at:
            self.holding.set()
            assert self.release.wait(10)
        self.sent.append(sample.n)
        return True


@contextmanager
def first_write_in_flight(policy: ConnPolicy) -> Iterator[tuple[Src, WriterEnd, GatedCarrier]]:
    """A writer end whose first write is being sent by another thread (holding the end's
    lock) for the duration of the block; on leaving, that send ends."""
    src = Src("src")
    end = WriterEnd(src.out, policy, "test end")
    attach(src.out, end)
    carrier = GatedCarrier(hold_at=1)
    end.connected("test", carrier, new_peer=True)
    first = threading.Thread(target=src.out.write, args=(0,))
    first.start()
    try:
        assert carrier.holding.wait(10)
        yield src, end, carrier
    finally:
        carrier.release.set()
        first.join(10)
        assert not first.is_alive()
        detach(src.out, end)


def test_a_sample_written_while_another_thread_sends_is_sent_after_it_in_order() -> None:
    for policy in (ConnPolicy.data(), ConnPolicy.buffer(8), ConnPolicy.circular_buffer(4)):
        with first_write_in_flight(policy) as (src, end, carrier):
            assert src.out.write(20).name == "WRITE_SUCCESS"  # write 2, while 1 is being sent: it waits ...
            assert carrier.sent == [] and end.pending == 1
        assert carrier.sent == [1, 2] and end.pending == 0, policy  # ... and goes once 1 is out
        assert end.sent == 2 and end.unsent == 0


def test_a_full_buffer_refuses_the_newest_even_while_another_thread_sends() -> None:
    with first_write_in_flight(ConnPolicy.buffer(2)) as (src, end, carrier):
        statuses = [src.out.write(k).name for k in (20, 30, 40)]  # room for two
    assert statuses == ["WRITE_SUCCESS", "WRITE_SUCCESS", "WRITE_FAILURE"]  # a mandatory buffer says so
    assert carrier.sent == [1, 2, 3] and end.unsent == 1  # the fourth write: refused, counted


def test_a_circular_buffer_keeps_the_newest_and_counts_the_rest_while_another_thread_sends() -> None:
    with first_write_in_flight(ConnPolicy.circular_buffer(4)) as (src, end, carrier):
        for k in range(9):  # writes 2..10 while 1 is being sent: more than the buffer holds
            src.out.write(k)
        assert end.pending == 4  # bounded while it waits
    assert carrier.sent == [1, 7, 8, 9, 10] and end.unsent == 5  # the newest four, the rest counted


class FullCarrier:
    """A socket that has no room until ``room`` is set; joins frames (``batch_bytes``),
    as ipc's carrier does: what it sends is kept as whole messages."""

    def __init__(self, batch_bytes: int) -> None:
        self.batch_bytes = batch_bytes
        self.room = False
        self.messages: list[bytes] = []

    encode = staticmethod(frames.encoder(int))

    def send(self, sample, data) -> bool:
        if not self.room:
            return False
        self.messages.append(data)
        return True


@contextmanager
def reader_behind(batch_bytes: int) -> Iterator[tuple[Src, WriterEnd, FullCarrier]]:
    """A connected writer end whose carrier has no room yet (the reader is behind)."""
    src = Src("src")
    end = WriterEnd(src.out, ConnPolicy.buffer(100), "test end")
    attach(src.out, end)
    carrier = FullCarrier(batch_bytes)
    try:
        end.connected("test", carrier, new_peer=True)
        yield src, end, carrier
    finally:
        detach(src.out, end)


def test_what_waited_for_room_leaves_joined_in_order_and_within_the_batch_size() -> None:
    with reader_behind(batch_bytes=200) as (src, end, carrier):
        for k in range(30):  # the reader is behind: all 30 wait
            assert src.out.write(1000 + k).name == "WRITE_SUCCESS"
        assert end.pending == 30 and carrier.messages == []
        carrier.room = True
        end.flush()  # the transport, once its socket has room again
    assert end.pending == 0 and end.sent == 30 and end.unsent == 0
    assert 1 < len(carrier.messages) < 30  # many samples per message, none larger than the batch size
    assert all(len(m) <= 200 for m in carrier.messages)
    received = [(s.sequence, codec.decode(s.value)) for m in carrier.messages for s in pb.LinkRequest.FromString(m).samples]
    assert received == [(k + 1, 1000 + k) for k in range(30)]  # each once, in order, as written


def test_a_batch_the_carrier_has_no_room_for_stays_queued_whole() -> None:
    with reader_behind(batch_bytes=10_000) as (src, end, carrier):
        for k in range(5):
            src.out.write(k)
        end.flush()  # still no room: nothing is lost or counted as sent
        assert end.pending == 5 and end.sent == 0 and end.unsent == 0
        carrier.room = True
        end.flush()
    assert len(carrier.messages) == 1 and end.sent == 5
    assert [s.sequence for s in pb.LinkRequest.FromString(carrier.messages[0]).samples] == [1, 2, 3, 4, 5]
