"""A port's type onto a ROS 1 message type and back (:mod:`dataflow.transports.ros1.convert`),
without a master: what is planned, what is refused when planned (naming both types and
the fields), what a sample that does not fit raises, and the ROS 1 bytes made."""

from __future__ import annotations

import sys
import types
from typing import Any

import pytest
from pydantic import BaseModel

from scart_ros1 import MessageTypes
from dataflow.transports.ros1.convert import default_type, plan


@pytest.fixture(scope="module")
def ros_types() -> MessageTypes:
    return MessageTypes()


class Joints(BaseModel):
    name: list[str]
    position: list[float]
    velocity: list[float] = []


class Stamped(BaseModel):
    stamp: float
    frame_id: str = ""


class Point(BaseModel):
    x: float
    y: float
    z: float = 0.0


class Pose(BaseModel):
    position: Point
    orientation: dict[str, float]


def out(ros_types: MessageTypes, py_type: Any, ros_type: str | None = None, **kw: str) -> Any:
    conv, problems = plan(ros_types, py_type, ros_type, outgoing=True, **kw)
    assert conv is not None and not [p for p in problems if not p.warning], problems
    return conv


def into(ros_types: MessageTypes, py_type: Any, ros_type: str | None = None, **kw: str) -> Any:
    conv, problems = plan(ros_types, py_type, ros_type, outgoing=False, **kw)
    assert conv is not None and not [p for p in problems if not p.warning], problems
    return conv


def refusal(ros_types: MessageTypes, py_type: Any, ros_type: str | None, outgoing: bool, **kw: str) -> str:
    conv, problems = plan(ros_types, py_type, ros_type, outgoing=outgoing, **kw)
    assert conv is None and problems
    return "; ".join(p.message for p in problems)


@pytest.mark.parametrize(("py_type", "ros_type"), [
    (float, "std_msgs/Float64"), (int, "std_msgs/Int64"), (bool, "std_msgs/Bool"), (str, "std_msgs/String"),
    (list[float], "std_msgs/Float64MultiArray"), (list[int], "std_msgs/Int64MultiArray"),
])
def test_a_plain_type_maps_onto_its_std_msgs_type_both_ways(ros_types: MessageTypes, py_type: Any,
                                                            ros_type: str) -> None:
    assert default_type(py_type) == ros_type
    value = {float: 2.5, int: -7, bool: True, str: "hello", list[float]: [0.5, -1.0], list[int]: [1, 2]}[py_type]
    conv = out(ros_types, py_type)
    assert (conv.ros_type, conv.via) == (ros_type, "data field")
    msgtype = ros_types.msg(ros_type)
    wire = msgtype.serialize(conv.to_ros(value, 1, 0))
    assert into(ros_types, py_type).from_ros(msgtype.deserialize(wire)) == value


def test_float64_wire_bytes_are_ros_ones(ros_types: MessageTypes) -> None:
    msg = out(ros_types, float).to_ros(1.5, 1, 0)
    assert ros_types.msg("std_msgs/Float64").serialize(msg) == b"\x00\x00\x00\x00\x00\x00\xf8?"


def test_numbers_widen_but_never_narrow(ros_types: MessageTypes) -> None:
    assert into(ros_types, float, "std_msgs/Int32").from_ros(ros_types.msg("std_msgs/Int32").new(data=3)) == 3.0
    out(ros_types, int, "std_msgs/Float32")  # an int into a float32 field
    assert "float and int64" in refusal(ros_types, float, "std_msgs/Int64", outgoing=True)
    assert "float64" in refusal(ros_types, int, "std_msgs/Float64", outgoing=False)


def test_a_model_maps_by_field_names_and_a_header_is_stamped(ros_types: MessageTypes) -> None:
    conv = out(ros_types, Joints, "sensor_msgs/JointState", frame_id="arm")
    msg: Any = conv.to_ros(Joints(name=["a1"], position=[0.25]), 42, 1_700_000_000_250_000_000)
    assert (msg.header.seq, msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == \
        (42, 1_700_000_000, 250_000_000, "arm")
    assert list(msg.name) == ["a1"] and list(msg.position) == [0.25] and list(msg.effort) == []
    back = into(ros_types, Joints, "sensor_msgs/JointState").from_ros(msg)
    assert Joints.model_validate(back) == Joints(name=["a1"], position=[0.25])


def test_nested_models_and_time_as_seconds(ros_types: MessageTypes) -> None:
    ros_types.add_msg("scart_test/Sample", "time stamp\nstring frame_id\n")
    conv = out(ros_types, Stamped, "scart_test/Sample")
    msg: Any = conv.to_ros(Stamped(stamp=12.5, frame_id="map"), 1, 0)
    assert (msg.stamp.sec, msg.stamp.nanosec) == (12, 500_000_000)
    assert into(ros_types, Stamped, "scart_test/Sample").from_ros(msg) == {"stamp": 12.5, "frame_id": "map"}
    pose = into(ros_types, Pose, "geometry_msgs/Pose").from_ros(
        ros_types.msg("geometry_msgs/Pose").new(position={"x": 1.0, "y": 2.0}, orientation={"w": 1.0}))
    assert Pose.model_validate(pose).position == Point(x=1.0, y=2.0)
    assert pose["orientation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


def test_fields_that_do_not_map_are_named(ros_types: MessageTypes) -> None:
    text = refusal(ros_types, Point, "sensor_msgs/JointState", outgoing=True)
    assert "Point's x, y, z have no field in sensor_msgs/JointState (its fields: header, name, position" in text
    assert text.endswith("give a converter")
    # reading, a field the model does not require may be missing from the message
    into(ros_types, Joints, "sensor_msgs/JointState")
    assert "has no default ROS type" in refusal(ros_types, Point, None, outgoing=True)
    assert "unknown ROS 1 message type 'nope_msgs/Nope'" in refusal(ros_types, float, "nope_msgs/Nope", outgoing=True)


def test_a_sample_that_does_not_fit_raises(ros_types: MessageTypes) -> None:
    small = out(ros_types, int, "std_msgs/Int8")
    with pytest.raises(Exception):  # noqa: B017,PT011 - struct.error or ValueError: the stream counts either
        ros_types.msg("std_msgs/Int8").frame(small.to_ros(300, 1, 0))
    ros_types.add_msg("scart_test/Three", "float64[3] v\n")

    class Three(BaseModel):
        v: list[float]

    with pytest.raises(ValueError, match=r"2 values for a float64\[3\]"):
        out(ros_types, Three, "scart_test/Three").to_ros(Three(v=[1.0, 2.0]), 1, 0)


@pytest.fixture
def converters() -> Any:
    module = types.ModuleType("scart_test_converters")
    code = '''
def to_point(p: float) -> dict:
    return {"x": p, "y": -p}

def from_point(msg) -> float:
    return msg.x + msg.y

def takes_str(p: str) -> dict:
    return {}

def returns_int(msg) -> int:
    return 1

def two(a, b):
    return a
'''
    exec(compile(code, "scart_test_converters.py", "exec"), module.__dict__)  # noqa: S102 - the test's own text
    sys.modules[module.__name__] = module
    try:
        yield module
    finally:
        del sys.modules[module.__name__]


def test_a_converter_both_ways_and_its_annotations_checked(ros_types: MessageTypes, converters: Any) -> None:
    name = converters.__name__
    conv = out(ros_types, float, "geometry_msgs/Point", converter=f"{name}:to_point")
    msg: Any = conv.to_ros(2.0, 1, 0)
    assert (msg.x, msg.y, msg.z) == (2.0, -2.0, 0.0) and conv.via == f"converter {name}:to_point"
    assert into(ros_types, float, "geometry_msgs/Point", converter=f"{name}:from_point").from_ros(msg) == 0.0
    assert "takes str; the port gives float" in refusal(ros_types, float, "geometry_msgs/Point", True,
                                                        converter=f"{name}:takes_str")
    assert "returns int; the port takes str" in refusal(ros_types, str, "geometry_msgs/Point", False,
                                                        converter=f"{name}:returns_int")
    assert "cannot be called with one argument" in refusal(ros_types, float, "geometry_msgs/Point", True,
                                                           converter=f"{name}:two")
    assert "has no 'nope'" in refusal(ros_types, float, "geometry_msgs/Point", True, converter=f"{name}:nope")


def test_a_converter_module_is_never_imported_by_a_stream(ros_types: MessageTypes) -> None:
    assert "not imported in this process" in refusal(ros_types, float, "geometry_msgs/Point", True,
                                                     converter="scart_never_made_module:fn")
    assert "scart_never_made_module" not in sys.modules


@pytest.mark.parametrize(("py_type", "ros_type", "value"), [
    (float, "std_msgs/Float64", -2.5), (float, "std_msgs/Float32", 0.5), (int, "std_msgs/Int64", -(2**40)),
    (int, "std_msgs/UInt8", 200), (bool, "std_msgs/Bool", True), (str, "std_msgs/String", "grüß dich"),
    (float, "std_msgs/Int32", 7.0),
])
def test_one_field_messages_go_straight_to_and_from_ros_bytes(ros_types: MessageTypes, py_type: Any, ros_type: str,
                                                            value: Any) -> None:
    msgtype = ros_types.msg(ros_type)
    sent, read = plan(ros_types, py_type, ros_type, outgoing=True)[0], into(ros_types, py_type, ros_type)
    if sent is not None:  # a float port never publishes into an integer field
        assert sent.to_frame is not None
        assert sent.to_frame(value, 1, 0) == bytes(msgtype.frame(sent.to_ros(value, 1, 0)))
    wire = msgtype.serialize(msgtype.new(data=int(value) if ros_type == "std_msgs/Int32" else value))
    assert read.from_bytes is not None and read.from_bytes(wire) == value
    assert type(read.from_bytes(wire)) is py_type
    with pytest.raises(Exception):  # noqa: B017,PT011 - struct.error or ValueError: counted as refused
        read.from_bytes(wire + b"\0")
    assert into(ros_types, list[float]).from_bytes is None  # not one fixed field: rosbags' way
