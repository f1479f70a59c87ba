"""A subscriber's inbox on an output port is that connection's storage: it tags each
sample with an increasing write number, and whatever happens to the subscriber (full,
over its byte budget, unable to measure a sample) the writer's write succeeds and the
task's other readers get their samples."""

from __future__ import annotations

import threading

from dataflow import ConnPolicy, InputPort, OutputPort
from dataflow.policy import BufferPolicy, FlowStatus, WriteStatus
from dataflow.remote._inbox import Inbox


class _Failing(Inbox):
    def _admit(self, value: object) -> None:
        raise UnicodeEncodeError("utf-8", "\ud800", 0, 1, "surrogates not allowed")


def test_a_full_or_failing_subscriber_never_fails_the_writer() -> None:
    port = OutputPort(float, name="out")
    inbox = Inbox(port, ConnPolicy.buffer(2), name="sub")
    assert [port.write(float(i)) for i in range(4)] == [WriteStatus.WRITE_SUCCESS] * 4
    assert [seq for seq, _, _ in inbox.take()] == [1, 2] and inbox.dropped == 2
    inbox.limit(1)  # the byte budget
    assert [port.write(float(i)) for i in range(3)] == [WriteStatus.WRITE_SUCCESS] * 3
    failing = _Failing(port, ConnPolicy.buffer(8), name="bad")
    local = InputPort(float, name="local")
    port.connect_to(local)  # a reader connected after the subscriber
    assert port.write(9.0) is WriteStatus.WRITE_SUCCESS
    assert local.read() == (FlowStatus.NEW_DATA, 9.0)
    assert [v for _, _, v in failing.take()] == [9.0]  # measuring failed: logged, the sample kept
    shared = ConnPolicy.buffer(2).with_(buffer_policy=BufferPolicy.SHARED)
    Inbox(port, shared, name="shared").close()  # any policy a subscriber asks for is its own inbox's


def test_write_numbers_only_go_up_with_concurrent_writers() -> None:
    port = OutputPort(int, name="out")
    inbox = Inbox(port, ConnPolicy.buffer(10_000), name="sub")
    start = threading.Barrier(2)

    def writer(base: int) -> None:
        start.wait(5)
        for k in range(2_000):
            port.write(base + k)

    threads = [threading.Thread(target=writer, args=(b,)) for b in (0, 100_000)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    numbers = [seq for seq, _, _ in inbox.take()]
    assert len(numbers) == 4_000 and inbox.dropped == 0  # every sample kept once
    assert all(b > a for a, b in zip(numbers, numbers[1:]))  # never repeated, never back
