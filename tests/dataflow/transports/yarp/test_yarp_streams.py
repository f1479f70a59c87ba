"""Ports as YARP ports through the ``yarp`` transport (``Deployer.stream``), judged by
YARP's own ``yarpserver`` and ``yarp``: what ``yarp read`` prints, what a task sees of
``yarp write``, and what is refused and counted (a bottle of another shape, a value out
of the port's bounds) — never passed on half-decoded."""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import wait_until
from support.yarp import YarpServer, yarpserver
from support.yarp_tasks import Arm

from dataflow import (ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, PeriodicActivity, TaskContext,
                      WaitMode)
from dataflow.introspection import LinkDescription
from dataflow.transports import TransportError, load

pytestmark = pytest.mark.integration


@pytest.fixture
def yarp(tmp_path: Path) -> Iterator[YarpServer]:
    with yarpserver(tmp_path / "yarp") as server:
        yield server


@pytest.fixture
def arm() -> Iterator[Arm]:
    dep = Deployer()
    task = dep.add(Arm("arm"))
    task.set_activity(PeriodicActivity(0.05))
    dep.configure_all()
    dep.start_all()
    DEPLOYERS[task] = dep
    try:
        yield task
    finally:
        del DEPLOYERS[task]
        for name in list(dep.streams()):
            dep.unstream(name)
        dep.stop_all()
        dep.cleanup_all()


DEPLOYERS: dict[Arm, Deployer] = {}


def stream(task: Arm, yarp: YarpServer, port: str, topic: str, policy: ConnPolicy | None = None,
           **options: str) -> LinkDescription:
    return DEPLOYERS[task].stream(f"arm.{port}", (policy or ConnPolicy.data()).with_(transport="yarp", topic=topic),
                                  {"server": yarp.address, **options})


def listed(task: Arm, name: str) -> LinkDescription:
    return next(link for link in DEPLOYERS[task].links() if link.name == name)


def test_yarp_read_prints_a_model_as_the_bottle_of_its_fields(yarp: YarpServer, arm: Arm) -> None:
    reader = yarp.spawn("read", "/r")
    try:
        reader.read_until("active", timeout=15)
        made = stream(arm, yarp, "armState", "/arm/state", connect="/r")
        wait_until(lambda: listed(arm, made.name).state == "connected", timeout=15,
                   message=f"never connected: {listed(arm, made.name)}")
        text = reader.read_until("arm (0.0 0.0)", timeout=15)
        seq = [int(m[1]) for m in re.finditer(r"arm \(0\.0 0\.0\) [0-9.]+ true (\d+)", text)]
        assert seq and seq == sorted(seq), text  # name (joints) stamp ok seq, in order
        assert yarp.registered("/arm/state")
    finally:
        reader.stop()
    assert listed(arm, made.name).dropped == 0


def test_yarp_write_reaches_the_task_and_what_does_not_fit_is_refused_and_counted(yarp: YarpServer,
                                                                                  arm: Arm) -> None:
    made = stream(arm, yarp, "cmd", "/arm/cmd", ConnPolicy.buffer(16))
    gain = stream(arm, yarp, "gain", "/arm/gain")
    wait_until(lambda: yarp.registered("/arm/cmd") and yarp.registered("/arm/gain"), timeout=15)
    lines = "0.5 -0.25\n1 2 x\n(1 2)\n3 4\n"
    assert yarp.tool("write", "/w", "/arm/cmd", stdin=lines).returncode == 0
    assert yarp.tool("write", "/w2", "/arm/gain", stdin="2.5\n11\nnan\n").returncode == 0
    wait_until(lambda: len(arm.commands) == 2 and arm.gains == [2.5], timeout=15,
               message=f"commands {arm.commands}, gains {arm.gains}")
    assert arm.commands == [[0.5, -0.25], [3.0, 4.0]]  # ints widen to floats
    link = wait_until(lambda: (found := listed(arm, made.name)).samples == 4 and found, timeout=10)
    assert (link.samples, link.dropped) == (4, 2)
    note = next(p for p in arm.describe().ports if p.name == "cmd").streams[0]
    assert note.refused == 2 and "a number is wanted" in note.refusal and note.unauthenticated
    gain_note = wait_until(lambda: (n := next(p for p in arm.describe().ports if p.name == "gain").streams[0])
                           .refused == 2 and n, timeout=10)
    assert listed(arm, gain.name).dropped == 2 and gain_note.refusal  # 11 over the bound, NaN


def test_yarp_connect_and_disconnect_work_either_way(yarp: YarpServer, arm: Arm) -> None:
    stream(arm, yarp, "armState", "/arm/state")
    stream(arm, yarp, "cmd", "/arm/cmd", ConnPolicy.buffer(16))
    wait_until(lambda: yarp.registered("/arm/state") and yarp.registered("/arm/cmd"), timeout=15)
    done = yarp.tool("connect", "/arm/state", "/arm/cmd")  # scart to scart, through YARP's own tool
    assert done.returncode == 0, done.stdout + done.stderr
    writer = yarp.spawn("write", "/w")
    try:
        writer.read_until("active", timeout=15)
        assert yarp.tool("connect", "/w", "/arm/cmd", "text").returncode == 0
        assert writer.proc.stdin is not None
        writer.proc.stdin.write(b"7 8\n")
        writer.proc.stdin.flush()
        wait_until(lambda: [7.0, 8.0] in arm.commands, timeout=15, message=f"{arm.commands[-3:]}")
        assert yarp.tool("disconnect", "/w", "/arm/cmd").returncode == 0
    finally:
        writer.stop()
    assert yarp.tool("disconnect", "/arm/state", "/arm/cmd").returncode == 0


def test_a_stream_that_cannot_be_made_says_why(arm: Arm) -> None:
    transport = load("yarp")
    with pytest.raises(TransportError, match="carrier='mcast': scart speaks YARP over tcp, fast_tcp, text, udp"):
        DEPLOYERS[arm].stream("arm.cmd", ConnPolicy.data().with_(transport="yarp", topic="/x"), {"carrier": "mcast"})
    assert DEPLOYERS[arm].streams() == {}
    problems = transport.check_stream(Arm.out, "no slash", {"colour": "red"})
    assert [p.message.split(":")[0] for p in problems] == ["yarp", "yarp"]
    assert "unknown option(s) colour" in problems[0].message and "port name 'no slash'" in problems[1].message


class Flow(TaskContext):
    """A writer's port and a reader's, streamed to each other over YARP (no activity: the
    test writes and reads them)."""

    out = OutputPort(int)
    inp = InputPort(int)


@pytest.mark.parametrize("wait", [WaitMode.WAIT_BEFORE, WaitMode.WAIT_AFTER])
def test_over_yarp_a_waiting_writer_and_a_single_buffer_lose_nothing(yarp: YarpServer, wait: WaitMode) -> None:
    """Figure 2 across YARP's TCP: the slow reader's full buffer holds its YARP port's
    acknowledgement back, the writer waits for it, and every sample arrives."""
    got, read_when_written = _figure2(yarp, ConnPolicy.single_buffer(wait).with_(wait_timeout=10.0))
    assert got == list(range(1, 31))
    assert read_when_written >= 27  # the writer was held to the reader's pace


def test_over_yarp_a_no_wait_writer_never_waits_and_the_reader_counts_its_losses(yarp: YarpServer) -> None:
    got, read_when_written = _figure2(yarp, ConnPolicy.single_buffer())
    assert read_when_written < 15 and got and len(got) < 30 and got == sorted(got)


def _figure2(yarp: YarpServer, policy: ConnPolicy, n: int = 30) -> tuple[list[int], int]:
    dep = Deployer()
    task = dep.add(Flow("flow"))
    dep.configure_all()
    dep.start_all()
    got: list[int] = []
    try:
        sink = dep.stream("flow.inp", policy.with_(transport="yarp", topic="/flow/in"), {"server": yarp.address})
        dep.stream("flow.out", policy.with_(transport="yarp", topic="/flow/out"),
                   {"server": yarp.address, "connect": "/flow/in"})
        wait_until(lambda: "/flow/in" in yarp.tool("ping", "/flow/out").stdout, timeout=15)
        reader = threading.Thread(target=_slow_reader, args=(task.inp, got, n))
        reader.start()
        for value in range(1, n + 1):
            task.out.write(value)
        read_when_written = len(got)
        reader.join(30)
        link = next(lk for lk in dep.links() if lk.name == sink.name)
        assert link.samples - len(got) == link.dropped or not got  # what it did not get is counted
        return got, read_when_written
    finally:
        for name in list(dep.streams()):
            dep.unstream(name)
        dep.stop_all()
        dep.cleanup_all()


def _slow_reader(port: InputPort[int], got: list[int], n: int) -> None:
    deadline = time.monotonic() + 20
    quiet = 0
    while time.monotonic() < deadline and quiet < 400:  # bounded: 20 s, or 0.4 s with nothing new
        flow, value = port.read()
        if flow is FlowStatus.NEW_DATA:
            got.append(value)
            quiet = 0
            if value == n:
                return
            time.sleep(0.004)  # the slow observer's work per sample
        else:
            quiet += 1
            time.sleep(0.001)
