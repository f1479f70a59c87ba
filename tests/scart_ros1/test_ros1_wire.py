"""ROS 1 without a master: types and md5sums against Debian's generated Python, names as
rospy resolves them, the TCPROS header and frame codecs and their bounds."""

from __future__ import annotations

import struct

import pytest
from rosbags.typesys import Stores, get_typestore

from scart_ros1 import Limits, MessageTypes, RosNameError, TypeDefinitionError, UnknownTypeError
from scart_ros1.io import FrameReader
from scart_ros1.names import node_names, parse_remaps, resolve
from scart_ros1.tcpros import HeaderError, decode_header, encode_header

# md5sums from Debian's generated Python (python3-std-msgs, -sensor-msgs, -roscpp-msg: _md5sum)
DEBIAN_MD5 = {
    "sensor_msgs/JointState": "3066dcd76a6cfaef579bd0f34173e9fd",
    "std_msgs/Int64": "34add168574510e6e17f5d23ecc077ef",
    "std_msgs/String": "992ce8a1687cec8c8bd883ec73ca41d1",
    "std_msgs/Header": "2176decaecbce78abc3b96ef049fabed",
    "geometry_msgs/PoseStamped": "d3812c3cbc69362b77dc0b19b345f8f5",
}
DEBIAN_SRV_MD5 = {  # roscpp.srv (Debian) and std_srvs (ros/std_srvs .srv files)
    "roscpp/GetLoggers": "32e97e85527d4678a8f9279894bb64b0",
    "roscpp/SetLoggerLevel": "51da076440d78ca1684d36c868df61ea",
    "std_srvs/Trigger": "937c9679a518e3a18d831e57125ea522",
    "std_srvs/SetBool": "09fb03525b03e7ea1fd3992bafd87e16",
    "std_srvs/Empty": "d41d8cd98f00b204e9800998ecf8427e",
}


@pytest.mark.parametrize("name", sorted(DEBIAN_MD5))
def test_message_md5sums_equal_debians(types: MessageTypes, name: str) -> None:
    assert types.msg(name).md5sum == DEBIAN_MD5[name]


@pytest.mark.parametrize("name", sorted(DEBIAN_SRV_MD5))
def test_service_md5sums_equal_debians(types: MessageTypes, name: str) -> None:
    assert types.srv(name).md5sum == DEBIAN_SRV_MD5[name]


def test_every_store_md5sum_equals_rosbags(types: MessageTypes) -> None:
    store = get_typestore(Stores.ROS1_NOETIC)
    names = [n for n in store.types if "/msg/" in n]
    assert len(names) > 150
    wrong = [n for n in names if types.msg(n).md5sum != store.generate_msgdef(n)[1]]
    assert wrong == []


def test_definition_is_genmsgs_full_text(types: MessageTypes) -> None:
    text = types.msg("sensor_msgs/JointState").definition
    main, dep = text.split("=" * 80 + "\n")
    assert main == "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n\n"
    assert dep == "MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n"
    # a user's type keeps its own text, comments included
    types.add_msg("scart_test/Commented", "# a comment\nfloat64 x  # metres\n")
    assert types.msg("scart_test/Commented").definition == "# a comment\nfloat64 x  # metres\n"


def test_serialisation_round_trips_and_refuses_garbage(types: MessageTypes) -> None:
    js = types.msg("sensor_msgs/JointState")
    msg = js.new(header={"frame_id": "base", "stamp": {"sec": 3}}, name=["a1", "a2"], position=[0.5, -1.0])
    frame = js.frame(msg)
    assert struct.unpack_from("<I", frame)[0] == len(frame) - 4
    back = js.deserialize(bytes(frame[4:]))
    assert back.name == ["a1", "a2"] and list(back.position) == [0.5, -1.0] and back.header.stamp.sec == 3
    assert types.msg("std_msgs/Int64").serialize(types.msg("std_msgs/Int64").new(data=-2)) == struct.pack("<q", -2)
    with pytest.raises(ValueError, match="sensor_msgs/JointState"):
        js.deserialize(b"\x01\x02")
    with pytest.raises(ValueError, match="left over"):
        types.msg("std_msgs/Int64").deserialize(b"\0" * 9)
    with pytest.raises(TypeError, match="no field nope"):
        js.new(nope=1)


def test_user_files_in_a_ros_package_layout(tmp_path) -> None:
    (tmp_path / "my_pkg" / "msg").mkdir(parents=True)
    (tmp_path / "my_pkg" / "srv").mkdir()
    (tmp_path / "my_pkg" / "msg" / "Pair.msg").write_text("Header header\nfloat64 a\nfloat64 b\n")
    (tmp_path / "my_pkg" / "srv" / "AddTwoInts.srv").write_text("int64 a\nint64 b\n---\nint64 sum\n")
    mt = MessageTypes(files=[tmp_path / "my_pkg" / "msg" / "Pair.msg", tmp_path / "my_pkg" / "srv" / "AddTwoInts.srv"])
    assert "MSG: std_msgs/Header" in mt.msg("my_pkg/Pair").definition
    # rospy_tutorials/AddTwoInts, as Debian's and ROS's tutorials give it
    assert mt.srv("my_pkg/AddTwoInts").md5sum == "6a2e34150c00229791cc89ff309fff21"
    assert mt.srv("my_pkg/AddTwoInts").request.name == "my_pkg/AddTwoIntsRequest"


def test_bad_types_say_what_and_where(tmp_path) -> None:
    mt = MessageTypes()
    with pytest.raises(UnknownTypeError, match="nope_msgs/Nothing"):
        mt.msg("nope_msgs/Nothing")
    with pytest.raises(UnknownTypeError, match="package/Type"):
        mt.msg("no-slash")
    with pytest.raises(UnknownTypeError, match="add its .srv"):
        mt.srv("std_srvs/Unknown")
    mt.add_msg("scart_test/UsesMissing", "missing_pkg/Thing thing\n")
    with pytest.raises(UnknownTypeError, match=r"missing_pkg/Thing.*used by scart_test/UsesMissing"):
        mt.msg("scart_test/UsesMissing")
    bad = tmp_path / "pkg" / "msg" / "Bad.msg"
    bad.parent.mkdir(parents=True)
    bad.write_text("# fine\nfloat64 x\nfloat64[ y\n")
    with pytest.raises(TypeDefinitionError, match=r"Bad.msg: pkg/Bad: line 3: 'float64\[ y' cannot be parsed"):
        mt.add_file(bad)
    with pytest.raises(TypeDefinitionError, match="'---'"):
        mt.add_srv("pkg/NoSep", "int64 a\n")


def test_names_resolve_as_rospy() -> None:
    node = "/robot/talker"
    assert resolve("chatter", node) == "/robot/chatter"
    assert resolve("/chatter", node) == "/chatter"
    assert resolve("~state", node) == "/robot/talker/state"
    assert resolve("sub/topic/", node) == "/robot/sub/topic"
    for bad in ("", "1abc", "a b", "a//b", "a~b"):
        with pytest.raises(RosNameError):
            resolve(bad, node)


def test_remaps_name_namespace_and_master() -> None:
    names = node_names("scart", remaps=["__name:=other", "__ns:=/robot", "chatter:=/remapped", "_param:=1",
                                        "not-a-remap", "~priv:=shared"], env={})
    assert names.node == "/robot/other" and names.namespace == "/robot"
    assert names.master_uri == "http://localhost:11311/"
    assert names.resolve("chatter") == "/remapped"
    assert names.resolve("~priv") == "/robot/shared"
    env = {"ROS_MASTER_URI": "http://127.0.0.1:1234", "ROS_NAMESPACE": "ns"}
    assert node_names("n", env=env).node == "/ns/n"
    assert node_names("n", env=env).master_uri == "http://127.0.0.1:1234"
    assert node_names("n", master_uri="http://h:1/", remaps={"__master": "http://m:2/"}, env={}).master_uri == "http://m:2/"
    with pytest.raises(RosNameError, match="node name"):
        node_names("a/b", env={})
    with pytest.raises(RosNameError, match="master URI"):
        node_names("n", master_uri="localhost:11311", env={})
    with pytest.raises(RosNameError, match="special remap"):
        parse_remaps(["__bogus:=1"])


def test_header_codec_and_its_bounds() -> None:
    fields = {"callerid": "/a", "topic": "/t", "message_definition": "int64 data\n", "md5sum": "*", "empty": ""}
    encoded = encode_header(fields)
    assert struct.unpack_from("<I", encoded)[0] == len(encoded) - 4
    assert decode_header(encoded[4:]) == fields
    cases = [
        (struct.pack("<I", 100) + b"x=1", "overruns"),
        (struct.pack("<I", 3) + b"abc", "not key=value"),
        (struct.pack("<I", 2) + b"=v", "not key=value"),
        (struct.pack("<I", 3) + b"a=\xff", "UTF-8"),
        (b"\x01\x00", "cut short"),
        (b"".join(struct.pack("<I", 3) + f"k{i}=".encode()[:3] for i in range(70)), "not key=value|more than"),
    ]
    for body, match in cases:
        with pytest.raises(HeaderError, match=match):
            decode_header(body)
    many = b"".join(struct.pack("<I", len(f"k{i}=v")) + f"k{i}=v".encode() for i in range(70))
    with pytest.raises(HeaderError, match="more than 64"):
        decode_header(many)


def test_frame_reader_cuts_joins_and_skips_oversized() -> None:
    frames: list[bytes] = []
    oversized: list[int] = []
    reader = FrameReader(8, frames.append, oversized.append)
    stream = b"".join(struct.pack("<I", len(p)) + p for p in (b"one", b"", b"x" * 20, b"two!", b"12345678"))
    for i in range(0, len(stream), 3):  # in 3-byte pieces: every boundary cut somewhere
        reader.feed(stream[i : i + 3])
    assert frames == [b"one", b"", b"two!", b"12345678"] and oversized == [20]
    frames.clear()
    reader.feed(stream)  # all at once
    assert frames == [b"one", b"", b"two!", b"12345678"] and all(type(f) is bytes for f in frames)
    frames.clear()
    for payload in (b"alone", b"", b"x" * 9, b"12345678"):  # one whole frame per read: the common case
        reader.feed(struct.pack("<I", len(payload)) + payload)
    assert frames == [b"alone", b"", b"12345678"] and oversized == [20, 20, 9]


def test_frame_reader_says_what_is_still_due() -> None:
    """``missing()`` is the rest of the message begun (a subscriber reads a large one in
    larger pieces), or of one being skipped; 0 between messages."""
    frames: list[bytes] = []
    reader = FrameReader(100, frames.append, lambda size: None)
    assert reader.missing() == 0
    reader.feed(struct.pack("<I", 50)[:3])  # its length not known yet
    assert reader.missing() == 0
    reader.feed(struct.pack("<I", 50)[3:] + b"x" * 20)
    assert reader.missing() == 30
    reader.feed(b"x" * 30 + struct.pack("<I", 500) + b"y" * 10)  # the next one is over the limit: skipped
    assert frames == [b"x" * 50] and reader.missing() == 490
    reader.feed(b"y" * 490)
    assert reader.missing() == 0 and frames == [b"x" * 50]


def test_limits_refuse_nonsense() -> None:
    with pytest.raises(ValueError, match="max_message"):
        Limits(max_message=0)
    with pytest.raises(ValueError, match="header_timeout"):
        Limits(header_timeout=float("nan"))


def test_types_are_found_through_ros_package_path(tmp_path) -> None:
    src = tmp_path / "ws" / "src"
    msgs = src / "robot_stack" / "my_msgs"  # a package inside a metapackage's folder, as in a catkin workspace
    (msgs / "msg").mkdir(parents=True)
    (msgs / "srv").mkdir()
    (msgs / "package.xml").write_text("<package><name>my_msgs</name></package>")
    (msgs / "msg" / "Angle.msg").write_text("float64 radians\n")
    (msgs / "msg" / "Pose2.msg").write_text("float64 x\nfloat64 y\nmy_msgs/Angle theta\n")
    (msgs / "srv" / "SetPose2.srv").write_text("Pose2 pose\n---\nbool ok\n")
    types = MessageTypes(package_path=f"{tmp_path / 'elsewhere'}:{src}")
    pose = types.msg("my_msgs/Pose2")  # and my_msgs/Angle, which it uses
    assert pose.deserialize(pose.serialize(pose.new(x=1.0, theta={"radians": 0.5}))).theta.radians == 0.5
    assert "MSG: my_msgs/Angle" in pose.definition
    assert types.srv("my_msgs/SetPose2").request.name == "my_msgs/SetPose2Request"
    with pytest.raises(UnknownTypeError, match="ROS_PACKAGE_PATH"):
        types.msg("my_msgs/Missing")
    assert MessageTypes(package_path="").package_path == []
