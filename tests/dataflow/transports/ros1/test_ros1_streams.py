"""Ports as ROS 1 topics through the ``ros1`` transport (``Deployer.stream``), judged by
ROS's own tools and rospy against a real ``rosmaster --core``: what they print, what the
task sees, and what is refused and counted (another md5sum, NaN, out of range, a value
that does not convert, a master that is down)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from support import wait_until
from support.ros1 import RosMaster, needs_ros, require_rospy, running
from support.ros1_tasks import Gauge

from dataflow import ConnPolicy, Deployer, PeriodicActivity
from dataflow.introspection import LinkDescription, PortStreamDescription
from dataflow.transports import TransportError, load
from dataflow.transports.ros1.calls import ServiceProxy, serve_operation

pytestmark = [pytest.mark.integration, needs_ros]

NODE = "scart_test"


@pytest.fixture
def deployer() -> Iterator[Deployer]:
    dep = Deployer()
    try:
        yield dep
    finally:
        for name in list(dep.streams()):
            dep.unstream(name)
        dep.stop_all()
        dep.cleanup_all()


def stream(dep: Deployer, ros: RosMaster, port: str, topic: str, policy: ConnPolicy | None = None,
           **options: str) -> LinkDescription:
    return dep.stream(port, (policy or ConnPolicy.data()).with_(transport="ros1", topic=topic),
                      {"master": ros.uri, "node": NODE, **options})


def listed(dep: Deployer, name: str) -> LinkDescription:
    return next(link for link in dep.links() if link.name == name)


def connected(dep: Deployer, name: str) -> LinkDescription:
    return wait_until(lambda: (link := listed(dep, name)).state == "connected" and link, timeout=20,
                      message=f"{name} never connected: {listed(dep, name)}")


def note(task: Gauge, port: str) -> PortStreamDescription:
    return next(p for p in task.describe().ports if p.name == port).streams[0]


def running_gauge(dep: Deployer, rate: float = 50.0) -> Gauge:
    gauge = dep.add(Gauge("gauge"))
    gauge.set_activity(PeriodicActivity(1.0 / rate))
    dep.configure_all()
    dep.start_all()
    return gauge


def test_rostopic_echo_prints_a_port_published_by_field_names(ros: RosMaster, deployer: Deployer) -> None:
    running_gauge(deployer)
    made = stream(deployer, ros, "gauge.point", "/gauge/point", type="geometry_msgs/Point")
    connected(deployer, made.name)
    done = ros.tool("rostopic", "echo", "-n", "1", "/gauge/point", timeout=60)
    assert done.returncode == 0, done.stderr
    x = float(re.search(r"x: ([0-9.]+)", done.stdout).group(1))
    assert x > 0 and "y: 1.0" in done.stdout and "z: -2.0" in done.stdout, done.stdout


def test_rostopic_pub_reaches_the_input_port(ros: RosMaster, deployer: Deployer) -> None:
    gauge = deployer.add(Gauge("gauge"))
    made = stream(deployer, ros, "gauge.level", "/gauge/level")
    assert made.source == "ros1:/gauge/level" and made.sink == "gauge.level"
    connected(deployer, made.name)
    done = ros.tool("rostopic", "pub", "-1", "/gauge/level", "std_msgs/Float64", "0.25", timeout=60)
    assert done.returncode == 0, done.stderr
    wait_until(lambda: gauge.drain() or gauge.levels == [0.25], timeout=10, message=f"{gauge.levels}")
    assert listed(deployer, made.name).samples == 1


def test_rostopic_hz_sees_the_tasks_rate(ros: RosMaster, deployer: Deployer) -> None:
    running_gauge(deployer, rate=50.0)
    connected(deployer, stream(deployer, ros, "gauge.count", "/gauge/count").name)
    hz = ros.spawn("rostopic", "hz", "-w", "50", "/gauge/count")
    with running(hz):
        hz.read_until("average rate", timeout=60, count=3)
    rates = [float(r) for r in re.findall(r"average rate: ([0-9.]+)", hz.text())]
    assert rates and 40 <= rates[-1] <= 60, hz.text()


def test_rosnode_info_lists_the_node_with_its_topics(ros: RosMaster, deployer: Deployer) -> None:
    running_gauge(deployer)
    for made in (stream(deployer, ros, "gauge.count", "/gauge/count"),
                 stream(deployer, ros, "gauge.level", "/gauge/level")):
        connected(deployer, made.name)
    info = ros.tool("rosnode", "info", f"/{NODE}")
    assert info.returncode == 0, info.stderr
    published, subscribed = info.stdout.split("Subscriptions:")
    assert f"Node [/{NODE}]" in published and " * /gauge/count [std_msgs/Int64]" in published
    assert " * /gauge/level [" in subscribed.split("Services:")[0]


def test_rosbag_records_a_stream(ros: RosMaster, deployer: Deployer, tmp_path: Path) -> None:
    running_gauge(deployer, rate=50.0)
    connected(deployer, stream(deployer, ros, "gauge.count", "/gauge/count").name)
    bag = tmp_path / "scart.bag"
    record = ros.tool("rosbag", "record", "-O", str(bag), "-l", "20", "/gauge/count", timeout=60)
    assert record.returncode == 0, record.stderr
    info = ros.tool("rosbag", "info", str(bag))
    assert info.returncode == 0, info.stderr
    line = next(x for x in info.stdout.splitlines() if "/gauge/count" in x)
    assert re.search(r"\b20 msgs\s*:\s*std_msgs/Int64", line), info.stdout


def test_a_rospy_node_publishes_to_scart_and_subscribes_from_it(ros: RosMaster, deployer: Deployer) -> None:
    require_rospy()
    gauge = running_gauge(deployer, rate=100.0)
    # every number is asked for: a buffer, not the latest value (two may land in one cycle)
    connected(deployer, stream(deployer, ros, "gauge.number", "/rospy/numbers", ConnPolicy.buffer(16)).name)
    connected(deployer, stream(deployer, ros, "gauge.count", "/gauge/count").name)
    sub = ros.rospy("sub", "/gauge/count", "3")
    pub = ros.rospy("pub", "/rospy/numbers", "5", "50")
    with running(sub, pub):
        got = sub.read_until("got", timeout=60, count=3)
        pub.read_until("done", timeout=60)
    counts = [int(n) for n in re.findall(r"got (\d+)", got)]
    assert len(counts) >= 3 and counts == sorted(counts) and counts[0] >= 1, got
    wait_until(lambda: gauge.numbers_seen() == [0, 1, 2, 3, 4], timeout=10, message=f"{gauge.numbers_seen()}")


def test_another_md5sum_is_refused_both_ways_with_both_types_and_sums(ros: RosMaster, deployer: Deployer) -> None:
    require_rospy()
    deployer.add(Gauge("gauge"))
    gauge = deployer.task("gauge")
    into = stream(deployer, ros, "gauge.level", "/mixed/in")  # std_msgs/Float64 here ...
    out = stream(deployer, ros, "gauge.count", "/mixed/out", type="std_msgs/Int32")
    for made in (into, out):
        connected(deployer, made.name)
    pub = ros.rospy("pub", "/mixed/in", "3", "10")  # ... std_msgs/Int64 there
    sub = ros.rospy("sub", "/mixed/out", "1")  # std_msgs/Int64 there, std_msgs/Int32 here
    with running(pub, sub):
        pub.read_until("ready", timeout=60)
        sub.read_until("ready", timeout=60)
        refused_in = wait_until(lambda: note(gauge, "level").refusal, timeout=30)
        refused_out = wait_until(lambda: note(gauge, "count").refusal, timeout=30)
    ours_in, theirs = load("ros1").types.msg("std_msgs/Float64"), load("ros1").types.msg("std_msgs/Int64")
    # rospy's publisher refuses naming both types (not its sum); we add ours
    assert "std_msgs/Int64" in refused_in and f"std_msgs/Float64/{ours_in.md5sum}" in refused_in, refused_in
    ours_out = load("ros1").types.msg("std_msgs/Int32")  # our publisher refuses as roscpp: both types, both sums
    assert f"std_msgs/Int32/{ours_out.md5sum}" in refused_out and f"std_msgs/Int64/{theirs.md5sum}" in refused_out
    assert gauge.seen() == []


def test_a_master_down_is_waited_for_and_said(tmp_path: Path, deployer: Deployer) -> None:
    master = RosMaster(tmp_path)  # not started yet
    try:
        running_gauge(deployer)
        made = stream(deployer, master, "gauge.count", "/gauge/count")
        waiting = listed(deployer, made.name)
        assert waiting.state == "waiting" and f"waiting for the ROS master {master.uri}" in waiting.detail
        assert note(deployer.task("gauge"), "count").state == "waiting"
        master.start()
        connected(deployer, made.name)
        done = master.tool("rostopic", "echo", "-n", "1", "/gauge/count", timeout=60)
        assert done.returncode == 0 and "data: " in done.stdout, done.stderr
    finally:
        master.stop()


def test_nan_and_out_of_range_from_ros_are_refused_and_counted(ros: RosMaster, deployer: Deployer) -> None:
    gauge = deployer.add(Gauge("gauge"))
    made = stream(deployer, ros, "gauge.level", "/gauge/level", ConnPolicy.buffer(10))
    connected(deployer, made.name)
    for value in ("data: .nan", "data: 2.0", "data: -0.5", "data: 0.5"):
        done = ros.tool("rostopic", "pub", "-1", "/gauge/level", "std_msgs/Float64", value, timeout=60)
        assert done.returncode == 0, done.stderr
    wait_until(lambda: listed(deployer, made.name).samples == 4, timeout=10, message=f"{listed(deployer, made.name)}")
    gauge.drain()
    assert gauge.levels == [0.5]
    assert listed(deployer, made.name).dropped == 3
    seen = note(gauge, "level")
    assert seen.refused == 3 and "0 <= x <= 1" in seen.refusal and seen.unauthenticated


def test_a_value_that_does_not_convert_is_refused_and_counted(ros: RosMaster, deployer: Deployer) -> None:
    gauge = deployer.add(Gauge("gauge"))
    made = stream(deployer, ros, "gauge.count", "/gauge/small", type="std_msgs/Int8")
    connected(deployer, made.name)
    echo = ros.spawn("rostopic", "echo", "/gauge/small")

    def printed() -> bool:  # rostopic echo subscribed: what is written now is converted and sent
        gauge.count.write(7)
        try:
            echo.read_until("data: 7", timeout=0.2)
        except AssertionError:
            return False
        return True

    with running(echo):
        wait_until(printed, timeout=60, message="rostopic echo never printed")
        gauge.count.write(300)  # no int8
        gauge.count.write(8)
        echo.read_until("data: 8", timeout=30)
    seen = note(gauge, "count")
    assert seen.refused == 1 and seen.refusal.startswith("sample "), seen
    assert not seen.unauthenticated  # an output: nobody feeds it
    assert "data: 300" not in echo.text() and listed(deployer, made.name).dropped == 1


def test_a_stream_that_cannot_be_made_is_refused_clearly(ros: RosMaster, deployer: Deployer) -> None:
    deployer.add(Gauge("gauge"))
    cases: list[tuple[str, str, dict[str, Any], str]] = [
        ("gauge.level", "/x", {"type": "sensor_msgs/JointState"}, "maps onto a message with a 'data' field"),
        ("gauge.point", "/x", {"type": "sensor_msgs/JointState"}, "x, y, z have no field in sensor_msgs/JointState"),
        ("gauge.level", "/x", {"type": "std_msgs/Nope"}, "unknown ROS 1 message type"),
        ("gauge.number", "/x", {"type": "std_msgs/Float64"}, "float64"),
        ("gauge.level", "bad topic", {}, "illegal ROS topic name"),
        ("gauge.level", "/x", {"lach": "true"}, "unknown option(s) lach"),
        ("gauge.level", "/x", {"host": "10.1.2.3"}, "listens on loopback unless told insecure"),
        ("gauge.level", "/x", {"converter": "not_imported_anywhere:fn"}, "is not imported in this process"),
    ]
    for port, topic, options, words in cases:
        with pytest.raises(TransportError, match=re.escape(words)):
            stream(deployer, ros, port, topic, **options)
    assert deployer.streams() == {}


def test_one_node_per_process(ros: RosMaster, deployer: Deployer) -> None:
    deployer.add(Gauge("gauge"))
    stream(deployer, ros, "gauge.level", "/a")
    with pytest.raises(TransportError, match="one node per process"):
        stream(deployer, ros, "gauge.number", "/b", node="another_name")


def test_rosservice_call_is_answered_by_a_task_operation(ros: RosMaster, deployer: Deployer) -> None:
    load("ros1").types.add_srv("roscpp/SetLoggerLevel", "string logger\nstring level\n---\n")
    gauge = deployer.add(Gauge("gauge"))
    served = serve_operation(gauge, "set_logger_level", "/gauge/set_logger_level", "roscpp/SetLoggerLevel",
                             options={"master": ros.uri, "node": NODE})
    try:
        assert served.node.wait_registered(10)
        done = ros.tool("rosservice", "call", "/gauge/set_logger_level", "scart.test", "debug", timeout=60)
        assert done.returncode == 0, done.stderr
        assert gauge.loggers == [("scart.test", "debug")]
        bad = ros.tool("rosservice", "call", "/gauge/set_logger_level", "scart.test", "loud", timeout=60)
        assert bad.returncode != 0 and "no level 'loud'" in bad.stdout + bad.stderr
        assert (served.calls, served.failures) == (2, 1)
    finally:
        served.close()


def test_a_ros_service_is_called_from_scart(ros: RosMaster) -> None:
    require_rospy()
    types = load("ros1").types
    types.add_msg("roscpp/Logger", "string name\nstring level\n")
    types.add_srv("roscpp/GetLoggers", "---\nLogger[] loggers\n")
    peer = ros.rospy("serve", "/rospy/get_loggers")
    with running(peer):
        peer.read_until("ready", timeout=60)
        with ServiceProxy("/rospy/get_loggers", options={"master": ros.uri, "node": NODE}, timeout=10) as proxy:
            wait_until(lambda: _answers(proxy), timeout=30, interval=0.2, message="the rospy service never answered")
            assert proxy() == {"loggers": [{"name": "scart.test", "level": "info"}]}
            assert proxy.type_name == "roscpp/GetLoggers"  # asked of the service, as rosservice does


def _answers(proxy: ServiceProxy) -> bool:
    from scart_ros1 import ServiceError

    try:
        proxy()
        return True
    except ServiceError:
        return False


def test_nan_and_inf_from_ros_pass_unless_the_port_asks_for_finite(ros: RosMaster, deployer: Deployer) -> None:
    from scart_ros1 import Node

    gauge = deployer.add(Gauge("gauge"))
    pose = stream(deployer, ros, "gauge.pose", "/gauge/pose", ConnPolicy.buffer(10), type="geometry_msgs/Point")
    strict = stream(deployer, ros, "gauge.strict", "/gauge/strict", ConnPolicy.buffer(10))
    with Node("peer", master_uri=ros.uri) as peer:
        points, floats = peer.advertise("/gauge/pose", "geometry_msgs/Point"), peer.advertise("/gauge/strict",
                                                                                             "std_msgs/Float64")
        assert points.wait_for_connections(1, timeout=20) and floats.wait_for_connections(1, timeout=20)
        points.publish(points.type.new(x=float("nan"), y=1.0, z=float("inf")))  # legal ROS floats
        floats.publish(floats.type.new(data=float("nan")))
        floats.publish(floats.type.new(data=2.0))
        wait_until(lambda: listed(deployer, strict.name).samples == 2 and listed(deployer, pose.name).samples == 1,
                   timeout=10)
    flow, point = gauge.pose.read()
    assert flow.name == "NEW_DATA" and point.x != point.x and point.z == float("inf") and point.y == 1.0
    assert gauge.strict.read()[1] == 2.0 and listed(deployer, strict.name).dropped == 1
    assert "finite" in note(gauge, "strict").refusal
