"""ROS 2 types and conversions without a network: every message of the distros' stores
gives the bytes rosbags' own CDR serialiser gives (what rosbag2 stores, i.e. what rmw
puts on the wire), and bad values are refused naming type.field."""

from __future__ import annotations

import random

import pytest

pytest.importorskip("cyclonedds.idl", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

import numpy as np  # noqa: E402
from rosbags.typesys.base import Nodetype  # noqa: E402

from scart_ros2 import ConversionError, MessageTypes, UnknownTypeError, message_to_dict  # noqa: E402

_NP = {"bool": np.bool_, "byte": np.int8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
       "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32, "int64": np.int64,
       "uint64": np.uint64, "float32": np.float32, "float64": np.float64}


def _value(types: MessageTypes, desc: object, rng: random.Random) -> object:
    """A rosbags value for a field description, filled with varied data."""
    kind, detail = desc  # type: ignore[misc]
    if kind == Nodetype.NAME:
        return _message(types, detail, rng)
    if kind == Nodetype.BASE:
        return _scalar(detail[0], detail[1], rng)
    inner, size = detail
    count = size if kind == Nodetype.ARRAY else min(size or 3, 3)
    if inner[0] == Nodetype.BASE and inner[1][0] in _NP:
        return np.array([_scalar(inner[1][0], 0, rng) for _ in range(count)], dtype=_NP[inner[1][0]])
    return [_value(types, inner, rng) for _ in range(count)]


def _scalar(base: str, bound: int, rng: random.Random) -> object:
    if base == "bool":
        return rng.random() < 0.5
    if base == "string":
        return "ab€"[: bound or 3] if rng.random() < 0.8 else ""
    if base.startswith("float"):
        return rng.randint(-1000, 1000) / 8  # exact in float32 too
    return {"byte": rng.randint(0, 127), "char": rng.randint(0, 255)}.get(base, rng.randint(0, 100))


def _message(types: MessageTypes, name: str, rng: random.Random) -> object:
    fields = types._store.fielddefs[name][1]
    return types.message_class(name)(**{f: _value(types, d, rng) for f, d in fields})


@pytest.mark.parametrize("distro", ["humble", "jazzy"])
def test_every_message_of_the_store_has_rosbags_cdr_bytes_both_ways(distro: str) -> None:
    types, rng = MessageTypes(distro), random.Random(22)
    names = types.names()
    assert len(names) > 100
    for name in names:
        message = _message(types, name, rng)
        reference = types._store.serialize_cdr(message, name)
        assert types.serialize(name, message) == reference, name
        back = types.deserialize(name, reference)
        assert types._store.serialize_cdr(back, name) == reference, name


def test_dds_type_names_and_nested_types() -> None:
    types = MessageTypes()
    joint_state = types.idl_type("sensor_msgs/msg/JointState")
    assert joint_state.__idl_typename__ == "sensor_msgs::msg::dds_::JointState_"
    assert types.idl_type("sensor_msgs/msg/JointState") is joint_state  # cached
    header = joint_state.__annotations__["header"]
    assert header.__idl_typename__ == "std_msgs::msg::dds_::Header_"
    assert header.__annotations__["stamp"].__idl_typename__ == "builtin_interfaces::msg::dds_::Time_"


def test_a_mapping_takes_zero_values_for_missing_fields_and_refuses_unknown_ones() -> None:
    types = MessageTypes()
    message = types.from_idl("sensor_msgs/msg/JointState",
                             types.to_idl("sensor_msgs/msg/JointState", {"name": ["a"], "position": [1.0]}))
    assert message_to_dict(message) == {
        "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
        "name": ["a"], "position": [1.0], "velocity": [], "effort": []}
    with pytest.raises(ConversionError, match="sensor_msgs/msg/JointState has no field 'positions'"):
        types.to_idl("sensor_msgs/msg/JointState", {"positions": [1.0]})


@pytest.mark.parametrize(("type_name", "value", "message"), [
    ("std_msgs/msg/Int8", {"data": 128}, r"std_msgs/msg/Int8.data: 128 is out of range \[-128, 127\]"),
    ("std_msgs/msg/UInt64", {"data": -1}, r"UInt64.data: -1 is out of range"),
    ("std_msgs/msg/Int64", {"data": 1.5}, r"Int64.data: expected an integer, got float"),
    ("std_msgs/msg/Float64", {"data": "1"}, r"Float64.data: expected a number, got str"),
    ("std_msgs/msg/Float32", {"data": 1e39}, r"Float32.data: 1e\+39 does not fit a float32"),
    ("std_msgs/msg/String", {"data": b"x"}, r"String.data: expected a str, got bytes"),
    ("std_msgs/msg/Bool", {"data": 2}, r"Bool.data: expected a bool, got 2"),
    ("geometry_msgs/msg/PoseWithCovariance", {"covariance": [0.0] * 35},
     r"PoseWithCovariance.covariance: 35 elements, the array holds 36"),
    ("sensor_msgs/msg/JointState", {"header": {"stamp": {"sec": "now"}}},
     r"builtin_interfaces/msg/Time.sec: expected an integer, got str"),
    ("std_msgs/msg/Float64", 3.0, r"expected a std_msgs/msg/Float64 message or a mapping, got float"),
])
def test_a_value_that_does_not_fit_is_refused_naming_the_field(type_name: str, value: object, message: str) -> None:
    with pytest.raises(ConversionError, match=message):
        MessageTypes().to_idl(type_name, value)


def test_a_message_of_another_type_is_refused() -> None:
    types = MessageTypes()
    with pytest.raises(ConversionError, match="got std_msgs/msg/Int64"):
        types.to_idl("std_msgs/msg/Float64", types.message_class("std_msgs/msg/Int64")(data=1))


def test_user_messages_and_services() -> None:
    types = MessageTypes()
    types.add_msg("my_pkg/msg/Reading", "std_msgs/Header header\nfloat64[3] xyz\nstring<=8 label\nint32 LIMIT=5\n")
    types.add_msg("my_pkg/msg/Batch", "Reading[<=2] readings\n")  # same-package reference
    batch = {"readings": [{"xyz": [1.0, 2.0, 3.0], "label": "a"}]}
    assert message_to_dict(types.deserialize("my_pkg/msg/Batch", types.serialize("my_pkg/msg/Batch", batch))) == {
        "readings": [{"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""}, "xyz": [1.0, 2.0, 3.0],
                      "label": "a"}]}
    with pytest.raises(ConversionError, match="label: 9 characters, the bound is 8"):
        types.to_idl("my_pkg/msg/Reading", {"label": "123456789"})
    with pytest.raises(ConversionError, match="readings: 3 elements, the bound is 2"):
        types.to_idl("my_pkg/msg/Batch", {"readings": [{}, {}, {}]})
    types.add_srv("my_pkg/srv/Scale", "my_pkg/Reading reading\nfloat64 factor\n---\nmy_pkg/Reading scaled\n")
    assert types.service("my_pkg/srv/Scale") == ("my_pkg/srv/Scale_Request", "my_pkg/srv/Scale_Response")
    request = types.service_idl_type("my_pkg/srv/Scale_Request")
    assert request.__idl_typename__ == "my_pkg::srv::dds_::Scale_Request_"
    assert list(request.__annotations__)[:3] == ["guid_", "seq_", "reading"]
    assert types.service("std_srvs/srv/Trigger")[1] == "std_srvs/srv/Trigger_Response"  # a standard one


def test_bad_definitions_and_unknown_types_say_so() -> None:
    types = MessageTypes()
    with pytest.raises(UnknownTypeError, match=r"unknown ROS 2 message type 'nope/msg/Nope' \(ROS 2 jazzy\)"):
        types.idl_type("nope/msg/Nope")
    with pytest.raises(UnknownTypeError, match="add its .srv"):
        types.service("nope/srv/Nope")
    with pytest.raises(ValueError, match="one '---' line"):
        types.add_srv("my_pkg/srv/Bad", "int32 a\n")
    with pytest.raises(ValueError, match="not a ROS 2 type name"):
        types.add_msg("Bad", "int32 a\n")
    with pytest.raises(ValueError, match="already defined"):
        types.add_msg("std_msgs/msg/Int64", "int64 data\n")
    with pytest.raises(ValueError, match="unknown ROS 2 distro 'noetic'"):
        MessageTypes("noetic")


def test_type_hashes_from_iron_on() -> None:
    assert MessageTypes("jazzy").type_hash("std_msgs/msg/String") == (
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18")  # rmw_zenoh's design doc
    assert MessageTypes("humble").type_hash("std_msgs/msg/String") is None


def test_a_msg_file_names_itself_by_its_path(tmp_path) -> None:
    folder = tmp_path / "my_robot" / "msg"
    folder.mkdir(parents=True)
    (folder / "Wheel.msg").write_text("float64 speed\nstring<=4 side\n", encoding="utf-8")
    types = MessageTypes()
    assert types.add_msg_file(folder / "Wheel.msg") == "my_robot/msg/Wheel"
    assert types.idl_type("my_robot/msg/Wheel").__idl_typename__ == "my_robot::msg::dds_::Wheel_"
    srv = tmp_path / "my_robot" / "srv" / "Stop.srv"
    srv.parent.mkdir()
    srv.write_text("bool now\n---\nbool stopped\n", encoding="utf-8")
    assert types.add_srv_file(srv) == "my_robot/srv/Stop"
    assert types.zero("my_robot/srv/Stop_Response").stopped is False


def test_types_are_found_through_ament_prefix_path(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    share = tmp_path / "install" / "share" / "lab_msgs"  # as colcon installs a package
    (share / "msg").mkdir(parents=True)
    (share / "srv").mkdir()
    (share / "msg" / "Angle.msg").write_text("float64 radians\n")
    (share / "msg" / "Pose2.msg").write_text("float64 x\nfloat64 y\nAngle theta\n")
    (share / "srv" / "SetPose2.srv").write_text("Pose2 pose\n---\nbool ok\n")
    (share / "msg" / "Broken.msg").write_text("float64[ x\n")
    monkeypatch.setenv("AMENT_PREFIX_PATH", f"{tmp_path / 'elsewhere'}:{tmp_path / 'install'}")
    types = MessageTypes()
    pose = types.deserialize("lab_msgs/msg/Pose2", types.serialize("lab_msgs/msg/Pose2", {"theta": {"radians": 0.5}}))
    assert pose.theta.radians == 0.5  # and lab_msgs/msg/Angle, which it uses
    assert types.service("lab_msgs/srv/SetPose2") == ("lab_msgs/srv/SetPose2_Request", "lab_msgs/srv/SetPose2_Response")
    with pytest.raises(UnknownTypeError, match="AMENT_PREFIX_PATH"):
        types.fields("lab_msgs/msg/Missing")
    with pytest.raises(UnknownTypeError, match="Broken.msg: lab_msgs/msg/Broken: bad definition"):
        types.fields("lab_msgs/msg/Broken")
    assert MessageTypes(prefix_path="").prefixes == ()
