"""rosbags' message classes as port types (``OutputPort(Image)`` with rosbags' ROS 2
``sensor_msgs/msg/Image``), numpy fields and all: known to another process by name alone,
across deployers (shm: the image's bytes a view of the shared memory), as JSON (echo,
record, play), and on ROS 1 (the message as it is); on ROS 2 see
``transports/ros2/test_ros2_arrays.py``."""

from __future__ import annotations


import base64

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from dataflow import ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, TaskContext
from dataflow.remote import connect
from scart_wire import codec
from scart_wire.errors import PortTypeError
from scart_wire.types import registry
from support import wait_until

ROS2 = get_typestore(Stores.ROS2_JAZZY)
Image = ROS2.types["sensor_msgs/msg/Image"]
Header, Time = ROS2.types["std_msgs/msg/Header"], ROS2.types["builtin_interfaces/msg/Time"]
NAME = "rosbags:ros2_dashing:sensor_msgs/msg/Image"  # the module of the first distro with this definition


def image(height: int, width: int, seed: int) -> object:
    data = ((np.arange(height * width * 3, dtype=np.int64) * seed + seed) % 251).astype(np.uint8)
    return Image(header=Header(stamp=Time(sec=1, nanosec=2), frame_id="camera"), height=height, width=width,
                 encoding="rgb8", is_bigendian=0, step=width * 3, data=data)


class Camera(TaskContext):
    image = OutputPort(Image)


class Viewer(TaskContext):
    image = InputPort(Image)

    def newest(self) -> list[object]:
        flow, value = self.image.read()
        return [value] if flow is FlowStatus.NEW_DATA else []


def test_a_rosbags_class_is_a_port_type_known_by_name_with_its_numpy_fields() -> None:
    assert Camera("c").image.type_name == NAME and registry.python_type(NAME) is Image
    assert registry.python_type("rosbags:ros2_dashing:os/msg/system") is None  # only rosbags' own classes
    sent = image(2, 3, 7)
    wire = codec.encode(sent, Image)
    raw = wire.data  # (as a transport holds them: shm's slot, ipc's datagram)
    got = codec.decode(codec.Payload(wire.type_name, raw))
    assert type(got) is Image and got.header.frame_id == "camera" and isinstance(got.data, np.ndarray)
    assert np.array_equal(got.data, sent.data) and not got.data.flags.writeable
    assert np.shares_memory(got.data, np.frombuffer(raw, dtype=np.uint8))  # a view of the bytes
    as_json = registry.to_jsonable(sent)
    assert as_json["data"] == base64.b64encode(sent.data.tobytes()).decode()  # base64: the bytes
    assert as_json["header"]["stamp"] == {"sec": 1, "nanosec": 2}
    back = registry.from_jsonable(NAME, as_json)
    assert type(back) is Image and np.array_equal(back.data, sent.data) and back.encoding == "rgb8"
    assert registry.validate(Image, {"height": 4}).width == 0  # ROS's zero for what is left out
    with pytest.raises(PortTypeError, match="has no field 'colour'"):
        registry.from_jsonable(NAME, {"colour": 1})
    with pytest.raises(PortTypeError):
        Camera("c").image.write({"height": 4})  # a port's check is exact: a message of the class


@pytest.mark.integration
def test_a_6mb_image_message_crosses_deployers_over_shm_as_a_view(tmp_path) -> None:
    d1, d2 = Deployer(), Deployer()
    cam, viewer = d1.add(Camera("cam")), d2.add(Viewer("viewer"))
    s1 = d1.serve("127.0.0.1:0")
    s2 = d2.serve("127.0.0.1:0", ns=s1.address)
    try:
        with connect(s1.address, timeout=5.0) as system:
            system.connect_ports("cam.image", "viewer.image", ConnPolicy.buffer(2).with_(transport="shm"), name="l")
            wait_until(lambda: [lk for lk in system.links() if lk.name == "l" and lk.transport == "shm"], timeout=10)
            sent = image(1080, 1920, 5)
            assert cam.image.write(sent).name == "WRITE_SUCCESS"
            (got,) = wait_until(viewer.newest, timeout=20, message="the image never arrived")
            assert type(got) is Image and (got.height, got.width, got.header.frame_id) == (1080, 1920, "camera")
            assert np.array_equal(got.data, sent.data) and not got.data.flags.writeable
    finally:
        s2.stop()
        s1.stop()


def test_a_rosbags_ros1_class_is_a_ros1_topic_as_it_is() -> None:
    from scart_ros1 import MessageTypes
    from dataflow.transports.ros1.convert import plan

    noetic = get_typestore(Stores.ROS1_NOETIC)
    ros1_image = noetic.types["sensor_msgs/msg/Image"]
    types = MessageTypes()
    out, problems = plan(types, ros1_image, None, outgoing=True)
    back, more = plan(types, ros1_image, None, outgoing=False)
    assert out is not None and back is not None and out.ros_type == "sensor_msgs/Image", problems + more
    header = noetic.types["std_msgs/msg/Header"](seq=1, stamp=noetic.types["builtin_interfaces/msg/Time"](
        sec=1, nanosec=0), frame_id="camera")
    sent = ros1_image(header=header, height=1, width=2, encoding="mono8", is_bigendian=0, step=2,
                      data=np.array([9, 8], dtype=np.uint8))
    msgtype = types.msg("sensor_msgs/Image")
    got = back.from_ros(msgtype.deserialize(msgtype.serialize(out.to_ros(sent, 1, 0))))
    assert type(got) is ros1_image and np.array_equal(got.data, [9, 8]) and got.header.frame_id == "camera"
    wrong, said = plan(types, Image, None, outgoing=True)  # a ROS 2 class is not a ROS 1 type
    assert wrong is None and said, said
