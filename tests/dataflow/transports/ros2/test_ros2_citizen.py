"""scart's ROS 2 node as a citizen, judged as ``ros2`` would judge it: a Cyclone DDS client
with ``rcl_interfaces`` types calls the logger and parameter services of a ``scart deploy``
subprocess on this run's domain, reads its ``/rosout``, and drives its time on ``/clock``."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from support import free_port, wait_until  # noqa: E402
from support.remote import start_scart, stop_process, subprocess_env  # noqa: E402

from scart_ros2 import Participant, QoS  # noqa: E402

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]

LOGGER = "dataflow.transports.ros2"  # the logger of a refused parameter's warning


@pytest.fixture
def on_domain(domain: int, monkeypatch: pytest.MonkeyPatch) -> int:
    """Subprocesses started by the test join this run's domain (ROS_DOMAIN_ID); the ROS 1
    node that ``--ros-name`` makes too finds no master (a closed port, not a roscore of the
    host's)."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("ROS_MASTER_URI", f"http://127.0.0.1:{free_port()}/")
    return domain


def scart(*args: str, domain: int) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True, timeout=60,
                          env={**subprocess_env(), "ROS_DOMAIN_ID": str(domain)})


class Node:
    """A deployed scart process as its ROS 2 node: its services called from ``ros``."""

    def __init__(self, ros: Participant, name: str, ns: str, domain: int, topic: str) -> None:
        self.ros, self.name, self.ns, self.domain, self.topic = ros, name, ns, domain, topic
        self._clients: dict[str, Any] = {}

    def client(self, service: str, kind: str) -> Any:
        if service not in self._clients:
            self._clients[service] = self.ros.client(f"/{self.name}/{service}", f"rcl_interfaces/srv/{kind}")
        return self._clients[service]

    def call(self, service: str, kind: str, request: dict) -> Any:
        """The answer of the node's ``service`` (the first calls wait for DDS discovery)."""
        client = self.client(service, kind)
        return wait_until(lambda: _answer(client, request), timeout=20, message=f"{service} never answered")

    def set_param(self, name: str, value: dict) -> Any:
        return self.call("set_parameters", "SetParameters", {"parameters": [{"name": name, "value": value}]}).results[0]

    def prop(self, task: str, name: str) -> str:
        return scart("prop", "get", task, name, "--ns", self.ns, domain=self.domain).stdout.strip()


@pytest.fixture
def deployed(on_domain: int, topic: str) -> Iterator[Any]:
    """``deployed(name, cls, *extra)``: a ``scart deploy`` of ``cls`` as the ROS 2 node
    ``/name``, an output streamed to the test's topic (so its node exists); a :class:`Node`."""
    procs: list[subprocess.Popen[str]] = []
    ros = Participant(on_domain)

    def start(name: str, cls: str, stream: list[str], *extra: str) -> Node:
        ns = f"127.0.0.1:{free_port()}"
        proc, _ = start_scart(["deploy", cls, "--period", "0.05", "--listen", ns, "--ros-name", name, *extra])
        procs.append(proc)
        made = scart("stream", stream[0], f"ros2:{topic}", *stream[1:], "--ns", ns, domain=on_domain)
        assert made.returncode == 0, made.stderr
        return Node(ros, name, ns, on_domain, topic)

    try:
        yield start
    finally:
        ros.close()
        for proc in procs:
            assert stop_process(proc) == 0


def test_the_logger_services_change_what_a_logger_publishes_on_rosout(deployed) -> None:
    node = deployed("loud", "support.remote:Pinger", ["pinger.output"])
    logged: list = []
    node.ros.subscribe("/rosout", "rcl_interfaces/msg/Log", logged.append, QoS.buffer(100, latching=True))

    def levels(*names: str) -> list[int]:
        got = node.call("get_logger_levels", "GetLoggerLevels", {"names": list(names)}).levels
        assert [g.name for g in got] == list(names)
        return [g.level for g in got]

    def set_levels(*asked: tuple[str, int]) -> list[tuple[bool, str]]:
        request = {"levels": [{"name": name, "level": level} for name, level in asked]}
        return [(r.successful, r.reason) for r in node.call("set_logger_levels", "SetLoggerLevels", request).results]

    assert levels(LOGGER, "loud", "nobody.here") == [0, 20, 0]  # unset; the node's own: the root at INFO
    (ok, _), (unknown, why_unknown), (bad, why_bad) = set_levels((LOGGER, 40), ("nobody.here", 10), (LOGGER, 35))
    assert ok and not unknown and "no logger 'nobody.here'" in why_unknown
    assert not bad and "invalid logger level 35" in why_bad
    assert levels(LOGGER) == [40]
    assert not node.set_param("pinger.gain", {"type": 3, "double_value": float("inf")}).successful  # a warning
    assert set_levels((LOGGER, 30)) == [(True, "")]
    assert not node.set_param("pinger.label", {"type": 2, "integer_value": 7}).successful  # published now
    wait_until(lambda: any("pinger.label" in m.msg for m in logged), timeout=15, message=f"{logged}")
    assert not any("pinger.gain" in m.msg for m in logged)  # /rosout is reliable and ordered: it came first
    assert node.prop("pinger", "gain") == "1.0"


def test_use_sim_time_given_at_launch_puts_the_tasks_on_clock(deployed) -> None:
    node = deployed("clocked", "support.ros1_tasks:Gauge",  # --ros-name: a ROS 1 node too, following its /clock
                    ["gauge.heat", "--type", "sensor_msgs/msg/Temperature"], "_use_sim_time:=true")
    value = node.call("get_parameters", "GetParameters", {"names": ["use_sim_time"]}).values[0]
    assert (value.type, value.bool_value) == (1, True)  # read at start: no set_parameters asked
    stamps: list[int] = []
    node.ros.subscribe(node.topic, "sensor_msgs/msg/Temperature", lambda m: stamps.append(m.header.stamp.sec),
                       QoS.buffer(100))
    clock = node.ros.publisher("/clock", "rosgraph_msgs/msg/Clock", QoS.data(best_effort=True))
    wait_until(lambda: clock.matched(), timeout=20, message="the node never subscribed to /clock")
    before = int(scart("call", "gauge.cycle_count", "--ns", node.ns, domain=node.domain).stdout)
    for i in range(301):  # 3 s of the simulation's time in about 1.5 s: periods of 0.05 s pass in it
        clock.publish({"clock": {"sec": 5000 + i // 100, "nanosec": (i % 100) * 10_000_000}})
        time.sleep(0.005)
    ran = int(scart("call", "gauge.cycle_count", "--ns", node.ns, domain=node.domain).stdout) - before
    assert 45 <= ran <= 63, f"{ran} cycles of 0.05 s in 3 simulated seconds (the wall clock would give ~30)"
    wait_until(lambda: stamps and stamps[-1] >= 5002, timeout=10, message=f"stamps {stamps[-5:]}")
    assert all(5000 <= s <= 5003 for s in stamps[-20:]), stamps[-20:]  # stamped in the simulation's time


def test_a_read_only_node_serves_its_parameters_to_read_and_refuses_every_set(deployed) -> None:
    node = deployed("watched", "support.remote:Pinger", ["pinger.output"], "--ros-read-only")
    listed = node.call("list_parameters", "ListParameters", {"prefixes": [], "depth": 0}).result.names
    assert {"pinger.gain", "pinger.label", "use_sim_time"} <= set(listed), listed
    value = node.call("get_parameters", "GetParameters", {"names": ["pinger.gain"]}).values[0]
    assert (value.type, value.double_value) == (3, 1.0)
    described = node.call("describe_parameters", "DescribeParameters", {"names": ["pinger.gain"]}).descriptors[0]
    assert described.description == "multiplier"
    refused = node.set_param("pinger.gain", {"type": 3, "double_value": 2.0})  # a valid value, refused all the same
    assert not refused.successful and "read-only" in refused.reason
    assert not node.set_param("use_sim_time", {"type": 1, "bool_value": True}).successful  # no /clock from ROS
    assert node.prop("pinger", "gain") == "1.0"
    assert not node.client("set_logger_levels", "SetLoggerLevels").service_ready()  # not offered (as on ROS 1)


def test_use_sim_time_at_launch_is_refused_when_read_only(on_domain: int) -> None:
    done = scart("deploy", "support.remote:Pinger", "_use_sim_time:=true", "--ros-read-only",
                 "--listen", f"127.0.0.1:{free_port()}", domain=on_domain)
    assert done.returncode != 0 and "use_sim_time is refused" in done.stderr, done.stderr


def _answer(client, request: dict):
    try:
        return client.call(request, timeout=1.0)
    except TimeoutError:
        return None
