"""scart's ROS 1 node as a citizen of a ROS system, judged by ROS's own tools against a
``scart deploy`` subprocess: ``rosnode kill`` ends it as rospy ends, saying who asked."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import free_port, wait_until
from support.remote import start_scart, stop_process, subprocess_env
from support.ros1 import RosMaster, needs_ros, rosmaster

pytestmark = [pytest.mark.integration, pytest.mark.subprocess, needs_ros]


@pytest.fixture
def ros(tmp_path: Path) -> Iterator[RosMaster]:
    with rosmaster(tmp_path) as master:
        yield master


def scart(*args: str, ns: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args, "--ns", ns], capture_output=True, text=True,
                          timeout=60, env=subprocess_env())


def deploy(ros: RosMaster, name: str, *extra: str) -> tuple[subprocess.Popen[str], str]:
    """``scart deploy`` of a Gauge as the ROS node ``/NAME``; (process, its name service)."""
    ns = f"127.0.0.1:{free_port()}"
    proc, _ = start_scart(["deploy", "support.ros1_tasks:Gauge", "--period", "0.05", "--ns", ns,
                           "--ros-master", ros.uri, "--ros-name", name, *extra])
    return proc, ns


def nodes(ros: RosMaster) -> list[str]:
    return ros.tool("rosnode", "list").stdout.split()


def test_rosnode_kill_ends_scart_deploy_saying_who_asked(ros: RosMaster) -> None:
    proc, ns = deploy(ros, "doomed")
    try:
        made = scart("stream", "gauge.count", "ros1:/doomed/count", ns=ns)
        assert made.returncode == 0, made.stderr
        wait_until(lambda: "/doomed" in nodes(ros), timeout=20)
        killed = ros.tool("rosnode", "kill", "/doomed")
        assert killed.returncode == 0, killed.stderr
        assert proc.wait(timeout=30) == 0
        said = proc.stderr.read() if proc.stderr else ""
        assert "the ROS node /doomed was shut down by /rosnode (user request): stopping" in said, said
        assert "/doomed" not in nodes(ros)  # everything it had registered is gone with it
    finally:
        stop_process(proc)
