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
from dataflow.remote import errors
from scart.bindings.dataflow import DataflowSettings

zenoh_transport = pytest.importorskip("dataflow.transports.zenoh")
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


@pytest.fixture
def session():
    """``open_session`` for a test: every session it opened is closed after the test, also
    when the test fails (a session left open keeps Zenoh's threads and sockets)."""
    opened = []

    def open_(*args, **kwargs):
        opened.append(open_session(*args, **kwargs))
        return opened[-1]

    yield open_
    for each in reversed(opened):
        each.close()


def _publish_until(port, value, recorder: Recorder) -> None:
    """Write ``value`` until it arrives (a subscription is live once Zenoh has matched it)."""
    wait_until(lambda: port.write(value) and value in recorder.values(), timeout=15,
               message=f"{value!r} never arrived over Zenoh")


def test_a_port_on_zenoh_between_peers_and_through_a_router(tmp_path, session) -> None:
    here = f"unixsock-stream/{tmp_path}/a.sock"
    a = session(listen=[here])
    b = session(connect=[here], listen=[f"unixsock-stream/{tmp_path}/b.sock"])
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
        sub.close()  # the publisher hears that nobody matches, then that someone does again
        again = Recorder()
        sub = ZenohSubscription(b, "counter", "out", again, ns="lab")
        _publish_until(task.out, -2, again)
    finally:
        sub.close()
        publisher.close()
    wait_until(lambda: discover(b, "lab") == {}, timeout=10, message="the liveliness tokens stayed")

    # a fleet: two clients that only reach each other through a router
    router_at = f"unixsock-stream/{tmp_path}/router.sock"
    session(listen=[router_at], mode="router")
    robot = session(connect=[router_at], mode="client")
    desk = session(connect=[router_at], mode="client")
    publisher = ZenohPublisher(deployer, robot)
    seen = Recorder()
    sub = ZenohSubscription(desk, "counter", "status", seen)
    try:
        _publish_until(task.status, {"x": 1.5}, seen)
        assert discover(desk) == {"counter": ["out", "status"]}
    finally:
        sub.close()
        publisher.close()


class Setpoint(TaskContext):
    target = InputPort(float, ge=0.0, doc="a set-point from the fleet")


def test_an_input_port_fed_from_zenoh_checks_what_comes(tmp_path, session) -> None:
    """An input port subscribed to another process's output key: good values arrive
    through the policy; NaN and out-of-bounds ones are refused as from any outside writer."""
    here = f"unixsock-stream/{tmp_path}/a.sock"
    a = session(listen=[here])
    b = session(connect=[here], listen=[f"unixsock-stream/{tmp_path}/b.sock"])
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


def test_a_routable_endpoint_needs_insecure() -> None:
    with pytest.raises(ValueError, match="not loopback"):
        open_session(listen=["tcp/0.0.0.0:0"])
    with pytest.raises(ValueError, match="not loopback"):
        open_session(connect=["tcp/10.1.2.3:7447"])
    with pytest.raises(ValueError, match="expected PROTOCOL/ADDRESS"):
        open_session(listen=["tcp/127.0.0.1"])
    with pytest.raises(ValueError, match="cannot be a Zenoh key chunk"):
        zenoh_transport.key_of("lab", "a/b", "out")


def _scart(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True,
                          env={**subprocess_env(), **(env or {})}, timeout=60)


OPERATOR, READER = "zenoh-operator-token-0123456789", "zenoh-reader-token-0123456789"


def _reached(zenoh_session) -> int:
    info = zenoh_session.info
    return len(list(info.peers_zid())) + len(list(info.routers_zid()))


def test_with_tokens_a_zenoh_session_admits_only_peers_presenting_an_operate_token(tmp_path, session) -> None:
    """A session listening with scart's auth file admits a peer presenting an ``operate``
    token (it reads the samples), and neither a peer without one nor one with a ``read``
    token (a Zenoh link both reads and writes): those reach no peer and get nothing. The
    command line says why nothing was reached."""
    from scart_wire.security import Security

    auth = tmp_path / "auth"
    auth.write_text(f"operate {OPERATOR}\nread {READER}\n")
    auth.chmod(0o600)
    here = f"unixsock-stream/{tmp_path}/a.sock"
    served = session(listen=[here], security=Security(auth_file=str(auth)))
    deployer = Deployer()
    task = deployer.add(FloatOut("guarded"))
    publisher = ZenohPublisher(deployer, served)
    operator = session(connect=[here], mode="client", security=Security(token=OPERATOR))
    got = Recorder()
    subs = [ZenohSubscription(operator, "guarded", "out", got)]
    # a peer without a token, or with a read one, is refused
    for security in (None, Security(token=READER)):
        with pytest.raises(Exception, match="Unable to connect"):
            open_session(connect=[here], mode="client", security=security)
    # and a guarded session dialing a listener that checks no token (one posing as a
    # router, say) is refused there: that listener gets none of its samples
    peer_at = f"unixsock-stream/{tmp_path}/outsider.sock"
    outsider = session(listen=[peer_at])
    heard = Recorder()
    subs.append(ZenohSubscription(outsider, "guarded", "out", heard))
    dialing = session(listen=[f"unixsock-stream/{tmp_path}/c.sock"], connect=[peer_at],
                      security=Security(auth_file=str(auth), token=OPERATOR))
    also = ZenohPublisher(deployer, dialing)
    try:
        _publish_until(task.out, 1.0, got)
        assert _reached(operator) == 1 and discover(operator) == {"guarded": ["out"]}
        for k in range(20):
            task.out.write(2.0 + k)
        wait_until(lambda: 21.0 in got.values(), timeout=10, message=f"got {got.values()}")
        assert _reached(outsider) == 0 and _reached(dialing) == 0 and heard.values() == []
        ls = _scart("ls", "--zenoh", "--zenoh-connect", here, "--timeout", "2", env={"SCART_TOKEN": ""})
        assert ls.returncode == 1 and "Unable to connect" in ls.stderr and "admits only a command given one" in ls.stderr
        ls = _scart("ls", "--zenoh", "--zenoh-connect", here, "--json", env={"SCART_TOKEN": OPERATOR})
        assert ls.returncode == 0 and json.loads(ls.stdout) == [{"name": "guarded", "ports": ["out"]}], ls.stderr
    finally:
        for sub in subs:
            sub.close()
        also.close()
        publisher.close()
    only_readers = tmp_path / "readers"
    only_readers.write_text(f"read {READER}\n")
    only_readers.chmod(0o600)
    with pytest.raises(ValueError, match="no operate or admin token"):
        open_session(listen=[f"unixsock-stream/{tmp_path}/b.sock"], security=Security(auth_file=str(only_readers)))


def test_deploy_ls_and_echo_over_zenoh_without_a_name_service(tmp_path, session) -> None:
    """A deployer prints where its Zenoh session listens; ls and echo reach it there with no
    name service. Killed, its liveliness tokens go with it: ls through a router lists nothing."""
    router_at = f"unixsock-stream/{tmp_path}/router.sock"
    session(listen=[router_at], mode="router")
    proc, line = start_scart(["deploy", "support.remote:Pinger", "--name", "zp", "--period", "0.02",
                              "--ns", "127.0.0.1:0", "--zenoh", "--zenoh-connect", router_at], ready="serving")
    try:
        endpoint = line.rpartition("listening on ")[2]  # a free loopback port, printed
        assert endpoint.startswith("tcp/127.0.0.1:") and "2 port(s) under scart/default/" in line
        alone = _scart("ls", "--zenoh", "--ns", "127.0.0.1:1")  # nowhere to look
        assert alone.returncode == 1 and "give --zenoh-connect ENDPOINT" in alone.stderr
        zenoh = ["--zenoh", "--zenoh-connect", endpoint, "--ns", "127.0.0.1:1"]  # no name service answers there
        listed = [{"name": "zp", "ports": ["output", "ticks"]}]  # each port's token comes on its own: wait for both

        def lists(*args: str) -> bool:
            return json.loads(_scart("ls", "--json", *args).stdout or "[]") == listed

        wait_until(lambda: lists(*zenoh), timeout=15, message="ls over Zenoh never listed zp's two ports")
        echoed = _scart("echo", "zp.ticks", "-n", "2", "--json", *zenoh)
        ticks = [json.loads(x) for x in echoed.stdout.split()]
        assert echoed.returncode == 0 and len(ticks) == 2 and ticks[1] > ticks[0] > 0
        via_router = ["--zenoh", "--zenoh-connect", router_at]
        wait_until(lambda: lists(*via_router), timeout=15, message="ls through the router never listed zp")
        # the Python API: lookups from Zenoh, then calls and a subscription to the deployer
        client = session(connect=[router_at], mode="client")
        with zenoh_transport.connect_zenoh(client, timeout=5.0) as system:  # closes its subscriptions too
            seen = Recorder()
            wait_until(lambda: system.component_names() == ["zp"], timeout=15, message="zp not announced")
            assert system.component("zp").call("add", 1.0, 2.0) == 3.0
            sub = system.component("zp").subscribe("ticks", seen)
            wait_until(lambda: len(seen.values()) >= 2, timeout=10, message="no ticks through a Zenoh lookup")
            assert sub.transport == "ipc"  # the samples go the fastest way; only the lookup was Zenoh's
            sub.close()
            proc.send_signal(signal.SIGKILL)  # its tokens go with the process
            proc.wait(timeout=10)
            wait_until(lambda: json.loads(_scart("ls", "--json", *via_router).stdout or "null") == [], timeout=20,
                       message="a killed deployer is still announced")
            with pytest.raises(errors.RemoteNotFoundError, match="no component named 'zp' is served on Zenoh"):
                system.component("zp")
    finally:
        stop_process(proc, signal.SIGKILL)


def test_zenoh_lookups_take_only_loopback_deployers_unless_insecure(tmp_path, session) -> None:
    """Anyone on Zenoh may announce a component: a routable address (where the system would
    send its token) is ignored unless insecure, a malformed announcement always is, and a
    component announced by two deployers is not used (a spoofed or stale one)."""
    here = f"unixsock-stream/{tmp_path}/a.sock"
    a = session(listen=[here])
    b = session(connect=[here], listen=[f"unixsock-stream/{tmp_path}/b.sock"])
    served = zenoh_transport.served_key
    tokens = [a.liveliness().declare_token(key) for key in (
        served("lab", "near", "127.0.0.1:50051", "b1"), served("lab", "far", "10.1.2.3:50051", "b2"),
        "scart-served/lab/odd/no-port/b3", "scart-served/lab/bad/127.0.0.1%3A99999/b4",
        served("lab", "twin", "127.0.0.1:6001", "t1"), served("lab", "twin", "127.0.0.1:6002", "t2"))]
    try:
        insecure = zenoh_transport.ZenohNames(b, "lab", timeout=2.0, insecure=True)
        wait_until(lambda: [e.component for e in insecure.entries()] == ["far", "near"], timeout=10,
                   message="the announcements did not arrive")  # the malformed ones never count
        assert insecure.resolve("far").address == "10.1.2.3:50051"
        names = zenoh_transport.ZenohNames(b, "lab", timeout=2.0)
        # Each lookup is a fresh liveliness query, which may briefly see one twin of two.
        wait_until(lambda: [(e.component, e.address, e.boot_id) for e in names.entries()]
                   == [("near", "127.0.0.1:50051", "b1")], timeout=10, message="a secure lookup kept far or twin")
        with pytest.raises(errors.RemoteNotFoundError, match="known: near"):
            names.resolve("far")
        with pytest.raises(errors.RemoteNotFoundError):  # announced twice: never a guess
            names.resolve("twin")
    finally:
        for token in tokens:
            token.undeclare()


PROBE = """
from typing import Protocol

import scart
from dataflow import FlowStatus, InputPort, TaskContext, operation


class PingerPorts(Protocol):
    def input(self, value: float) -> None: ...
    def output(self) -> float: ...


class Logged(Protocol):
    def logged(self) -> list[int]: ...


class Probe(Protocol):
    def echo(self, value: float) -> float: ...
    def ticks_seen(self) -> list[int]: ...


class Logger(TaskContext):
    ticks = InputPort(int, event=True)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.seen: list[int] = []

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, value = self.ticks.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.seen.append(value)

    @operation
    def logged(self) -> list[int]:
        return list(self.seen)


@scart.component(services=[Probe])
class ProbeImpl:
    pinger: PingerPorts = scart.reference()
    logger: Logged = scart.reference()

    def echo(self, value: float) -> float:
        self.pinger.input(value)
        return self.pinger.output()

    def ticks_seen(self) -> list[int]:
        return self.logger.logged()
"""


def test_binding_dataflow_finds_its_task_on_zenoh_without_a_name_service(tmp_path) -> None:
    """``<scart:binding.dataflow zenoh="ENDPOINT">``: the task is looked up through Zenoh
    liveliness (the composite's runtime has no name service to ask), then written and read."""
    from support.sca import composite, write

    import scart

    proc, line = start_scart(["deploy", "support.remote:Pinger", "--name", "zp", "--period", "0.01",
                              "--ns", "127.0.0.1:0", "--zenoh"], ready="serving")
    try:
        endpoint = line.rpartition("listening on ")[2]
        path = write(tmp_path, {"z.composite": composite(f"""
            <component name="logger"><scart:implementation.task class="zprobe:Logger"/></component>
            <scart:connect from="zp.ticks" to="logger.ticks" policy="buffer:64" zenoh="{endpoint}"/>
            <component name="probe"><scart:implementation.python class="zprobe:ProbeImpl"/>
              <reference name="pinger"><scart:binding.dataflow component="zp" zenoh="{endpoint}"/></reference>
              <reference name="logger" target="logger"/>
            </component>"""), "zprobe.py": PROBE}, with_components=False)
        settings = DataflowSettings(ns="127.0.0.1:1").apply()  # nothing answers there: only Zenoh can find zp
        with scart.Runtime.from_file(path, settings=settings) as rt:
            probe = rt.service("probe/Probe")
            wait_until(lambda: _echo(probe, 2.5) == 2.5, timeout=20, message="zp never answered through Zenoh")
            # <scart:connect zenoh=...>: zp.ticks read from its Zenoh key into the local task
            wait_until(lambda: len(probe.ticks_seen()) >= 3, timeout=20, message="no ticks came over Zenoh")
            seen = probe.ticks_seen()
            assert seen == sorted(seen) and seen[0] > 0  # the deployer's counter, in order
            # undone as any stream is (scart unstream): it stops feeding, and the stop after it is clean
            from scart.bindings.dataflow._host import host_of

            deployer = host_of(rt).deployer
            (name,) = [n for n in deployer.streams() if n.startswith("zenoh:")]
            assert deployer.unstream(name) and name not in deployer.streams()
    finally:
        stop_process(proc, signal.SIGKILL)


def _echo(probe, value: float) -> float | None:
    try:
        return probe.echo(value)
    except Exception:  # noqa: BLE001 - not connected yet: the binding says so until it is
        return None


@pytest.mark.parametrize(("attrs", "words"), [
    ('from="zp.ticks" zenoh="tcp/10.0.0.1:7447"', "Zenoh endpoint 'tcp/10.0.0.1:7447' is not loopback"),
    ('from="zp.ticks" zenoh="unixsock-stream/z.sock" ns="127.0.0.1:1"', "give either ns"),
    ('from="src.out" zenoh="unixsock-stream/z.sock"', "'src' is in this composite; with zenoh the source is a task"),
])
def test_a_zenoh_connect_is_checked_at_load(tmp_path, attrs: str, words: str) -> None:
    import re

    import scart
    from support.sca import composite, write

    path = write(tmp_path, {"c.composite": composite(f"""
        <component name="logger"><scart:implementation.task class="zprobe:Logger"/></component>
        <component name="src"><scart:implementation.task class="support.remote:Pinger"/></component>
        <scart:connect {attrs} to="logger.ticks"/>"""), "zprobe.py": PROBE}, with_components=False)
    with pytest.raises(scart.ScdlError, match=re.escape(words)):
        scart.Runtime.from_file(path)


def test_a_routable_zenoh_endpoint_loads_with_zenoh_insecure(tmp_path) -> None:
    """A fleet's router on another machine: allowed when the composite says so."""
    import scart
    from support.sca import composite, write

    path = write(tmp_path, {"c.composite": composite("""
        <component name="logger"><scart:implementation.task class="zprobe:Logger"/></component>
        <scart:connect from="zp.ticks" to="logger.ticks" zenoh="tcp/10.0.0.1:7447" zenoh-insecure="true"/>
        <component name="probe"><scart:implementation.python class="zprobe:ProbeImpl"/>
          <reference name="pinger"><scart:binding.dataflow component="zp" zenoh="tcp/10.0.0.1:7447"
                                                           zenoh-insecure="true"/></reference>
          <reference name="logger" target="logger"/>
        </component>"""), "zprobe.py": PROBE}, with_components=False)
    scart.Runtime.from_file(path)  # loads: nothing is opened before start
