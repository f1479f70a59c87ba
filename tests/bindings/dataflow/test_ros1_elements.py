"""``<scart:stream transport="ros1">`` and ``<scart:rosservice>`` in a composite: the types
checked at load with file:line and a SCART code (a port's type against the topic's, a
converter's annotations, request fields against an operation's parameters), then — with
a real ``rosmaster`` — a composite whose stream publishes by a converter and whose SCA
service answers ``rosservice call``."""

from __future__ import annotations

from pathlib import Path

import pytest
from support import wait_until
from support.ros1 import needs_ros, rosmaster
from support.sca import composite, line_of, write

import scart
from scart.cli import main

MODS = '''
from __future__ import annotations

from typing import Protocol

from pydantic import BaseModel

import scart
from dataflow import InputPort, OutputPort, TaskContext, operation


class Pose(BaseModel):
    x: float
    y: float
    theta: float


class Rover(TaskContext):
    pose = OutputPort(Pose)
    speed = InputPort(float, ge=0.0, le=2.0)
    label = OutputPort(str)

    @operation
    def brake(self, why: str) -> None:
        pass

    @operation
    def halt(self) -> None:
        pass


def pose_to_pose2d(pose: Pose) -> dict:
    return {"x": pose.x, "y": pose.y, "theta": pose.theta}


def wrong_side(pose: int) -> dict:
    return {}


def untyped(pose):
    return {"x": pose.x}


@scart.interface
class Logging(Protocol):
    def set_logger_level(self, logger: str, level: str) -> None: ...
    def count(self) -> int: ...


@scart.component(services=[Logging])
class LogService:
    def __init__(self) -> None:
        self.levels: list[tuple[str, str]] = []

    def set_logger_level(self, logger: str, level: str) -> None:
        self.levels.append((logger, level))

    def count(self) -> int:
        return len(self.levels)
'''

ROVER = '''
<component name="rover">
    <scart:implementation.task class="rosmods:Rover"/>
</component>
<component name="logs">
    <scart:implementation.python class="rosmods:LogService"/>
</component>
'''


def validate(tmp_path: Path, body: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    text = composite(ROVER + body)
    path = write(tmp_path, {"r.composite": text, "rosmods.py": MODS}, with_components=False)
    code = main(["validate", str(path)])
    return code, capsys.readouterr().err, text


def test_a_ros1_composite_that_maps_loads(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err, _ = validate(tmp_path, '''
        <scart:stream port="rover.pose" transport="ros1" topic="/pose" type="geometry_msgs/Pose2D"/>
        <scart:stream port="rover.pose" transport="ros1" topic="/pose2" type="geometry_msgs/Pose2D"
                      converter="rosmods:pose_to_pose2d" name="by-converter"/>
        <scart:stream port="rover.speed" transport="ros1" topic="/speed"/>
        <scart:stream port="rover.label" transport="ros1" topic="/label" latch="true"/>
        <scart:rosservice service="/rover/halt" type="std_srvs/Trigger" operation="rover.halt"/>
        <scart:rosservice service="/logs/level" type="roscpp/SetLoggerLevel"
                          target="logs/Logging.set_logger_level"/>
    ''', capsys)
    assert code == 0, err


@pytest.mark.parametrize(("element", "code", "words"), [
    ('<scart:stream port="rover.pose" transport="ros1" topic="/p" type="sensor_msgs/JointState"/>', "SCART-T006",
     "Pose's x, y, theta have no field in sensor_msgs/JointState"),
    ('<scart:stream port="rover.speed" transport="ros1" topic="/s" type="std_msgs/String"/>', "SCART-T006",
     "port type float vs std_msgs/String.data: float and string"),
    ('<scart:stream port="rover.pose" transport="ros1" topic="/p" type="geometry_msgs/Pose2D" '
     'converter="rosmods:wrong_side"/>', "SCART-T006", "converter rosmods:wrong_side takes int; the port gives Pose"),
    ('<scart:stream port="rover.pose" transport="ros1" topic="/p" type="geometry_msgs/Pose2D" '
     'converter="rosmods:nowhere"/>', "SCART-T006", "converter='rosmods:nowhere' cannot be imported"),
    ('<scart:stream port="rover.pose" transport="ros1" topic="/p"/>', "SCART-T006", "has no default ROS type"),
    ('<scart:stream port="rover.speed" transport="ros1" topic="/s" queue_size="0"/>', "SCART-T005",
     "queue_size='0'"),
    ('<scart:stream port="rover.speed" transport="ros1" topic="/s" insecure="maybe"/>', "SCART-T005",
     "insecure='maybe': expected true or false"),
    ('<scart:rosservice service="/stop" type="std_srvs/SetBool" operation="rover.brake"/>', "SCART-T007",
     "parameter why (str) vs std_srvs/SetBoolRequest.data: str and bool"),
    ('<scart:rosservice service="/count" type="roscpp/SetLoggerLevel" target="logs/Logging.count"/>', "SCART-T007",
     "roscpp/SetLoggerLevelRequest field(s) logger, level match no parameter"),
    ('<scart:rosservice service="/x" type="std_srvs/Trigger" target="logs/Nope.count"/>', "SCART-T007",
     "'logs' has no service 'Nope'"),
    ('<scart:rosservice service="/x" type="std_srvs/Nope" operation="rover.brake"/>', "SCART-T007",
     "unknown ROS 1 service type 'std_srvs/Nope'"),
], ids=["fields", "plain", "converter-annotation", "converter-missing", "no-type", "option", "flag",
        "request-fields", "sca-request", "sca-service", "srv-type"])
def test_what_does_not_map_is_refused_at_load_with_file_line_and_code(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], element: str, code: str, words: str) -> None:
    status, err, text = validate(tmp_path, element + "<!--HERE-->", capsys)
    assert status == 2, err
    line = line_of(text, "<!--HERE-->")
    assert f"r.composite:{line}: " in err and f"[{code}]" in err and words in err, err


def test_a_converter_without_annotations_is_a_warning(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err, _ = validate(tmp_path, '<scart:stream port="rover.pose" transport="ros1" topic="/p" '
                                      'type="geometry_msgs/Pose2D" converter="rosmods:untyped"/>', capsys)
    assert code == 0
    assert "warning: " in err and "converter rosmods:untyped has no type annotations" in err, err


@pytest.mark.integration
@needs_ros
def test_a_composite_streams_and_answers_rosservice_call(tmp_path: Path) -> None:
    with rosmaster(tmp_path / "ros") as ros:
        body = f'''
            <scart:stream port="rover.pose" transport="ros1" topic="/rover/pose" type="geometry_msgs/Pose2D"
                          converter="rosmods:pose_to_pose2d" latch="true" master="{ros.uri}" node="scart_rover"/>
            <scart:rosservice service="/logs/level" type="roscpp/SetLoggerLevel"
                              target="logs/Logging.set_logger_level" master="{ros.uri}" node="scart_rover"/>
        '''
        path = write(tmp_path, {"r.composite": composite(ROVER + body), "rosmods.py": MODS}, with_components=False)
        with scart.Runtime.from_file(str(path)) as rt:
            from scart.bindings.dataflow import deployer_of

            rover = deployer_of(rt).task("rover")
            rover.pose.write(rover.pose.type(x=1.5, y=-2.0, theta=0.25))
            echo = ros.tool("rostopic", "echo", "-n", "1", "/rover/pose", timeout=60)
            assert echo.returncode == 0 and "x: 1.5\ny: -2.0\ntheta: 0.25" in echo.stdout, echo.stderr
            done = wait_until(lambda: (d := ros.tool("rosservice", "call", "/logs/level", "rover", "debug",
                                                    timeout=60)).returncode == 0 and d, timeout=30, interval=0.2)
            assert done.stdout.strip() == ""
            assert rt.service("logs/Logging").count() == 1
