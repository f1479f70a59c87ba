"""The youBot demo in ROS's tools (``youbot-ros1.composite``), as its README shows it:
``scart run`` against a real ``rosmaster --core``, then ``rostopic echo /joint_states``,
``rostopic pub`` of the period and of a pose, and ``rosservice call /youbot/reset``."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import wait_until
from support.ros1 import RosMaster, needs_ros, rosmaster
from support.youbot import ROOT, Demo, env, ns_address

pytestmark = [pytest.mark.integration, pytest.mark.subprocess, needs_ros]


@pytest.fixture
def demo(tmp_path: Path) -> Iterator[tuple[Demo, RosMaster]]:
    with rosmaster(tmp_path) as ros:
        running = Demo("youbot-ros1.composite", ns_address(), "--ros-master", ros.uri)
        try:
            running.wait_line("scart: started", 60)
            yield running, ros
        finally:
            code = running.stop()
            assert code == 0, running.output()
            assert "Traceback" not in running.output()


def _scart(ns: str, *args: str) -> str:
    done = subprocess.run([sys.executable, "-m", "scart", *args, "--ns", ns], capture_output=True, text=True,
                          env=env(), cwd=ROOT, timeout=30)
    assert done.returncode == 0, (args, done.stdout, done.stderr)
    return done.stdout


def _positions(ros: RosMaster) -> list[float]:
    done = ros.tool("rostopic", "echo", "-n", "1", "/joint_states", timeout=60)
    assert done.returncode == 0, done.stderr
    return [float(x) for x in re.search(r"position: \[([^\]]*)\]", done.stdout).group(1).split(",")]


def test_joint_states_period_and_pose_through_ros_tools(demo: tuple[Demo, RosMaster]) -> None:
    running, ros = demo
    echo = ros.tool("rostopic", "echo", "-n", "1", "/joint_states", timeout=60)
    assert echo.returncode == 0, echo.stderr
    text = echo.stdout
    assert "name: \n  - arm_joint_1\n  - arm_joint_2\n  - arm_joint_3\n  - arm_joint_4\n  - arm_joint_5" in text
    for field in ("position", "velocity", "effort"):
        assert len(re.search(rf"{field}: \[([^\]]*)\]", text).group(1).split(",")) == 5, text
    secs = int(re.search(r"secs: (\d+)", text).group(1))
    assert abs(secs - time.time()) < 60, text  # stamped with the sample's own time
    assert int(re.search(r"seq: (\d+)", text).group(1)) > 0

    done = ros.tool("rostopic", "pub", "-1", "/youbot/period", "std_msgs/Float64", "0.05", timeout=60)
    assert done.returncode == 0, done.stderr
    wait_until(lambda: json.loads(_scart(running.ns, "prop", "get", "youBotDriver", "accepted_period", "--json"))
               == 0.05, timeout=10, message="the period from ROS never reached the driver")

    done = ros.tool("rostopic", "pub", "-1", "/youbot/pose", "std_msgs/Float64MultiArray",
                    "{data: [0.5, 0.2, -0.3, 0.1, 0.0]}", timeout=60)
    assert done.returncode == 0, done.stderr
    wait_until(lambda: abs(_positions(ros)[0] - 0.5) < 0.05, timeout=30, interval=0.2,
               message="the arm never reached the pose sent over ROS")

    reset = ros.tool("rosservice", "call", "/youbot/reset", timeout=60)
    assert reset.returncode == 0, reset.stderr
    wait_until(lambda: abs(_positions(ros)[0]) < 0.05, timeout=30, interval=0.2, message="reset did not home")
    assert json.loads(_scart(running.ns, "call", "ros1:/youbot/reset", "--ros-master", ros.uri)) == {}
    described = _scart(running.ns, "describe", "youBotDriver")
    assert "ros1:/youbot/pose (std_msgs/Float64MultiArray), connected, UNAUTHENTICATED" in described


def test_a_named_remapped_node_with_launch_parameters_ends_on_rosnode_kill(tmp_path: Path) -> None:
    with rosmaster(tmp_path) as ros:
        running = Demo("youbot-ros1.composite", ns_address(), "--ros-master", ros.uri, "--ros-name", "youbot",
                       "--remap", "/joint_states:=/js", "_youBotDriver/max_velocity:=0.5")
        try:
            running.wait_line("scart: started", 60)
            echo = ros.tool("rostopic", "echo", "-n", "1", "/js", timeout=60)  # /joint_states, remapped at launch
            assert echo.returncode == 0 and "arm_joint_1" in echo.stdout, echo.stderr
            wait_until(lambda: ros.tool("rosparam", "get", "/youbot/youBotDriver/max_velocity").stdout.strip()
                       == "0.5", timeout=20, message="the launch-time parameter never reached the server")
            killed = ros.tool("rosnode", "kill", "/youbot")
            assert killed.returncode == 0, killed.stderr
            assert running.proc.wait(30) == 0
        finally:
            code = running.stop()
        out = running.output()
        assert code == 0 and "scart: the ROS node /youbot was shut down by /rosnode (user request): stopping" in out
        assert "scart: stopped" in out and "Traceback" not in out
