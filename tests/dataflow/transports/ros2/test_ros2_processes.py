"""ROS 2 streams of scart processes, as a user makes them: ``scart stream COMP.PORT
ros2:/topic --type T`` against a ``scart deploy``, and the youBot demo's ROS 2 composite
(``/joint_states``, its period and pose from ROS 2 topics, its reset a ROS 2 service),
each judged by the independent peer (``support/ros2_stream_peer.py``) over loopback on
this run's domain."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from support import free_port, wait_until  # noqa: E402
from support.remote import start_scart, stop_process, subprocess_env  # noqa: E402
from support.youbot import Demo  # noqa: E402

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]


def scart(*args: str, domain: int) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True, timeout=60,
                          env={**subprocess_env(), "ROS_DOMAIN_ID": str(domain)})


@pytest.fixture
def on_domain(domain: int, monkeypatch: pytest.MonkeyPatch) -> int:
    """Subprocesses started by the test join this run's domain (ROS_DOMAIN_ID)."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    return domain


def test_scart_stream_joins_a_deployed_port_to_ros2_topics(on_domain: int, topic: str, stream_peer) -> None:
    ns = f"127.0.0.1:{free_port()}"
    proc, _ = start_scart(["deploy", "support.remote:Pinger", "--period", "0.01", "--listen", ns])
    try:
        made = scart("stream", "pinger.input", f"ros2:{topic}/in", "--type", "std_msgs/msg/Float64",
                     "--policy", "buffer:10", "--ns", ns, domain=on_domain)
        assert made.returncode == 0, made.stderr
        assert f"streaming ros2:{topic}/in -> pinger.input (buffer:10)" in made.stdout
        assert scart("stream", "pinger.output", f"ros2:{topic}/out", "--ns", ns, domain=on_domain).returncode == 0
        refused = scart("stream", "pinger.input", f"ros2:{topic}/x", "--type", "std_msgs/msg/String", "--ns", ns,
                        domain=on_domain)
        assert refused.returncode == 1 and "float and string" in refused.stderr, refused.stderr
        reader = stream_peer("read", f"{topic}/out", "Float64")
        writer = stream_peer("write", f"{topic}/in", "Float64", [2.5, float("nan")])
        writer.next_event("acked")
        assert reader.next_event("sample")["data"] == 2.5  # in over ROS 2, gain 1, out over ROS 2
        nan = reader.next_event("sample")["data"]
        assert nan != nan  # a legal ROS float: a port that does not ask for finite values takes it, as ROS does
        described = scart("describe", "pinger", "--ns", ns, domain=on_domain)
        assert f"ros2:{topic}/in (std_msgs/msg/Float64), connected, UNAUTHENTICATED" in described.stdout
        assert "refused" not in described.stdout, described.stdout
        links = json.loads(scart("links", "--json", "--ns", ns, domain=on_domain).stdout)
        listed = {lk["name"]: lk for lk in links}
        assert listed[f"pinger.input~ros2:{topic}/in"]["dropped"] == 0
    finally:
        assert stop_process(proc) == 0


def test_the_youbot_ros2_composite_speaks_joint_states_and_takes_period_and_pose(
        on_domain: int, stream_peer) -> None:
    ns = f"127.0.0.1:{free_port()}"
    demo = Demo("youbot-ros2.composite", ns)
    try:
        demo.wait_line("scart: started")
        reader = stream_peer("read", "/joint_states", "JointState")
        first = reader.next_event("sample")
        assert first["name"] == [f"arm_joint_{i}" for i in range(1, 6)]
        assert len(first["position"]) == len(first["velocity"]) == len(first["effort"]) == 5
        assert first["sec"] > 1_600_000_000  # the sample's own time, not zero

        stream_peer("write", "/youbot/period", "Float64", [0.05]).next_event("acked")
        wait_until(lambda: "0.05" in scart("prop", "get", "youBotDriver", "accepted_period", "--ns", ns,
                                           domain=on_domain).stdout, timeout=15, message="the period never changed")

        stream_peer("write", "/youbot/pose", "Float64MultiArray", [[0.5, 0.2, -0.3, 0.1, 0.0]]).next_event("acked")

        def moved() -> bool:
            return reader.next_event("sample")["position"][0] > 0.1
        wait_until(moved, timeout=30, message="joint 1 never moved toward the pose sent")

        reset = scart("call", "ros2:/youbot/reset", "--type", "std_srvs/srv/Empty", domain=on_domain)
        assert reset.returncode == 0, reset.stderr  # the driver's reset operation, as a ROS 2 service
        wait_until(lambda: abs(reader.next_event("sample")["position"][0]) < 0.05, timeout=30,
                   message="joint 1 never went back to the candle pose after the reset")
    finally:
        assert demo.stop() == 0, demo.output()


def test_a_deployed_node_is_named_in_the_graph_serves_its_parameters_and_logs(on_domain: int, topic: str,
                                                                               peer) -> None:
    from scart_ros2 import Participant, QoS

    graph = peer("graph")
    ns = f"127.0.0.1:{free_port()}"
    proc, _ = start_scart(["deploy", "support.remote:Pinger", "--period", "0.01", "--listen", ns,
                           "--ros-name", "pinger_node", "--ros-namespace", "/robot"])
    try:
        assert scart("stream", "pinger.output", f"ros2:{topic}/out", "--ns", ns, domain=on_domain).returncode == 0
        for _ in range(500):  # ros_discovery_info as rmw_dds_common writes it (each event within a deadline)
            nodes = graph.next_event("participant")["nodes"]
            if any(n["name"] == "pinger_node" and len(n["writers"]) >= 2 for n in nodes):  # the stream's, /rosout's
                break
        assert next(n for n in nodes if n["name"] == "pinger_node")["namespace"] == "/robot"
        with Participant(on_domain) as ros:
            logged: list = []
            ros.subscribe("/rosout", "rcl_interfaces/msg/Log", logged.append,
                          QoS.buffer(100, latching=True))

            def call(service: str, kind: str, request: dict):  # the first calls wait for DDS discovery
                client = ros.client(f"/robot/pinger_node/{service}", f"rcl_interfaces/srv/{kind}")
                return wait_until(lambda: _answer(client, request), timeout=20, message=f"{service} never answered")

            listed = call("list_parameters", "ListParameters", {"prefixes": [], "depth": 0}).result.names
            assert {"pinger.gain", "pinger.label", "use_sim_time"} <= set(listed), listed
            value = call("get_parameters", "GetParameters", {"names": ["pinger.gain", "nobody"]}).values
            assert (value[0].type, value[0].double_value, value[1].type) == (3, 1.0, 0)
            described = call("describe_parameters", "DescribeParameters", {"names": ["pinger.gain"]}).descriptors[0]
            assert (described.type, described.description) == (3, "multiplier")

            def set_gain(number: float):
                return call("set_parameters", "SetParameters", {"parameters": [
                    {"name": "pinger.gain", "value": {"type": 3, "double_value": number}}]}).results[0]

            assert set_gain(2.5).successful
            assert scart("prop", "get", "pinger", "gain", "--ns", ns, domain=on_domain).stdout.strip() == "2.5"
            refused = set_gain(float("inf"))
            assert not refused.successful and "finite" in refused.reason
            assert scart("prop", "get", "pinger", "gain", "--ns", ns, domain=on_domain).stdout.strip() == "2.5"
            wait_until(lambda: any("refused" in m.msg for m in logged), timeout=15, message=f"{logged}")
            record = next(m for m in logged if "refused" in m.msg)
            assert record.name == "robot.pinger_node" and record.level == 30 and "pinger.gain" in record.msg
    finally:
        assert stop_process(proc) == 0


def test_a_type_of_an_installed_package_is_found_through_ament_prefix_path(
        on_domain: int, topic: str, tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    from support.ros2 import cli_read

    share = tmp_path / "install" / "share" / "lab_msgs" / "msg"  # as colcon installs a package
    share.mkdir(parents=True)
    (share / "Count.msg").write_text("int64 data\nUnit unit  # a type of the same package, found too\n")
    (share / "Unit.msg").write_text("string name\n")
    monkeypatch.setenv("AMENT_PREFIX_PATH", f"{tmp_path / 'nothing'}{os.pathsep}{tmp_path / 'install'}")
    ns = f"127.0.0.1:{free_port()}"
    proc, _ = start_scart(["deploy", "support.remote:Pinger", "--period", "0.01", "--listen", ns])
    try:
        made = scart("stream", "pinger.ticks", f"ros2:{topic}", "--type", "lab_msgs/msg/Count", "--ns", ns,
                     domain=on_domain)
        assert made.returncode == 0, made.stderr
        out = cli_read(on_domain, "rt" + topic, until="Count_(data=")  # the tool learns the type from DDS
        assert "unit=Unit_(name='')" in out, out
    finally:
        assert stop_process(proc) == 0


def _answer(client, request: dict):
    try:
        return client.call(request, timeout=1.0)
    except TimeoutError:
        return None
