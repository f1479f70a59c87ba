"""YARP's flow control as connection policies (seed 002, §5 and its Figure 2): one writer,
a fast observer and a slow one, for each writer mode (no-wait, wait-after, wait-before)
and reader buffering (single, double, triple). What each reader got and what the writer
waited are counted: a waiting writer with a single or double buffer loses nothing and is
slowed to its slowest reader; a no-wait writer never waits, and its slow reader loses
what it could not hold (counted); a triple buffer (DATA) always has room."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import pytest

from dataflow import ConnPolicy, FlowStatus, InputPort, OutputPort, WaitMode
from dataflow.buffers import WaitingStorage

N = 40  #: samples the writer writes, as fast as it can
SLOW_S = 0.004  #: the slow observer's work per sample (its workload, not a synchronisation)


@dataclass
class Outcome:
    got: dict[str, list[int]]  #: per reader, the values it read, in order
    dropped: dict[str, int]
    waited: float  #: seconds the writer spent waiting for room
    read_when_written: int  #: what the slow reader had read when the writer was done


def run(policy: ConnPolicy) -> Outcome:
    out: OutputPort[int] = OutputPort(int, "out")
    readers = {"fast": InputPort(int, "fast"), "slow": InputPort(int, "slow")}
    conns = {name: out.connect_to(port, policy) for name, port in readers.items()}
    got: dict[str, list[int]] = {name: [] for name in readers}
    done = threading.Event()

    def observe(name: str, pause: float) -> None:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:  # bounded in time; ends when the writer is done and all is read
            flow, value = readers[name].read()
            if flow is FlowStatus.NEW_DATA:
                got[name].append(value)
                if value == N:
                    return
                time.sleep(pause)
            elif done.is_set():
                return
            else:
                time.sleep(0.0005)

    threads = [threading.Thread(target=observe, args=(name, pause)) for name, pause in (("fast", 0.0),
                                                                                        ("slow", SLOW_S))]
    for thread in threads:
        thread.start()
    for value in range(1, N + 1):
        out.write(value)
    read_when_written = len(got["slow"])
    done.set()
    for thread in threads:
        thread.join(35)
    waited = sum(c.storage.waited for c in conns.values() if isinstance(c.storage, WaitingStorage))
    return Outcome(got, {name: c.dropped for name, c in conns.items()}, waited, read_when_written)


@pytest.mark.parametrize("reader", ["single", "double"])
@pytest.mark.parametrize("wait", [WaitMode.WAIT_BEFORE, WaitMode.WAIT_AFTER])
def test_a_waiting_writer_loses_nothing_and_waits_for_its_slowest_reader(reader: str, wait: WaitMode) -> None:
    outcome = run(ConnPolicy.parse(f"{reader},{wait.value}").with_(wait_timeout=10.0))
    assert outcome.got == {"fast": list(range(1, N + 1)), "slow": list(range(1, N + 1))}
    assert outcome.dropped == {"fast": 0, "slow": 0}
    assert outcome.waited > 0  # it was held back ...
    assert outcome.read_when_written >= N - (1 if reader == "single" else 2) - 1  # ... to the slow reader's pace


@pytest.mark.parametrize("reader", ["single", "double"])
def test_a_no_wait_writer_never_waits_and_a_slow_reader_counts_what_it_lost(reader: str) -> None:
    outcome = run(ConnPolicy.parse(reader))
    assert outcome.waited == 0 and outcome.read_when_written < N // 2  # done long before the slow reader
    slow = outcome.got["slow"]
    assert len(slow) < N and slow == sorted(slow)
    assert outcome.dropped["slow"] == N - len(slow)  # every sample it did not get is counted


@pytest.mark.parametrize("wait", list(WaitMode))
def test_a_triple_buffer_always_has_room_so_its_writer_never_waits(wait: WaitMode) -> None:
    outcome = run(ConnPolicy.triple_buffer(wait))
    assert outcome.waited == 0
    assert outcome.got["slow"][-1] == N  # the newest sample always reaches it
    assert outcome.dropped["slow"] == N - len(outcome.got["slow"])


def test_a_wait_has_a_deadline_then_the_sample_is_refused_and_counted() -> None:
    out: OutputPort[int] = OutputPort(int, "out")
    port = InputPort(int, "nobody_reads")
    conn = out.connect_to(port, ConnPolicy.single_buffer(WaitMode.WAIT_BEFORE).with_(wait_timeout=0.05))
    assert out.write(1).name == "WRITE_SUCCESS"
    assert out.write(2).name == "WRITE_FAILURE"  # waited 0.05 s for room that never came
    assert conn.dropped == 1 and port.read() == (FlowStatus.NEW_DATA, 1)


@pytest.mark.parametrize("text, policy", [
    ("single", ConnPolicy.buffer(1)),
    ("double,wait-before", ConnPolicy.buffer(2).with_(wait=WaitMode.WAIT_BEFORE)),
    ("triple,wait-after", ConnPolicy.data().with_(wait=WaitMode.WAIT_AFTER)),
    ("buffer:8,wait-after", ConnPolicy.buffer(8).with_(wait=WaitMode.WAIT_AFTER)),
])
def test_the_short_forms_name_yarps_modes(text: str, policy: ConnPolicy) -> None:
    assert ConnPolicy.parse(text) == policy
    assert ConnPolicy.parse(str(policy)) == policy


@pytest.mark.parametrize("text, words", [("single,wait-forever", "a writer's wait is no-wait, wait-after or "
                                                                   "wait-before"),
                                         ("quadruple", "expected 'data'")])
def test_a_wrong_short_form_says_the_right_ones(text: str, words: str) -> None:
    with pytest.raises(ValueError, match=words):
        ConnPolicy.parse(text)
    with pytest.raises(ValueError, match="wait_timeout"):
        ConnPolicy.single_buffer(WaitMode.WAIT_BEFORE).with_(wait_timeout=float("nan"))
