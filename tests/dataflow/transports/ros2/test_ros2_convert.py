"""How the ``ros2`` transport maps a port's type onto a ROS 2 message, checked before any
stream is made (``check_stream``, what a composite's load asks) and applied per sample
without DDS: plain types onto ``data``, models by field names (a header stamped, Time as
seconds), converters by their annotations; what does not fit is said with both types."""

from __future__ import annotations

import math
from typing import Any

import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from pydantic import BaseModel  # noqa: E402

from dataflow import InputPort, OutputPort  # noqa: E402
from dataflow.transports.ros2 import Ros2Transport  # noqa: E402
from scart_ros2 import ConversionError  # noqa: E402

ROS2 = Ros2Transport()  # no participant is made by checks or conversions


class Point(BaseModel):
    x: float
    y: float
    z: float = 0.0


class Stamped(BaseModel):
    point: Point


class Pose2D(BaseModel):
    x: float
    y: float
    theta: float
    note: str = ""


class Header(BaseModel):
    stamp: float
    frame_id: str


def out(tp: Any) -> OutputPort:
    return OutputPort(tp, name="p")


def inp(tp: Any) -> InputPort:
    return InputPort(tp, name="p")


def convert(port: Any, options: dict[str, str]):
    conv, problems = ROS2.conversion(port, options)
    assert conv is not None, problems
    return conv


@pytest.mark.parametrize("tp, value, ros_type", [
    (float, 2.5, "std_msgs/msg/Float64"), (int, -7, "std_msgs/msg/Int64"), (bool, True, "std_msgs/msg/Bool"),
    (str, "hi", "std_msgs/msg/String"), (list[float], [0.5, 1.5], "std_msgs/msg/Float64MultiArray"),
    (list[int], [1, 2], "std_msgs/msg/Int64MultiArray"), (bytes, b"\x00\xff", "std_msgs/msg/UInt8MultiArray")])
def test_a_plain_type_maps_onto_its_std_msgs_type_and_back(tp: Any, value: Any, ros_type: str) -> None:
    assert ROS2.check_stream(out(tp), "/t", {}) == []
    sent = convert(out(tp), {})
    assert sent.ros_type == ros_type and sent.via == "data field"
    message = sent.to_idl(value, 0)
    assert type(message).__name__ == ros_type.rsplit("/", 1)[1] + "_"
    back = convert(inp(tp), {}).from_idl(type(message).deserialize(message.serialize()))
    assert back == value and type(back) is type(value)


def test_numbers_widen_and_never_narrow() -> None:
    assert ROS2.check_stream(out(int), "/t", {"type": "std_msgs/msg/Float32"}) == []
    assert ROS2.check_stream(inp(float), "/t", {"type": "std_msgs/msg/Int32"}) == []
    assert convert(inp(float), {"type": "std_msgs/msg/Int32"}).from_idl(
        convert(out(int), {"type": "std_msgs/msg/Int32"}).to_idl(3, 0)) == 3.0
    (problem,) = ROS2.check_stream(out(float), "/t", {"type": "std_msgs/msg/Int32"})
    assert problem.types and not problem.warning
    assert "from port p (float64)" in problem.message and "Int32.data: float and int32 (a float never narrows" \
        in problem.message
    (problem,) = ROS2.check_stream(inp(int), "/t", {"type": "std_msgs/msg/Float64"})
    assert "int and float64 (a float never narrows" in problem.message


def test_a_value_the_field_cannot_hold_refuses_that_sample() -> None:
    to_idl = convert(out(int), {"type": "std_msgs/msg/UInt8"}).to_idl
    assert to_idl(255, 0).data == 255
    with pytest.raises(ConversionError, match=r"300 is out of range \[0, 255\]"):
        to_idl(300, 0)
    nan = convert(out(float), {}).to_idl(math.nan, 0)  # NaN is a float64 a ROS peer may send: not refused here
    assert math.isnan(nan.data)


def test_a_model_publishes_by_field_names_with_its_header_stamped() -> None:
    conv = convert(out(Stamped), {"type": "geometry_msgs/msg/PointStamped", "frame_id": "base"})
    assert conv.via == "field names"
    message = conv.to_idl(Stamped(point=Point(x=1, y=2)), 1_700_000_000_123_456_789)
    assert (message.point.x, message.point.y, message.point.z) == (1.0, 2.0, 0.0)
    assert (message.header.stamp.sec, message.header.stamp.nanosec, message.header.frame_id) == \
        (1_700_000_000, 123_456_789, "base")


def test_time_is_float_seconds_both_ways() -> None:
    message = convert(out(Header), {"type": "std_msgs/msg/Header"}).to_idl(Header(stamp=12.25, frame_id="f"), 0)
    assert (message.stamp.sec, message.stamp.nanosec) == (12, 250_000_000)
    assert convert(inp(Header), {"type": "std_msgs/msg/Header"}).from_idl(message) == {"stamp": 12.25, "frame_id": "f"}


def test_a_model_field_without_a_namesake_is_refused_publishing_and_optional_reading() -> None:
    (problem,) = ROS2.check_stream(out(Pose2D), "/t", {"type": "geometry_msgs/msg/Pose2D"})
    assert problem.types and "Pose2D's note has no field in geometry_msgs/msg/Pose2D (its fields: x, y, theta)" \
        in problem.message
    assert ROS2.check_stream(inp(Pose2D), "/t", {"type": "geometry_msgs/msg/Pose2D"}) == []  # note has a default
    assert ROS2.check_stream(inp(Point), "/t", {"type": "geometry_msgs/msg/Pose2D"}) == []  # z: a default
    (problem,) = ROS2.check_stream(inp(Stamped), "/t", {"type": "geometry_msgs/msg/Pose2D"})
    assert "Stamped's point has no field in geometry_msgs/msg/Pose2D" in problem.message


def test_a_model_needs_a_type_and_a_field_of_another_shape_is_named() -> None:
    (problem,) = ROS2.check_stream(out(Point), "/t", {})
    assert "no default ROS 2 type" in problem.message
    (problem,) = ROS2.check_stream(out(Stamped), "/t", {"type": "sensor_msgs/msg/JointState"})
    assert "Stamped's point has no field in sensor_msgs/msg/JointState" in problem.message


def to_float64(value: float) -> dict:
    return {"data": value * 2}


def takes_str(value: str) -> dict:
    return {"data": 0.0}


def from_float64(message: Any) -> float:
    return message.data / 2


def unannotated(value):  # noqa: ANN001, ANN201 - the point of the test
    return {"data": value}


def two_args(a: float, b: float) -> dict:
    return {}


def test_a_converter_is_checked_by_its_annotations() -> None:
    ref = f"{__name__}:"
    assert ROS2.check_stream(out(float), "/t", {"converter": ref + "to_float64"}) == []
    conv = convert(out(float), {"converter": ref + "to_float64"})
    assert conv.via == f"converter {ref}to_float64" and conv.to_idl(1.5, 0).data == 3.0
    back = convert(inp(float), {"converter": ref + "from_float64"})
    assert back.from_idl(conv.to_idl(1.5, 0)) == 1.5
    (problem,) = ROS2.check_stream(out(float), "/t", {"converter": ref + "takes_str"})
    assert problem.types and "takes str; the port gives float" in problem.message
    (problem,) = ROS2.check_stream(out(float), "/t", {"converter": ref + "unannotated"})
    assert problem.warning and "no type annotations" in problem.message
    (problem,) = ROS2.check_stream(out(float), "/t", {"converter": ref + "two_args"})
    assert "cannot be called with one argument" in problem.message
    (problem,) = ROS2.check_stream(out(float), "/t", {"converter": "not_imported_anywhere:f"})
    assert "is not imported in this process" in problem.message


@pytest.mark.parametrize("options, said", [
    ({"qos": "x"}, "unknown option(s) qos"), ({"latch": "maybe"}, "latch='maybe': expected true or false"),
    ({"domain": "300"}, "domain='300': an integer 0..232"), ({"domain": "x"}, "domain='x'"),
    ({"interface": "eth0"}, "give insecure=true too"), ({"type": "std_srvs/srv/Trigger"}, "is a service type"),
    ({"type": "nope/msg/Nothing"}, "unknown ROS 2 message type"), ({"type": "Float64"}, "is not a ROS 2 type name"),
    ({"msgs": "thing.msg"}, "a message file is named .../PACKAGE/msg/TYPE.msg")])
def test_options_are_checked(options: dict[str, str], said: str) -> None:
    problems = ROS2.check_stream(out(float), "/t", options)
    assert len(problems) == 1 and said in problems[0].message, problems


def test_a_bad_topic_name_is_refused() -> None:
    (problem,) = ROS2.check_stream(out(float), "/1bad//t", {})
    assert "not a valid token" in problem.message and not problem.types


def test_a_users_msg_file_gives_a_type(tmp_path) -> None:
    msg = tmp_path / "lab_msgs" / "msg" / "Reading.msg"
    msg.parent.mkdir(parents=True)
    msg.write_text("float64 x\nfloat64 y\nfloat64 z\n", encoding="utf-8")
    options = {"type": "lab_msgs/msg/Reading", "msgs": str(msg)}
    assert ROS2.check_stream(out(Point), "/t", options) == []
    message = convert(out(Point), options).to_idl(Point(x=1, y=2, z=3), 0)
    assert type(message).__idl_typename__.replace(".", "::") == "lab_msgs::msg::dds_::Reading_"


def test_the_network_is_loopback_unless_a_stream_or_the_process_opens_it(monkeypatch: pytest.MonkeyPatch) -> None:
    transport = Ros2Transport()  # a process's defaults, without touching the registry's
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    where = transport.where({})
    assert (where.domain, where.network.loopback_only) == (42, True)
    assert transport.where({"domain": "7"}).domain == 7
    opened = transport.where({"insecure": "true", "peers": "10.0.0.2"}).network
    assert not opened.loopback_only and opened.peers == ("10.0.0.2",)
    transport.configure(insecure=True)  # scart deploy --insecure
    assert not transport.where({}).network.loopback_only
    assert transport.where({"insecure": "false"}).network.loopback_only
    transport.configure(insecure=None)  # unchanged
    assert not transport.where({}).network.loopback_only
    transport.configure(insecure=False)
    assert transport.where({}).network.loopback_only
    assert transport.participants() == {}  # nothing joined
