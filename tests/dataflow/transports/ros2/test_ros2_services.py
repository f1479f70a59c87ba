"""ROS 2 services and scart, both ways: a task's operation answers a ROS 2 service called by
an independent rmw_cyclonedds-style client (``support/ros2_peer.py client``), and scart
calls an independent server (``ros2_peer.py server``); std_srvs' success/message
convention; the types checked before anything is served."""

from __future__ import annotations

import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from pydantic import BaseModel  # noqa: E402

from dataflow import Deployer, PeriodicActivity, TaskContext, operation  # noqa: E402
from dataflow.transports import TransportError, load  # noqa: E402
from dataflow.transports.ros2 import ServiceProxy, call_service, serve, serve_operation  # noqa: E402

pytestmark = pytest.mark.integration


class Calculator(TaskContext):
    """Operations a ROS 2 service may call; ``own_thread`` ones run in the task's thread."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.set_activity(PeriodicActivity(0.01))
        self.resets = 0

    @operation(own_thread=True)
    def add(self, a: int, b: int) -> int:
        return a + b

    @operation(own_thread=True)
    def reset(self) -> None:
        self.resets += 1

    @operation
    def jam(self) -> None:
        raise RuntimeError("the arm is jammed")

    @operation
    def halve(self, a: float, b: float) -> float:
        return (a + b) / 2


class Sum(BaseModel):
    sum: int


@pytest.fixture
def calculator():
    deployer = Deployer()
    task = deployer.add(Calculator("calc"))
    deployer.configure_all()
    deployer.start_all()
    yield task
    deployer.stop_all()
    deployer.cleanup_all()


def test_a_task_operation_answers_an_independent_ros2_client(domain: int, peer, calculator: Calculator) -> None:
    with serve_operation(calculator, "add", "/peer/add", "example_interfaces/srv/AddTwoInts",
                         options={"domain": str(domain)}) as served:
        client = peer("client")  # calls /peer/add with a=20, b=22 once matched, seq 7
        reply = client.next_event("reply")
        assert (reply["sum"], reply["seq"], reply["mine"]) == (42, 7, True)
        assert (served.calls, served.failures) == (1, 0)
    assert load("ros2").participants() == {}


def test_std_srvs_trigger_follows_the_success_message_convention(domain: int, topic: str,
                                                                  calculator: Calculator) -> None:
    options = {"domain": str(domain)}
    with serve_operation(calculator, "reset", topic + "/reset", "std_srvs/srv/Trigger", options=options), \
            serve_operation(calculator, "jam", topic + "/jam", "std_srvs/srv/Trigger", options=options), \
            serve(lambda flag: "on" if flag else "off", topic + "/set", "std_srvs/srv/SetBool", options=options):
        assert call_service(topic + "/reset", type_name="std_srvs/srv/Trigger", timeout=10, options=options) == \
            {"success": True, "message": ""}
        assert calculator.resets == 1
        assert call_service(topic + "/jam", type_name="std_srvs/srv/Trigger", timeout=10, options=options) == \
            {"success": False, "message": "RuntimeError: the arm is jammed"}
        assert call_service(topic + "/set", {"data": True}, type_name="std_srvs/srv/SetBool", timeout=10,
                            options=options) == \
            {"success": True, "message": "on"}


def test_scart_calls_an_independent_ros2_server(domain: int, peer) -> None:
    server = peer("server")  # /peer/times answers a × b
    with ServiceProxy("/peer/times", "example_interfaces/srv/AddTwoInts", returns=Sum, timeout=10,
                      options={"domain": str(domain)}) as times:
        assert times(a=6, b=7) == Sum(sum=42)
        assert times({"a": 3, "b": 3}) == Sum(sum=9)
    assert server.next_event("request")["a"] == 6


def test_types_that_do_not_map_are_refused_before_serving(domain: int, calculator: Calculator) -> None:
    options = {"domain": str(domain)}
    with pytest.raises(TransportError, match=r"calc\.halve: the return type float vs "
                                             r"example_interfaces/srv/AddTwoInts_Response.*float and int64"):
        serve_operation(calculator, "halve", "/x", "example_interfaces/srv/AddTwoInts", options=options)
    with pytest.raises(TransportError, match=r"calc\.reset: .*AddTwoInts_Request field\(s\) a, b match no parameter"):
        serve_operation(calculator, "reset", "/x", "example_interfaces/srv/AddTwoInts", options=options)
    with pytest.raises(TransportError, match="unknown ROS 2 service type"):
        serve_operation(calculator, "add", "/x", "nope/srv/Nothing", options=options)
    assert load("ros2").participants() == {}


def test_a_call_nobody_answers_times_out(domain: int, topic: str) -> None:
    with pytest.raises(TimeoutError, match="is not there within 0.3 s"):
        call_service(topic, type_name="std_srvs/srv/Trigger", timeout=0.3, options={"domain": str(domain)})
