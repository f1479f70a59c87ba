"""The ROS–YARP bridge (``composites/yarp-ros/``) with both sides real, as its README shows
it: ``scart run`` beside a ``yarpserver`` and a ``rosmaster --core``; ``yarp write`` in,
``rostopic echo`` out; ``rostopic pub`` in, ``yarp read`` out; and a builder of the wrong
type refused at load, at its line."""

from __future__ import annotations

import math
import re
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import ROOT, wait_until
from support.ros1 import Proc, RosMaster, needs_ros, rosmaster, running
from support.youbot import Demo, ns_address
from support.yarp import YarpServer, yarpserver

from scart.cli import main

pytestmark = [pytest.mark.integration, pytest.mark.subprocess, needs_ros]

FOLDER = ROOT / "composites" / "yarp-ros"


@pytest.fixture
def peers(tmp_path: Path) -> Iterator[tuple[YarpServer, RosMaster]]:
    with yarpserver(tmp_path / "yarp") as yarp, rosmaster(tmp_path / "ros") as ros:
        yield yarp, ros


def test_yarp_write_reaches_rostopic_echo_and_rostopic_pub_reaches_yarp_read(
        peers: tuple[YarpServer, RosMaster]) -> None:
    yarp, ros = peers
    head = yarp.spawn("write", "/icub/head/state:o")  # the robot's port, before or after scart: it is kept
    target = yarp.spawn("read", "/icub/head/target:i")
    bridge = Demo(str(FOLDER / "yarp-ros.composite"), ns_address(), "--yarp-server", yarp.address,
                  "--ros-master", ros.uri)
    try:
        bridge.wait_line("scart: started", 60)
        target.read_until("Receiving input from /scart/head/target:o", timeout=30)  # scart connected to it
        connected = 'There is an output connection from "/icub/head/state:o" to "/scart/head/state:i"'
        wait_until(lambda: connected in yarp.tool("ping", "/icub/head/state:o").stdout, timeout=30, interval=0.2,
                   message="the head's port was never asked to write to scart's")
        echo = ros.spawn("rostopic", "echo", "-n", "1", "/joint_states")
        with running(echo):
            text = _written_until_echoed(head, echo)
        assert "neck_pitch" in text and "eyes_vergence" in text, text
        positions = [float(x) for x in re.search(r"position: \[([^\]]*)\]", text).group(1).split(",")]
        assert positions == pytest.approx([math.radians(a) for a in (10, 0, -5, 0, 0, 2)])
        pub = ros.tool("rostopic", "pub", "-1", "/head/target", "std_msgs/Float64MultiArray",
                       "{data: [0.1, 0.0, -0.2, 0.0, 0.0, 0.0]}", timeout=60)
        assert pub.returncode == 0, pub.stderr
        line = target.read_until("5.7", timeout=30).splitlines()[-1]
        degrees = [float(x) for x in line.split()]
        assert degrees == pytest.approx([math.degrees(a) for a in (0.1, 0.0, -0.2, 0.0, 0.0, 0.0)])
    finally:
        code = bridge.stop()
        head.stop()
        target.stop()
    assert code == 0, bridge.output()
    assert "Traceback" not in bridge.output()
    assert not yarp.registered("/scart/head/state:i")  # withdrawn at the stop


def _written_until_echoed(head: Proc, echo: Proc) -> str:
    """Write the head's encoders until ``rostopic echo`` (subscribing meanwhile) prints one."""
    assert head.proc.stdin is not None
    for _ in range(150):  # bounded: 150 × 0.2 s
        head.proc.stdin.write(b"10 0 -5 0 0 2\n")
        head.proc.stdin.flush()
        try:
            return echo.read_until("effort", timeout=0.2)
        except AssertionError:
            continue
    raise AssertionError(f"rostopic echo printed nothing: {echo.text()}")


def test_a_builder_of_the_wrong_type_is_refused_at_its_line(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "yarp-ros"
    shutil.copytree(FOLDER, folder)
    (folder / "head.py").write_text((FOLDER / "head.py").read_text(encoding="utf-8") +
                                    "\n\ndef from_int(encoders: int) -> JointState:\n    return JointState()\n",
                                    encoding="utf-8")
    composite = folder / "yarp-ros.composite"
    text = composite.read_text(encoding="utf-8").replace('build="head:joint_state"', 'build="head:from_int"')
    composite.write_text(text, encoding="utf-8")
    assert main(["validate", str(composite)]) == 2
    err = capsys.readouterr().err
    line = next(i for i, row in enumerate(text.splitlines(), 1) if 'name="headState"' in row)
    assert f"yarp-ros.composite:{line}: " in err and "[SCART-B002]" in err, err
    assert "builder head:from_int parameter 'encoders' is int, but input 'encoders' gives list[float]" in err
