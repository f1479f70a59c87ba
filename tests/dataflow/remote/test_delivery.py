"""The subscriber's hand-over (Mailbox) keeps a policy's meaning exactly as a local
connection does, because it is that connection's storage; a byte budget (limit) only
ever lowers what it holds, and every loss is counted."""

from __future__ import annotations

import threading

from dataflow.policy import ConnPolicy
from dataflow.remote._delivery import Mailbox


def _drain(box: Mailbox) -> list:
    out = []
    for _ in range(1000):
        item = box.get(0.0)
        if item is None:
            return out
        out.append(item)
    return out


def test_data_keeps_the_newest_and_counts_the_overwritten() -> None:
    box: Mailbox[int] = Mailbox(ConnPolicy.data())
    assert all(box.put(k) for k in range(5))
    assert _drain(box) == [4]
    assert box.dropped == 4
    assert box.get(0.0) is None  # read once: no OLD_DATA repeat for a consumer


def test_buffer_refuses_when_full_and_a_ring_drops_its_oldest() -> None:
    fifo: Mailbox[int] = Mailbox(ConnPolicy.buffer(3))
    assert [fifo.put(k) for k in range(5)] == [True, True, True, False, False]
    assert _drain(fifo) == [0, 1, 2] and fifo.dropped == 2
    ring: Mailbox[int] = Mailbox(ConnPolicy.circular_buffer(3))
    assert all(ring.put(k) for k in range(5))
    assert _drain(ring) == [2, 3, 4] and ring.dropped == 2


def test_limit_lowers_the_capacity_within_the_policy() -> None:
    fifo: Mailbox[int] = Mailbox(ConnPolicy.buffer(100))
    fifo.limit(2)
    assert [fifo.put(k) for k in range(4)] == [True, True, False, False]
    assert _drain(fifo) == [0, 1] and fifo.dropped == 2
    ring: Mailbox[int] = Mailbox(ConnPolicy.circular_buffer(100))
    ring.limit(2)
    for k in range(5):
        ring.put(k)
    assert _drain(ring) == [3, 4] and ring.dropped == 3
    fifo.limit(10_000)  # never above the policy's own size
    assert sum(fifo.put(k) for k in range(150)) == 100


def test_get_waits_for_an_item_and_close_wakes_it() -> None:
    box: Mailbox[str] = Mailbox(ConnPolicy.buffer(4))
    got: list = []
    consumer = threading.Thread(target=lambda: got.append(box.get(10.0)))
    consumer.start()
    box.put("x")
    consumer.join(10.0)
    assert got == ["x"]
    consumer = threading.Thread(target=lambda: got.append(box.get(10.0)))
    consumer.start()
    box.close()
    consumer.join(10.0)
    assert not consumer.is_alive() and got == ["x", None]
