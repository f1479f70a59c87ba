"""Fair sharing of our ROS 1 node: slow XML-RPC clients hold a worker each, never the
node; one peer cannot take every connection; idle service connections and subscribers
that take nothing are closed. Judged by ``rostopic echo`` against a real ``rosmaster``."""

from __future__ import annotations

import socket
import time

import pytest
from support import wait_until
from support.ros1 import RosMaster, needs_ros

from scart_ros1 import Limits, MessageTypes, Node
from scart_ros1.tcpros import encode_header, read_header

pytestmark = [pytest.mark.integration, needs_ros]


def still_open(sock: socket.socket) -> bool:
    """Whether the other end has not closed ``sock`` (nothing to read, no EOF)."""
    sock.setblocking(False)
    try:
        return sock.recv(1) != b""
    except BlockingIOError:
        return True
    except OSError:
        return False
    finally:
        sock.setblocking(True)


def closed_within(sock: socket.socket, seconds: float) -> bool:
    """Whether the node closes ``sock`` within ``seconds`` (what it sends first is read)."""
    deadline = time.monotonic() + seconds
    while (left := deadline - time.monotonic()) > 0:
        sock.settimeout(left)
        try:
            if sock.recv(65536) == b"":
                return True
        except TimeoutError:
            return False
        except ConnectionResetError:
            return True
    return False


def echo_beside_slow_clients(ros: RosMaster, types: MessageTypes, name: str, text: str, count: int,
                             source: str, why: str) -> None:
    """``rostopic echo`` of a node's latched ``/NAME`` answered while ``count`` clients from
    ``source`` each hold one of its XML-RPC workers with a request begun and never finished
    (for 60 s); the slow ones still open after it (``why`` if not)."""
    with Node(name, master_uri=ros.uri, types=types, limits=Limits(xmlrpc_seconds=60)) as node:
        pub = node.advertise(f"/{name}", "std_msgs/String", latch=True)
        pub.publish(pub.type.new(data=text))
        assert node.wait_registered(10)
        port = int(node.uri.rsplit(":", 1)[1].strip("/"))
        slow = [socket.create_connection(("127.0.0.1", port), timeout=10, source_address=(source, 0))
                for _ in range(count)]
        try:
            for sock in slow:
                sock.sendall(b"POST / HTTP/1.0\r\nContent-Length: 500\r\n\r\n<?xml")
            echo = ros.tool("rostopic", "echo", "-n", "1", f"/{name}", timeout=50)  # its requestTopic: 127.0.0.1
            assert echo.returncode == 0, echo.stderr
            assert f'data: "{text}"' in echo.stdout
            assert all(still_open(sock) for sock in slow), why
        finally:
            for sock in slow:
                sock.close()


def test_three_slow_xmlrpc_clients_leave_rostopic_echo_answered(ros: RosMaster, types: MessageTypes) -> None:
    echo_beside_slow_clients(ros, types, "fair", "served", 3, "127.0.0.1",
                             "the slow clients were cut, not served beside echo")


def test_eight_slow_xmlrpc_clients_of_one_peer_leave_another_peers_echo_answered(ros: RosMaster,
                                                                                types: MessageTypes) -> None:
    # as many as the pool has workers, all from one peer address
    echo_beside_slow_clients(ros, types, "shared", "half the pool is yours", 8, "127.0.0.2",
                             "the slow clients were cut, not made to wait their turn")


def test_a_thousand_idle_connections_from_one_peer_leave_another_peer_in(ros: RosMaster, types: MessageTypes) -> None:
    with Node("crowded", master_uri=ros.uri, types=types) as node:
        pub = node.advertise("/crowded", "std_msgs/String", latch=True)
        pub.publish(pub.type.new(data="still in"))
        trigger = node.advertise_service("~trigger", "std_srvs/Trigger", lambda req: None)
        assert node.wait_registered(10)
        header = encode_header({"callerid": "/hog", "service": trigger.name, "md5sum": "*", "persistent": "1"})
        hogs: list[socket.socket] = []
        deadline = time.monotonic() + 60
        try:
            while len(hogs) < 1000 and time.monotonic() < deadline:  # one peer, 127.0.0.2, idle once connected
                sock = socket.create_connection(("127.0.0.1", node.tcpros_port), timeout=5,
                                                source_address=("127.0.0.2", 0))
                hogs.append(sock)
                try:
                    sock.sendall(header)
                except OSError:
                    pass  # refused and closed already
            assert len(hogs) == 1000
            wait_until(lambda: node.counters["refused_connections"] >= 1000 - node.limits.max_per_peer, timeout=20)
            echo = ros.tool("rostopic", "echo", "-n", "1", "/crowded", timeout=50)  # from 127.0.0.1
            assert echo.returncode == 0, echo.stderr
            assert 'data: "still in"' in echo.stdout
        finally:
            for sock in hogs:
                sock.close()


def test_an_idle_service_connection_is_closed(ros: RosMaster, types: MessageTypes) -> None:
    trigger = types.srv("std_srvs/Trigger")
    with Node("idle", master_uri=ros.uri, types=types, limits=Limits(idle_seconds=0.5)) as node:
        srv = node.advertise_service("~trigger", "std_srvs/Trigger", lambda req: trigger.response.new(success=True))
        header = {"callerid": "/idler", "service": srv.name, "md5sum": "*", "persistent": "1"}
        with socket.create_connection(("127.0.0.1", node.tcpros_port), timeout=10) as sock:
            sock.sendall(encode_header(header))
            assert read_header(sock, time.monotonic() + 10, 1 << 20)["type"] == "std_srvs/Trigger"
            assert closed_within(sock, 10)
        assert node.counters["idle_closed"] == 1


def test_a_subscriber_that_takes_nothing_is_closed(ros: RosMaster, types: MessageTypes) -> None:
    with Node("talker", master_uri=ros.uri, types=types, limits=Limits(idle_seconds=0.5)) as node:
        pub = node.advertise("/flood", "std_msgs/String")
        header = {"callerid": "/stalled", "topic": "/flood", "md5sum": "*", "type": "*", "tcp_nodelay": "1"}
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        with sock:
            sock.settimeout(10)
            sock.connect(("127.0.0.1", node.tcpros_port))
            sock.sendall(encode_header(header))
            read_header(sock, time.monotonic() + 10, 1 << 20)  # then it never reads again
            assert pub.wait_for_connections(1, timeout=10)
            payload = "p" * 64 * 1024
            for _ in range(200):  # far more than the kernel's buffers hold: the rest waits, unsent
                pub.publish(pub.type.new(data=payload))
            wait_until(lambda: pub.num_connections == 0, timeout=15, message="the stalled subscriber was kept")
        assert node.counters["idle_closed"] == 1
