"""The ros1 transport as a user drives it from a shell: ``scart deploy --ros-master``,
then ``scart stream COMP.PORT ros1:/topic --type T`` against it, ROS's tools on the other
side, ``scart links`` / ``scart describe`` showing what crossed and what was refused, and
``scart call ros1:/service`` calling a rospy node's service."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import free_port, wait_until
from support.remote import start_scart, stop_process, subprocess_env
from support.ros1 import RosMaster, needs_ros, require_rospy, running

pytestmark = [pytest.mark.integration, pytest.mark.subprocess, needs_ros]


def scart(*args: str, ns: str | None = None, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    extra = ["--ns", ns] if ns else []
    return subprocess.run([sys.executable, "-m", "scart", *args, *extra], capture_output=True, text=True, timeout=60,
                          env=env or subprocess_env())


@pytest.fixture
def deployed(ros: RosMaster) -> Iterator[str]:
    """A Gauge served by ``scart deploy`` speaking ROS as ``/scart_cli``; its name service."""
    ns = f"127.0.0.1:{free_port()}"
    proc, _ = start_scart(["deploy", "support.ros1_tasks:Gauge", "--period", "0.02", "--ns", ns,
                           "--ros-master", ros.uri, "--ros-name", "scart_cli"])
    try:
        yield ns
    finally:
        assert stop_process(proc) == 0


def links(ns: str) -> dict[str, dict]:
    done = scart("links", "--json", ns=ns)
    assert done.returncode == 0, done.stderr
    return {row["name"]: row for row in json.loads(done.stdout)}


def test_scart_stream_against_a_deployer_speaks_ros(ros: RosMaster, deployed: str) -> None:
    ns = deployed
    made = scart("stream", "gauge.count", "ros1:/cli/count", "--type", "std_msgs/Int64", ns=ns)
    assert made.returncode == 0, made.stderr
    assert made.stdout.startswith("streaming gauge.count -> ros1:/cli/count (data) as gauge.count~ros1:/cli/count")
    made = scart("stream", "gauge.level", "ros1:/cli/level", "--policy", "buffer:10", "--name", "level-in", ns=ns)
    assert made.returncode == 0, made.stderr
    wait_until(lambda: all(row["state"] == "connected" for row in links(ns).values()), timeout=20,
               message=f"{links(ns)}")
    echo = ros.tool("rostopic", "echo", "-n", "1", "/cli/count", timeout=60)
    assert echo.returncode == 0 and re.search(r"data: \d+", echo.stdout), echo.stderr
    for value in ("data: 0.5", "data: 7.0"):  # 7: beyond the port's bounds
        done = ros.tool("rostopic", "pub", "-1", "/cli/level", "std_msgs/Float64", value, timeout=60)
        assert done.returncode == 0, done.stderr
    wait_until(lambda: links(ns)["level-in"]["samples"] == 2, timeout=10, message=f"{links(ns)}")
    seen = scart("call", "gauge.seen", ns=ns)
    assert json.loads(seen.stdout) == [0.5], seen.stderr
    assert links(ns)["level-in"]["dropped"] == 1
    described = scart("describe", "gauge", ns=ns)
    assert described.returncode == 0, described.stderr
    line = next(x for x in described.stdout.splitlines() if "stream level-in" in x)
    assert "ros1:/cli/level (std_msgs/Float64), connected, UNAUTHENTICATED" in line
    assert "1 refused, last: gauge.level: 7.0 refused" in line
    info = ros.tool("rosnode", "info", "/scart_cli")
    assert " * /cli/count [std_msgs/Int64]" in info.stdout, info.stdout


def test_scart_stream_is_refused_when_the_types_do_not_map(deployed: str) -> None:
    done = scart("stream", "gauge.level", "ros1:/cli/bad", "--type", "sensor_msgs/JointState", ns=deployed)
    assert done.returncode == 1
    assert "ros1 into port gauge.level (float64)" in done.stderr and "sensor_msgs/JointState" in done.stderr
    assert "Traceback" not in done.stderr
    assert links(deployed) == {}


def test_scart_call_calls_a_rospy_nodes_service(ros: RosMaster) -> None:
    require_rospy()
    peer = ros.rospy("serve", "/rospy/get_loggers")
    with running(peer):
        peer.read_until("ready", timeout=60)
        asked = scart("call", "ros1:/rospy/get_loggers", "--ros-master", ros.uri)
        typed = scart("call", "ros1:/rospy/get_loggers", "{}", "--type", "roscpp/GetLoggers", env=subprocess_env() | {"ROS_MASTER_URI": ros.uri})
    for done in (asked, typed):
        assert done.returncode == 0, done.stderr
        assert json.loads(done.stdout) == {"loggers": [{"name": "scart.test", "level": "info"}]}
    missing = scart("call", "ros1:/nobody/here", "--ros-master", ros.uri)
    assert missing.returncode == 1 and "/nobody/here" in missing.stderr and "Traceback" not in missing.stderr


def test_scart_call_takes_a_custom_service_type_from_msgs(ros: RosMaster, tmp_path: Path) -> None:
    from scart_ros1 import MessageTypes, Node

    srv_file = tmp_path / "my_msgs" / "srv" / "AddTwo.srv"
    srv_file.parent.mkdir(parents=True)
    srv_file.write_text("int64 a\nint64 b\n---\nint64 sum\n")
    types = MessageTypes(files=[srv_file])
    add = types.srv("my_msgs/AddTwo")
    with Node("adder", master_uri=ros.uri, types=types) as node:
        node.advertise_service("/adder/add", "my_msgs/AddTwo", lambda req: add.response.new(sum=req.a + req.b))
        assert node.wait_registered(10)
        done = scart("call", "ros1:/adder/add", "{a: 2, b: 40}", "--msgs", str(srv_file), "--ros-master", ros.uri)
        assert done.returncode == 0 and json.loads(done.stdout) == {"sum": 42}, done.stderr
        unknown = scart("call", "ros1:/adder/add", "{a: 2, b: 40}", "--ros-master", ros.uri)
        assert unknown.returncode == 1 and "my_msgs/AddTwo" in unknown.stderr and "Traceback" not in unknown.stderr
