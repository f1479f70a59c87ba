"""Our ROS 1 node with rospy nodes (Debian's python3-rospy, run by the system Python):
rospy publishing to us, subscribing from us, serving a service we call, calling ours."""

from __future__ import annotations

import pytest
from support import wait_until
from support.ros1 import RosMaster, needs_ros, require_rospy, running

from scart_ros1 import MasterError, Node, ServiceError
from scart_ros1.services import service_type

pytestmark = [pytest.mark.integration, needs_ros]
COUNT = 50


@pytest.fixture(autouse=True)
def _rospy() -> None:
    require_rospy()  # every test here talks to a rospy peer


def test_rospy_publishes_to_us(ros: RosMaster, node: Node) -> None:
    got: list[int] = []
    sub = node.subscribe("/from_rospy", "std_msgs/Int64", lambda msg: got.append(msg.data))
    assert node.wait_registered(10)
    peer = ros.rospy("pub", "/from_rospy", str(COUNT), "100")
    with running(peer):
        peer.read_until("done", timeout=60)
        wait_until(lambda: len(got) >= COUNT, timeout=10, message=f"got {len(got)} of {COUNT}")
    assert got == list(range(COUNT))
    assert sub.counters["received"] == COUNT and sub.counters["bad_messages"] == 0


def test_rospy_subscribes_from_us(ros: RosMaster, node: Node) -> None:
    pub = node.advertise("/to_rospy", "std_msgs/Int64")
    peer = ros.rospy("sub", "/to_rospy", str(COUNT))
    with running(peer):
        peer.read_until("ready", timeout=60)
        assert pub.wait_for_connections(1, timeout=30), "rospy never connected"
        for i in range(COUNT):
            pub.publish(pub.type.new(data=i))
        peer.read_until(f"got {COUNT - 1}", timeout=30)
    assert [int(x) for x in peer.text().split("got ")[1:]] == list(range(COUNT))
    assert pub.counters["messages_sent"] == COUNT and pub.counters["dropped"] == 0


def test_we_call_a_rospy_service(ros: RosMaster, node: Node) -> None:
    peer = ros.rospy("serve", "/rospy/get_loggers")
    with running(peer):
        peer.read_until("ready", timeout=60)
        wait_until(lambda: _service_known(node, "/rospy/get_loggers"), timeout=20)
        assert service_type(node, "/rospy/get_loggers") == "roscpp/GetLoggers"  # the probe, as rosservice type
        srvtype = node.types.srv("roscpp/GetLoggers")
        answer = node.call_service("/rospy/get_loggers", "roscpp/GetLoggers", srvtype.request.new(), timeout=5)
    assert [(lg.name, lg.level) for lg in answer.loggers] == [("scart.test", "info")]
    with pytest.raises(ServiceError, match="not available"):
        service_type(node, "/rospy/nobody", timeout=2)


def test_rospy_calls_our_service(ros: RosMaster, node: Node) -> None:
    srvtype = node.types.srv("roscpp/GetLoggers")
    logger = node.types.msg("roscpp/Logger")
    srv = node.advertise_service("/scart/get_loggers", "roscpp/GetLoggers",
                                 lambda req: srvtype.response.new(loggers=[logger.new(name="scart", level="debug")]))
    assert node.wait_registered(10)
    peer = ros.rospy("call", "/scart/get_loggers")  # twice, on one persistent connection
    with running(peer):
        assert peer.read_until("loggers", timeout=60, count=2).count("loggers scart=debug") == 2
    assert srv.counters["requests"] == 2 and srv.counters["handler_errors"] == 0


def _service_known(node: Node, name: str) -> bool:
    try:
        node.master.lookup_service(name)
    except MasterError:
        return False
    return True
