"""Bad input and bad peers for our ROS 1 node: each refused or dropped, counted, survived.

md5sum mismatches (both types and sums said), a master that is down then up or restarted,
malformed headers, oversized messages, stalled peers (a silent one, a subscriber that
stops reading), peers that vanish, a flooding or trickling XML-RPC client, failing service
calls, ``rosnode kill``."""

from __future__ import annotations

import http.client
import logging
import socket
import struct
import threading
import time
from pathlib import Path

import pytest
from support import wait_until
from support.ros1 import RosMaster, needs_ros, require_rospy, running

from scart_ros1 import Limits, MessageTypes, Node, ServiceError
from scart_ros1.tcpros import encode_header, read_header

pytestmark = [pytest.mark.integration, needs_ros]
LOGGER = "scart_ros1"


def make_node(ros: RosMaster, types: MessageTypes, name: str = "scart", **kw: object) -> Node:
    return Node(name, master_uri=ros.uri, types=types, **kw)  # type: ignore[arg-type]


def raw_peer(node: Node, header: dict[str, str] | None = None, rcvbuf: int = 0) -> socket.socket:
    """A TCP connection to the node's TCPROS port, having sent ``header`` if given."""
    sock = socket.socket()
    if rcvbuf:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    sock.settimeout(10)
    sock.connect(("127.0.0.1", node.tcpros_port))
    if header is not None:
        sock.sendall(encode_header(header))
    return sock


def closed_by_peer(sock: socket.socket) -> bool:
    """Whether the node closed ``sock`` (whatever it said before; bounded reads)."""
    try:
        for _ in range(100):
            if sock.recv(65536) == b"":
                return True
    except ConnectionResetError:
        return True
    return False


def test_md5_mismatch_refused_with_both_types_and_sums(ros: RosMaster, types: MessageTypes, caplog) -> None:
    caplog.set_level(logging.WARNING, logger=LOGGER)
    with make_node(ros, types) as node:
        node.advertise("/t", "std_msgs/Int64")
        with raw_peer(node, {"callerid": "/evil", "topic": "/t", "md5sum": "0" * 32, "type": "std_msgs/String"}) as sock:
            reply = read_header(sock, time.monotonic() + 10, 1 << 20)
            assert closed_by_peer(sock)
        error = reply["error"]
        for part in ("/evil", "/t", "std_msgs/String", "0" * 32, "std_msgs/Int64", "34add168574510e6e17f5d23ecc077ef"):
            assert part in error
        assert error in caplog.text
        assert node.counters["md5_mismatches"] == 1
        # md5sum "*" (rostopic hz, rosbag) is accepted, as ROS does
        with raw_peer(node, {"callerid": "/any", "topic": "/t", "md5sum": "*", "type": "*"}) as sock:
            reply = read_header(sock, time.monotonic() + 10, 1 << 20)
        assert reply["md5sum"] == "34add168574510e6e17f5d23ecc077ef" and "error" not in reply


def test_our_subscriber_refuses_a_publisher_of_another_type(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types, "talker") as talker, make_node(ros, types, "listener") as listener:
        talker.advertise("/mixed", "std_msgs/Int64")
        sub = listener.subscribe("/mixed", "std_msgs/String", lambda msg: None)
        wait_until(lambda: sub.counters["connect_failures"] >= 1, timeout=15)
        assert talker.counters["md5_mismatches"] >= 1  # the publisher refused it first, saying why
        assert sub.num_connections == 0


def test_master_down_then_up_then_restarted(tmp_path: Path, types: MessageTypes, caplog) -> None:
    caplog.set_level(logging.INFO, logger=LOGGER)
    master = RosMaster(tmp_path)  # not started: the node meets no master
    try:
        with Node("scart", master_uri=master.uri, types=types, master_timeout=1.0, master_poll=0.3) as node:
            node.advertise("/survivor", "std_msgs/Int64")
            wait_until(lambda: node.counters["master_retries"] >= 2, timeout=15)
            assert not node.master_reachable and not node.wait_registered(0.1)
            assert "waits for it, retrying" in caplog.text and master.uri in caplog.text
            master.start()
            assert node.wait_registered(15) and node.master_reachable
            assert "answers again" in caplog.text
            assert ["/survivor", "std_msgs/Int64"] in node.master.get_published_topics()
            master.stop()
            master.start()  # a new rosmaster: it has forgotten us
            wait_until(lambda: ["/survivor", "std_msgs/Int64"] in node.master.get_published_topics(), timeout=20,
                       message="the node did not register again with the new master")
            assert node.counters["master_reregistrations"] >= 2
    finally:
        master.stop()


def test_malformed_headers_are_dropped_and_counted(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types) as node:
        pub = node.advertise("/ok", "std_msgs/Int64", latch=True)
        pub.publish(pub.type.new(data=5))
        bad_bodies = [
            struct.pack("<I", 0x7FFFFFFF),  # a header larger than the bound
            struct.pack("<I", 7) + struct.pack("<I", 3) + b"abc",  # a field without '='
            struct.pack("<I", 8) + struct.pack("<I", 90) + b"a=bc",  # a field overrunning the header
        ]
        for body in bad_bodies:
            with raw_peer(node) as sock:
                sock.sendall(body)
                assert closed_by_peer(sock)
        with raw_peer(node, {"callerid": "/x", "md5sum": "*"}) as sock:  # neither topic nor service
            assert "neither" in read_header(sock, time.monotonic() + 10, 1 << 20)["error"]
        assert node.counters["malformed_headers"] == 4
        got: list[int] = []  # the node still serves
        with make_node(ros, types, "checker") as checker:
            checker.subscribe("/ok", "std_msgs/Int64", lambda msg: got.append(msg.data))
            wait_until(lambda: got == [5], timeout=15)


def test_oversized_messages_are_skipped_and_counted(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types, "talker") as talker, \
            make_node(ros, types, "listener", limits=Limits(max_message=1000)) as listener:
        pub = talker.advertise("/big", "std_msgs/String")
        got: list[str] = []
        sub = listener.subscribe("/big", "std_msgs/String", lambda msg: got.append(msg.data))
        assert pub.wait_for_connections(1, timeout=15)
        for text in ("small", "x" * 5000, "after", "y" * 100_000, "last"):
            pub.publish(pub.type.new(data=text))
        wait_until(lambda: "last" in got, timeout=10)
        assert got == ["small", "after", "last"]
        assert sub.counters["oversized"] == 2 and listener.counters["oversized_messages"] == 2
        assert sub.num_connections == 1  # the connection lives on


def test_a_silent_peer_is_dropped_after_the_header_timeout(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types, limits=Limits(header_timeout=0.5)) as node:
        with raw_peer(node) as sock:
            sock.sendall(b"\x10\x00")  # two bytes of a length, then silence
            wait_until(lambda: node.counters["stalled_peers"] == 1, timeout=10)
            assert closed_by_peer(sock)


def test_a_stalled_subscriber_never_blocks_the_publisher(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types, "talker") as talker, make_node(ros, types, "listener") as listener:
        pub = talker.advertise("/flood", "std_msgs/String", queue_size=1000, queue_bytes=1 << 20)
        got: list[str] = []
        listener.subscribe("/flood", "std_msgs/String", lambda msg: got.append(msg.data[:8]))
        header = {"callerid": "/stalled", "topic": "/flood", "md5sum": "*", "type": "*", "tcp_nodelay": "1"}
        with raw_peer(talker, header, rcvbuf=4096) as stalled:
            read_header(stalled, time.monotonic() + 10, 1 << 20)  # then it never reads again
            assert pub.wait_for_connections(2, timeout=15)
            count, payload = 400, "p" * 32 * 1024
            publisher = threading.Thread(target=lambda: [pub.publish(pub.type.new(data=f"{i:08d}{payload}"))
                                                         for i in range(count)], name="test-publisher", daemon=True)
            publisher.start()
            publisher.join(timeout=30)  # a publish() blocking on the stalled peer would never end
            assert not publisher.is_alive(), "publish() blocked on a subscriber that reads nothing"
            wait_until(lambda: got and got[-1] == f"{count - 1:08d}", timeout=20, message="the good subscriber lagged")
            stalled_conn = next(c for c in pub.connections() if c.peer_id == "/stalled")
            good_conn = next(c for c in pub.connections() if c.peer_id != "/stalled")
            assert stalled_conn.stats["dropped"] > 0
            assert len(got) + good_conn.stats["dropped"] == count  # every message delivered or counted
            assert pub.counters["dropped"] == stalled_conn.stats["dropped"] + good_conn.stats["dropped"]


def test_a_vanished_rospy_publisher_is_counted_and_survived(ros: RosMaster, types: MessageTypes) -> None:
    require_rospy()
    with make_node(ros, types) as node:
        got: list[int] = []
        sub = node.subscribe("/from_rospy", "std_msgs/Int64", lambda msg: got.append(msg.data))
        peer = ros.rospy("pub", "/from_rospy", "5", "50")
        with running(peer):
            peer.read_until("done", timeout=60)
            wait_until(lambda: len(got) == 5, timeout=10)
            peer.proc.kill()  # gone without a word: no unregistration
            peer.wait()
            wait_until(lambda: sub.counters["publishers_gone"] == 1, timeout=10)
        assert node.counters["peer_disconnects"] >= 1 and sub.num_connections == 0
        pub = node.advertise("/still_alive", "std_msgs/Int64")  # and the node goes on
        assert node.wait_registered(10) and pub.publish(pub.type.new(data=1)) == 0


def test_a_vanished_subscriber_is_counted(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types) as node:
        pub = node.advertise("/t", "std_msgs/Int64")
        with raw_peer(node, {"callerid": "/brief", "topic": "/t", "md5sum": "*", "type": "*"}) as sock:
            read_header(sock, time.monotonic() + 10, 1 << 20)
            assert pub.wait_for_connections(1, timeout=10)
        wait_until(lambda: pub.num_connections == 0, timeout=10)
        assert pub.counters["subscribers_gone"] == 1
        assert pub.publish(pub.type.new(data=1)) == 0


def test_xmlrpc_floods_and_trickles_are_bounded(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types, limits=Limits(xmlrpc_bytes=4096, xmlrpc_seconds=0.5)) as node:
        port = int(node.uri.rsplit(":", 1)[1].strip("/"))
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        conn.request("POST", "/", body=b"<" * 10_000, headers={"Content-Type": "text/xml"})
        assert conn.getresponse().status == 413
        conn.close()
        with socket.create_connection(("127.0.0.1", port), timeout=10) as trickle:
            trickle.sendall(b"POST / HTTP/1.0\r\nContent-Length: 100\r\n\r\n<?xml")  # then stalls
            # the node answers another caller meanwhile: within 3 s, or the call times out
            assert node.master_for(5).uri and _get_pid(node.uri, timeout=3.0) == __import__("os").getpid()
            assert closed_by_peer(trickle)
        assert node.counters["xmlrpc_bad_requests"] >= 2


def _get_pid(uri: str, timeout: float = 10.0) -> int:
    import xmlrpc.client

    class Bounded(xmlrpc.client.Transport):  # a server that stalls fails the call, never hangs it
        def make_connection(self, host):  # type: ignore[no-untyped-def]
            conn = super().make_connection(host)
            conn.timeout = timeout
            return conn

    code, _, pid = xmlrpc.client.ServerProxy(uri, transport=Bounded()).getPid("/test")
    assert code == 1
    return pid


def test_service_call_failures_say_why(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types, "server") as server, make_node(ros, types, "client") as client:
        trigger = types.srv("std_srvs/Trigger")
        with pytest.raises(ServiceError, match="/nowhere is not available"):
            client.call_service("/nowhere", "std_srvs/Trigger", trigger.request.new(), timeout=2)
        server.advertise_service("/slow", "std_srvs/Trigger", lambda req: time.sleep(1.5) or trigger.response.new())
        server.advertise_service("/fine", "std_srvs/Trigger", lambda req: trigger.response.new(success=True, message="ok"))
        server.advertise_service("/wrong", "std_srvs/Trigger", lambda req: "not a response")
        assert server.wait_registered(10)
        with pytest.raises(ServiceError, match="no answer within 0.3 s"):
            client.call_service("/slow", "std_srvs/Trigger", trigger.request.new(), timeout=0.3)
        with pytest.raises(ServiceError, match="answered no std_srvs/TriggerResponse"):
            client.call_service("/wrong", "std_srvs/Trigger", trigger.request.new(), timeout=5)
        with pytest.raises(ServiceError, match="datatype/md5sum"):
            client.call_service("/fine", "std_srvs/SetBool", types.srv("std_srvs/SetBool").request.new(), timeout=5)
        answer = client.call_service("/fine", "std_srvs/Trigger", trigger.request.new(), timeout=5)
        assert answer.success and answer.message == "ok"


def test_rosnode_kill_shuts_the_node_down(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types) as node:
        node.advertise("/t", "std_msgs/Int64")
        assert node.wait_registered(10)
        done = ros.tool("rosnode", "kill", "/scart")
        assert done.returncode == 0, done.stderr
        assert node.wait_closed(10) and "/rosnode" in (node.shutdown_reason or "")


def test_rosnode_kill_restarts_a_respawning_node(ros: RosMaster, types: MessageTypes) -> None:
    with make_node(ros, types, respawn=True) as node:
        node.advertise("/t", "std_msgs/Int64")
        assert node.wait_registered(10)
        done = ros.tool("rosnode", "kill", "/scart")
        assert done.returncode == 0, done.stderr
        wait_until(lambda: node.counters["restarts"] == 1, timeout=10)
        assert not node.closed and node.wait_registered(10)
        info = ros.tool("rosnode", "info", "/scart")  # registered again, under the same name and URI
        assert info.returncode == 0 and " * /t [std_msgs/Int64]" in info.stdout, info.stdout + info.stderr
