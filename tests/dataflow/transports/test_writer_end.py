"""A writer end under two threads: a sample written while another thread holds the end
(a transport's flush, or a second writer) is sent by that thread once it lets go, in
order, and never left waiting with no one to send it (a lost wake-up otherwise: the
next writes queue behind it and nothing sends them until the channel ends)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

from dataflow import ConnPolicy, OutputPort, TaskContext
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
