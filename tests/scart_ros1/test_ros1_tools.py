"""Our ROS 1 node judged by ROS's own tools: rostopic echo/pub/hz, rosnode info, rosbag
record + info, rosservice call — each a subprocess against a real ``rosmaster --core``."""

from __future__ import annotations

import contextlib
import os
import re
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from support import wait_until
from support.ros1 import RosMaster, needs_ros, running

from scart_ros1 import Node, Publisher
from scart_ros1.master import call
from scart_ros1.tcpros import encode_header, read_header

pytestmark = [pytest.mark.integration, needs_ros]


@contextlib.contextmanager
def publishing(pub: Publisher, rate: float, make: Callable[[int], object]) -> Iterator[None]:
    """Publish ``make(i)`` at ``rate`` Hz on an owned thread until the block ends."""
    stop = threading.Event()

    def run() -> None:
        period, start, i = 1.0 / rate, time.monotonic(), 0
        while not stop.is_set() and i < rate * 120:  # bounded: two minutes at most
            pub.publish(make(i))
            i += 1
            stop.wait(max(0.0, start + i * period - time.monotonic()))

    thread = threading.Thread(target=run, name="test publisher")
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(10)


def test_rostopic_echo_prints_our_joint_states(ros: RosMaster, node: Node) -> None:
    pub = node.advertise("/joint_states", "sensor_msgs/JointState")
    assert node.wait_registered(10)

    def joint_state(i: int) -> object:
        return pub.type.new(header={"seq": i, "frame_id": "base"}, name=["a1", "a2"], position=[0.25, -1.5])

    with publishing(pub, 20, joint_state):
        done = ros.tool("rostopic", "echo", "-n", "1", "/joint_states", timeout=60)
    assert done.returncode == 0, done.stderr
    assert 'frame_id: "base"' in done.stdout
    assert "name: \n  - a1\n  - a2\n" in done.stdout and "position: [0.25, -1.5]" in done.stdout


def test_rostopic_echo_gets_the_latched_message(ros: RosMaster, node: Node) -> None:
    pub = node.advertise("~status", "std_msgs/String", latch=True)
    pub.publish(pub.type.new(data="latched hello"))
    assert node.wait_registered(10)
    done = ros.tool("rostopic", "echo", "-n", "1", "/scart/status", timeout=60)
    assert done.returncode == 0, done.stderr
    assert 'data: "latched hello"' in done.stdout


def test_rostopic_pub_reaches_our_subscriber(ros: RosMaster, node: Node) -> None:
    got: list[int] = []
    raw: list[bytes] = []
    sub = node.subscribe("/scart_in", "std_msgs/Int64", lambda msg: got.append(msg.data))
    with Node("raw", master_uri=ros.uri, types=node.types) as other:
        other.subscribe("/scart_in", "*", raw.append, raw=True)  # any type, bytes: as rostopic hz
        assert node.wait_registered(10) and other.wait_registered(10)
        done = ros.tool("rostopic", "pub", "-1", "/scart_in", "std_msgs/Int64", "data: 42", timeout=60)
        assert done.returncode == 0, done.stderr
        wait_until(lambda: got and raw, timeout=10, message="rostopic pub's value never reached the callbacks")
    assert got == [42] and raw == [(42).to_bytes(8, "little")]
    assert sub.counters["received"] == 1 and sub.counters["bad_messages"] == 0


def test_remapped_name_namespace_and_topic_as_ros_tools_see_them(ros: RosMaster) -> None:
    with Node("scart", master_uri=ros.uri, remaps=["__name:=renamed", "__ns:=/robot", "chatter:=/remapped"]) as n:
        n.advertise("chatter", "std_msgs/Int64")
        n.advertise("~private", "std_msgs/Int64")
        n.advertise("relative", "std_msgs/Int64")
        assert n.wait_registered(10)
        info = ros.tool("rosnode", "info", "/robot/renamed")
    assert info.returncode == 0, info.stderr
    published = info.stdout.split("Subscriptions:")[0]
    for topic in ("/remapped", "/robot/renamed/private", "/robot/relative"):
        assert f" * {topic} [std_msgs/Int64]" in published


def test_rostopic_hz_measures_our_rate(ros: RosMaster, node: Node) -> None:
    pub = node.advertise("/rate", "std_msgs/Int64")
    assert node.wait_registered(10)
    with publishing(pub, 50, lambda i: pub.type.new(data=i)):
        hz = ros.spawn("rostopic", "hz", "-w", "50", "/rate")
        with running(hz):
            hz.read_until("average rate", timeout=60, count=3)
    rates = [float(r) for r in re.findall(r"average rate: ([0-9.]+)", hz.text())]
    assert rates and 40 <= rates[-1] <= 60, hz.text()


def test_rosnode_info_lists_our_node_topics_and_connections(ros: RosMaster, node: Node) -> None:
    pub = node.advertise("/scart_out", "std_msgs/Int64", latch=True)
    pub.publish(pub.type.new(data=7))
    node.subscribe("/scart_cmd", "std_msgs/String", lambda msg: None)
    node.advertise_service("~get_loggers", "roscpp/GetLoggers", lambda req: None)
    assert node.wait_registered(10)
    echo = ros.spawn("rostopic", "echo", "/scart_out")
    with running(echo):
        echo.read_until("data: 7", timeout=60)
        assert pub.num_connections == 1
        info = ros.tool("rosnode", "info", "/scart")
    assert info.returncode == 0, info.stderr
    text = info.stdout
    assert "Node [/scart]" in text
    assert " * /scart_out [std_msgs/Int64]" in text.split("Subscriptions:")[0]
    # rosnode takes types from published topics: one nobody publishes is "[unknown type]", as for rospy
    assert " * /scart_cmd [" in text.split("Subscriptions:")[1].split("Services:")[0]
    assert " * /scart/get_loggers" in text.split("Services:")[1]
    assert " * topic: /scart_out" in text and "direction: outbound" in text and "transport: TCPROS" in text
    listed = ros.tool("rosnode", "list")
    assert "/scart" in listed.stdout.split()


def test_rosbag_records_our_topic(ros: RosMaster, node: Node, tmp_path: Path) -> None:
    pub = node.advertise("/joint_states", "sensor_msgs/JointState")
    assert node.wait_registered(10)
    bag = tmp_path / "scart.bag"
    with publishing(pub, 50, lambda i: pub.type.new(name=["a1"], position=[i * 0.01])):
        record = ros.tool("rosbag", "record", "-O", str(bag), "--duration=3", "/joint_states", timeout=60)
    assert record.returncode == 0, record.stderr
    info = ros.tool("rosbag", "info", str(bag))
    assert info.returncode == 0, info.stderr
    line = next(x for x in info.stdout.splitlines() if "/joint_states" in x)
    count = int(re.search(r"(\d+) msgs", line).group(1))
    assert "sensor_msgs/JointState" in line and count >= 50, info.stdout


def test_rosservice_call_into_our_service(ros: RosMaster, node: Node) -> None:
    srvtype = node.types.srv("roscpp/GetLoggers")
    logger = node.types.msg("roscpp/Logger")

    def handler(req: object) -> object:
        return srvtype.response.new(loggers=[logger.new(name="scart", level="debug")])

    srv = node.advertise_service("/scart/get_loggers", "roscpp/GetLoggers", handler)
    assert node.wait_registered(10)
    typ = ros.tool("rosservice", "type", "/scart/get_loggers")  # a probe connection
    assert typ.stdout.strip() == "roscpp/GetLoggers", typ.stderr
    done = ros.tool("rosservice", "call", "/scart/get_loggers")
    assert done.returncode == 0, done.stderr
    assert 'name: "scart"' in done.stdout and 'level: "debug"' in done.stdout
    assert srv.counters["requests"] == 1


def test_rosservice_call_sees_our_handlers_error(ros: RosMaster, node: Node) -> None:
    def handler(req: object) -> object:
        raise RuntimeError("the arm is not homed")

    srv = node.advertise_service("/scart/broken", "roscpp/GetLoggers", handler)
    assert node.wait_registered(10)
    done = ros.tool("rosservice", "call", "/scart/broken")
    assert done.returncode != 0
    assert "the arm is not homed" in done.stdout + done.stderr
    assert srv.counters["handler_errors"] == 1 and node.counters["service_errors"] == 1


def test_the_slave_api_answers_as_ros_says(ros: RosMaster, node: Node) -> None:
    pub = node.advertise("/out", "std_msgs/Int64")
    node.subscribe("/in", "std_msgs/String", lambda msg: None)
    assert node.wait_registered(10)

    def ask(method: str, *args: object) -> object:
        return call(node.uri, method, "/tester", *args, timeout=5)

    assert ask("getPid") == os.getpid() and ask("getMasterUri") == ros.uri
    assert ask("getPublications") == [["/out", "std_msgs/Int64"]]
    assert ask("getSubscriptions") == [["/in", "std_msgs/String"]]
    assert ask("requestTopic", "/out", [["UDPROS"], ["TCPROS"]]) == ["TCPROS", "127.0.0.1", node.tcpros_port]
    assert ask("paramUpdate", "/some/param", 3) == 0 and ask("publisherUpdate", "/in", []) == 0
    # tcp_nodelay as each subscriber asks
    peers = []
    for nodelay in ("1", "0"):
        sock = socket.create_connection(("127.0.0.1", node.tcpros_port), timeout=10)
        sock.sendall(encode_header({"callerid": f"/nd{nodelay}", "topic": "/out", "md5sum": "*", "tcp_nodelay": nodelay}))
        assert read_header(sock, time.monotonic() + 10, 1 << 20)["type"] == "std_msgs/Int64"
        peers.append(sock)
    assert pub.wait_for_connections(2, timeout=10)
    flags = {c.peer_id: c.sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) for c in pub.connections()}
    assert flags == {"/nd1": 1, "/nd0": 0}
    pub.publish(pub.type.new(data=3))
    wait_until(lambda: ask("getBusStats")[0][0][2][0][2] >= 1, timeout=10)  # [pubs][topic][conns][conn][numSent]
    info = ask("getBusInfo")
    assert sorted(row[1] for row in info) == ["/nd0", "/nd1"] and all(row[2:6] == ["o", "TCPROS", "/out", True] for row in info)
    for sock in peers:
        sock.close()
