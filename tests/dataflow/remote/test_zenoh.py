"""Data-flow ports on Zenoh, with real Zenoh sessions on Unix sockets (no ports, no
multicast): an output port published and subscribed to, through peers and through a
router, components found by their liveliness tokens with no name service, and the
``--zenoh`` command line against a ``scart deploy`` process, killed at the end."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading

import pytest
from support import wait_until
from support.remote import start_scart, stop_process, subprocess_env

from dataflow import ConnPolicy, Deployer, InputPort, OutputPort, TaskContext

zenoh_transport = pytest.importorskip("dataflow.remote.zenoh_transport")
pytest.importorskip("zenoh")
open_session, discover = zenoh_transport.open_session, zenoh_transport.discover
ZenohPublisher, ZenohSubscription = zenoh_transport.ZenohPublisher, zenoh_transport.ZenohSubscription


class FloatOut(TaskContext):
    out = OutputPort(float)


class Counter(TaskContext):
    out = OutputPort(int, doc="a counter")
    status = OutputPort(dict[str, float], doc="a structure")


class Recorder:
    def __init__(self) -> None:
        self.events: list = []
        self.lock = threading.Lock()

    def __call__(self, event) -> None:
        with self.lock:
            self.events.append(event)

    def values(self) -> list:
        with self.lock:
            return [e.value for e in self.events]


def _publish_until(port, value, recorder: Recorder) -> None:
    """Write ``value`` until it arrives (a subscription is live once Zenoh has matched it)."""
    wait_until(lambda: port.write(value) and value in recorder.values(), timeout=15,
               message=f"{value!r} never arrived over Zenoh")


def test_a_port_on_zenoh_between_peers_and_through_a_router(tmp_path) -> None:
    here = f"unixsock-stream/{tmp_path}/a.sock"
    a = open_session(listen=[here])
    b = open_session(connect=[here], listen=[f"unixsock-stream/{tmp_path}/b.sock"])
    deployer = Deployer()
    task = deployer.add(Counter("counter"))
    publisher = ZenohPublisher(deployer, a, ns="lab")
    got = Recorder()
    sub = ZenohSubscription(b, "counter", "out", got, ns="lab")
    try:
        assert publisher.keys == ["scart/lab/counter/out", "scart/lab/counter/status"]
        _publish_until(task.out, -1, got)
        for k in range(20):
            task.out.write(k)
        wait_until(lambda: got.values()[-20:] == list(range(20)), timeout=10, message=f"got {got.values()}")
        sequences = [e.sequence for e in got.events]
        assert sequences == sorted(sequences) and sub.dropped == 0  # the port's write numbers, none lost
        assert discover(b, "lab") == {"counter": ["out", "status"]}  # no name service anywhere
        assert discover(b, "other") == {}
    finally:
        sub.close()
        publisher.close()
    wait_until(lambda: discover(b, "lab") == {}, timeout=10, message="the liveliness tokens stayed")
    b.close()
    a.close()

    # a fleet: two clients that only reach each other through a router
    router_at = f"unixsock-stream/{tmp_path}/router.sock"
    router = open_session(listen=[router_at], mode="router")
    robot = open_session(connect=[router_at], mode="client")
    desk = open_session(connect=[router_at], mode="client")
    publisher = ZenohPublisher(deployer, robot)
    seen = Recorder()
    sub = ZenohSubscription(desk, "counter", "status", seen)
    try:
        _publish_until(task.status, {"x": 1.5}, seen)
        assert discover(desk) == {"counter": ["out", "status"]}
    finally:
        sub.close()
        publisher.close()
        for session in (desk, robot, router):
            session.close()


class Setpoint(TaskContext):
    target = InputPort(float, ge=0.0, doc="a set-point from the fleet")


def test_an_input_port_fed_from_zenoh_checks_what_comes(tmp_path) -> None:
    """An input port subscribed to another process's output key: good values arrive
    through the policy; NaN and out-of-bounds ones are refused as from any outside writer."""
    here = f"unixsock-stream/{tmp_path}/a.sock"
    a = open_session(listen=[here])
    b = open_session(connect=[here], listen=[f"unixsock-stream/{tmp_path}/b.sock"])
    source = Deployer()
    task = source.add(FloatOut("planner"))
    sink = Setpoint("arm")
    publisher = ZenohPublisher(source, a)
    feed = zenoh_transport.ZenohInput(b, "planner", "out", sink.target, ConnPolicy.buffer(100))
    try:
        wait_until(lambda: task.out.write(0.5) and sink.target.read()[1] == 0.5, timeout=15,
                   message="nothing came in over Zenoh")
        for value in (float("nan"), -1.0, 2.0):
            task.out.write(value)
        wait_until(lambda: feed.refused == 2, timeout=10, message=f"refused {feed.refused}")
        values = []
        wait_until(lambda: values.extend(v for s, v in [sink.target.read()] if s.name == "NEW_DATA")
                   or 2.0 in values, timeout=10)
        assert all(v >= 0 for v in values)  # neither NaN nor -1 reached the task
    finally:
        feed.close()
        publisher.close()
        b.close()
        a.close()


def test_a_routable_endpoint_needs_insecure() -> None:
    with pytest.raises(ValueError, match="not loopback"):
        open_session(listen=["tcp/0.0.0.0:0"])
    with pytest.raises(ValueError, match="not loopback"):
        open_session(connect=["tcp/10.1.2.3:7447"])
    with pytest.raises(ValueError, match="expected PROTOCOL/ADDRESS"):
        open_session(listen=["tcp/127.0.0.1"])
    with pytest.raises(ValueError, match="cannot be a Zenoh key chunk"):
        zenoh_transport.key_of("lab", "a/b", "out")


def _scart(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True,
                          env=subprocess_env(), timeout=60)


def test_deploy_ls_and_echo_over_zenoh_without_a_name_service(tmp_path) -> None:
    """A deployer prints where its Zenoh session listens; ls and echo reach it there with no
    name service. Killed, its liveliness tokens go with it: ls through a router lists nothing."""
    router_at = f"unixsock-stream/{tmp_path}/router.sock"
    router = open_session(listen=[router_at], mode="router")
    proc, line = start_scart(["deploy", "support.remote:Pinger", "--name", "zp", "--period", "0.02",
                              "--ns", "127.0.0.1:0", "--zenoh", "--zenoh-connect", router_at], ready="serving")
    try:
        endpoint = line.rpartition("listening on ")[2]  # a free loopback port, printed
        assert endpoint.startswith("tcp/127.0.0.1:") and "2 port(s) under scart/default/" in line
        alone = _scart("ls", "--zenoh", "--ns", "127.0.0.1:1")  # nowhere to look
        assert alone.returncode == 1 and "give --zenoh-connect ENDPOINT" in alone.stderr
        zenoh = ["--zenoh", "--zenoh-connect", endpoint, "--ns", "127.0.0.1:1"]  # no name service answers there
        listed = wait_until(lambda: json.loads(_scart("ls", "--json", *zenoh).stdout or "[]"), timeout=15)
        assert listed == [{"name": "zp", "ports": ["output", "ticks"]}]
        echoed = _scart("echo", "zp.ticks", "-n", "2", "--json", *zenoh)
        ticks = [json.loads(x) for x in echoed.stdout.split()]
        assert echoed.returncode == 0 and len(ticks) == 2 and ticks[1] > ticks[0] > 0
        via_router = ["--zenoh", "--zenoh-connect", router_at]
        assert json.loads(_scart("ls", "--json", *via_router).stdout) == listed
        proc.send_signal(signal.SIGKILL)  # its tokens go with the process
        proc.wait(timeout=10)
        wait_until(lambda: json.loads(_scart("ls", "--json", *via_router).stdout or "null") == [], timeout=20,
                   message="a killed deployer is still announced")
    finally:
        stop_process(proc, signal.SIGKILL)
        router.close()
