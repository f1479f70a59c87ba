"""YARP's flow control on a link between two deployers (``ConnPolicy.wait`` over ``ipc``):
the paper's Figure 2 again, with the slow observer in the other deployer. A waiting writer
with a single buffer loses nothing and is held to the reader's pace by its reports; a
no-wait writer is never held and its reader counts what it lost; a transport that cannot
hold a writer back is refused at connect, naming those that can."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest
from support import wait_until

from dataflow import ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, TaskContext, WaitMode
from dataflow.remote import connect, serve_nameserver

N = 30


class Writer(TaskContext):
    out = OutputPort(int)


class Reader(TaskContext):
    inp = InputPort(int)


@pytest.fixture
def pair() -> Iterator[tuple[Writer, Reader, object]]:
    ns = serve_nameserver("127.0.0.1:0")
    d1, d2 = Deployer(), Deployer()
    writer, reader = d1.add(Writer("w")), d2.add(Reader("r"))
    servers = []
    try:
        for d in (d1, d2):
            d.configure_all()
            d.start_all()
            servers.append(d.serve("127.0.0.1:0", ns=ns.address))
        with connect(ns.address) as system:
            yield writer, reader, system
    finally:
        for server in servers:
            server.stop()
        ns.stop()
        for d in (d1, d2):
            d.stop_all()
            d.cleanup_all()


def figure2(pair: tuple[Writer, Reader, object], policy: ConnPolicy) -> tuple[list[int], int, dict]:
    writer, reader, system = pair
    system.connect_ports("w.out", "r.inp", policy, name="flow")  # type: ignore[attr-defined]
    link = wait_until(lambda: next((lk for lk in system.links() if lk.name == "flow" and  # type: ignore[attr-defined]
                                    lk.state == "connected"), None), timeout=15, message="never connected")
    assert link.transport == "ipc"
    got: list[int] = []
    slow = threading.Thread(target=_slow_reader, args=(reader.inp, got))
    slow.start()
    for value in range(1, N + 1):
        writer.out.write(value)
    read_when_written = len(got)
    slow.join(30)
    counts = wait_until(lambda: (lk := next(x for x in system.links() if x.name == "flow")) and  # type: ignore[attr-defined]
                        lk.samples - lk.dropped == len(got) and {"samples": lk.samples, "dropped": lk.dropped},
                        timeout=10, message="the link's counts never settled")
    return got, read_when_written, counts


def _slow_reader(port: InputPort[int], got: list[int]) -> None:
    deadline, quiet = time.monotonic() + 20, 0
    while time.monotonic() < deadline and quiet < 500:  # bounded: 20 s, or 0.5 s with nothing new
        flow, value = port.read()
        if flow is FlowStatus.NEW_DATA:
            got.append(value)
            quiet = 0
            if value == N:
                return
            time.sleep(0.004)  # the slow observer's work per sample
        else:
            quiet += 1
            time.sleep(0.001)


@pytest.mark.parametrize("wait", [WaitMode.WAIT_BEFORE, WaitMode.WAIT_AFTER])
def test_a_waiting_writer_loses_nothing_across_deployers(pair: tuple[Writer, Reader, object], wait: WaitMode) -> None:
    got, read_when_written, counts = figure2(pair, ConnPolicy.single_buffer(wait).with_(wait_timeout=10.0))
    assert got == list(range(1, N + 1)) and counts == {"samples": N, "dropped": 0}
    assert read_when_written >= N - 3  # held to the reader's pace by its reports


def test_a_no_wait_writer_is_never_held_and_its_reader_counts_the_rest(pair: tuple[Writer, Reader, object]) -> None:
    got, read_when_written, counts = figure2(pair, ConnPolicy.single_buffer())
    assert read_when_written < N // 2 and len(got) < N and got == sorted(got)
    assert counts["samples"] - counts["dropped"] == len(got)  # written = delivered + dropped


def test_a_transport_that_cannot_hold_a_writer_back_is_refused_at_connect(pair: tuple[Writer, Reader, object]) -> None:
    _, _, system = pair
    with pytest.raises(Exception, match="transport grpc carries no writer that waits .wait-before.; ipc, shm do"):
        system.connect_ports("w.out", "r.inp", ConnPolicy.single_buffer(WaitMode.WAIT_BEFORE).with_(  # type: ignore[attr-defined]
            transport="grpc"))
    with pytest.raises(ValueError, match="a subscription's writer never waits"):
        system.component("w").subscribe("out", lambda *_: None,  # type: ignore[attr-defined]
                                        policy=ConnPolicy.single_buffer(WaitMode.WAIT_BEFORE))
