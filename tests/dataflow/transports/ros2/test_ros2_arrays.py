"""Array ports on ROS 2: an image-shaped array is a ``sensor_msgs/msg/Image``, any array a
``std_msgs`` multi-array of its element type with its shape in the layout. Judged by an
independent Cyclone DDS peer in another process (its own IDL types, Cyclone's own Python
serialiser), at 640x480x3 and at 6.2 MB (one 1080p RGB frame); and copied at most once
each way (the allocations of one conversion, traced)."""

from __future__ import annotations

import hashlib
import tracemalloc
from typing import Any

import numpy as np
import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from rosbags.typesys import Stores, get_typestore  # noqa: E402

from dataflow import Array, ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, TaskContext  # noqa: E402
from dataflow.transports import load  # noqa: E402
from scart_ros2 import MessageTypes  # noqa: E402
from dataflow.transports.ros2._convert import plan  # noqa: E402
from support import wait_until  # noqa: E402

VGA = Array[np.uint8, (480, 640, 3)]
FULL_HD = Array[np.uint8, (1080, 1920, 3)]
CLOUD = Array[np.float32, (None, 3)]
GRID = Array[np.float64, (None, 4)]


def pattern(size: int, seed: int) -> np.ndarray:
    """The peer's ``pattern()``: byte i is (i * seed + seed) % 251."""
    return ((np.arange(size, dtype=np.int64) * seed + seed) % 251).astype(np.uint8)


class Camera(TaskContext):
    image = OutputPort(VGA)
    cloud = OutputPort(CLOUD)


class Viewer(TaskContext):
    image = InputPort(FULL_HD)
    grid = InputPort(GRID)

    def newest(self, port: str) -> list[np.ndarray]:
        """``[the new sample]`` of ``port``, or ``[]``."""
        flow, value = self.port(port).read()
        return [value] if flow is FlowStatus.NEW_DATA else []


@pytest.fixture
def deployer():
    d = Deployer()
    yield d
    for name in list(d.streams()):
        d.unstream(name)
    assert load("ros2").participants() == {}, "the process's participant outlived its last stream"


def _ros2(topic: str, policy: ConnPolicy | None = None) -> ConnPolicy:
    return (policy or ConnPolicy.data()).with_(transport="ros2", topic=topic)


def test_an_image_is_serialised_with_one_copy_and_read_as_a_view_of_the_bytes() -> None:
    types = MessageTypes()
    out, problems = plan(types, FULL_HD, None, outgoing=True)
    back, more = plan(types, FULL_HD, None, outgoing=False)
    assert out is not None and back is not None and out.ros_type == "sensor_msgs/msg/Image", problems + more
    assert out.to_cdr is not None and back.from_cdr is not None
    frame = pattern(1080 * 1920 * 3, 7).reshape(1080, 1920, 3)
    out.to_cdr(frame, 0)  # rosbags makes its serialiser on first use
    tracemalloc.start()
    try:
        data = out.to_cdr(frame, 1_500_000_000)
        written = tracemalloc.get_traced_memory()[1]
        raw = bytes(data)  # as Cyclone hands a sample over (its copy, not ours)
        back.from_cdr(raw)
        tracemalloc.reset_peak()
        got = back.from_cdr(raw)
        read = tracemalloc.get_traced_memory()[1] - len(raw) - len(data)
    finally:
        tracemalloc.stop()
    assert written < 1.2 * frame.nbytes, f"{written} bytes allocated to send a {frame.nbytes}-byte frame"
    assert read < 0.05 * frame.nbytes, f"{read} bytes allocated to read a {frame.nbytes}-byte frame"
    assert np.array_equal(got, frame) and not got.flags.writeable
    assert np.shares_memory(got, np.frombuffer(raw, dtype=np.uint8))


def test_the_bytes_are_cyclones_own_for_an_image_and_a_multi_array() -> None:
    """rosbags' CDR, written as it is, is what Cyclone's serialiser makes of the same
    message (padded to 4 bytes, as Cyclone's writer pads)."""
    types = MessageTypes()
    for spec, value in ((Array[np.uint8, (1, 3)], np.array([[1, 2, 3]], dtype=np.uint8)),
                        (CLOUD, np.arange(6, dtype=np.float32).reshape(2, 3))):
        out, problems = plan(types, spec, None, outgoing=True)
        assert out is not None and out.to_cdr is not None, problems
        data = bytes(out.to_cdr(value, 3_000_000_007))
        own = types.serialize(out.ros_type, types.from_cdr(out.ros_type, data))
        assert data == own + bytes(-len(own) % 4), (data, own)


def test_arrays_that_do_not_fit_the_message_are_refused_when_planned() -> None:
    types = MessageTypes()
    for spec, ros_type, said in ((Array[np.float32, (None,)], "std_msgs/msg/Float64MultiArray", "an array of float32"),
                                 (GRID, "sensor_msgs/msg/Image", "is not an image"),
                                 (VGA, "std_msgs/msg/Float64", "'data' is an array of uint8")):
        conv, problems = plan(types, spec, ros_type, outgoing=True)
        assert conv is None and said in problems[0].message, problems


@pytest.mark.integration
def test_an_image_port_publishes_a_ros2_image_that_an_independent_peer_reads(
        domain: int, topic: str, stream_peer, deployer: Deployer) -> None:
    cam = deployer.add(Camera("cam"))
    deployer.stream("cam.image", _ros2(topic + "/image"), {"domain": str(domain), "frame_id": "camera"})
    deployer.stream("cam.cloud", _ros2(topic + "/cloud"), {"domain": str(domain),  # (a 2-d float32: 32FC1 by default)
                                                          "type": "std_msgs/msg/Float32MultiArray"})
    image_reader = stream_peer("read", topic + "/image", "Image")
    frame = pattern(480 * 640 * 3, 3).reshape(480, 640, 3)
    wait_until(lambda: cam.image.write(frame) and image_reader.poll("sample", timeout=0.5), timeout=20,
               message="the peer never read the image")
    got = image_reader.events[-1]
    assert (got["height"], got["width"], got["encoding"], got["step"], got["is_bigendian"], got["frame_id"]) == \
        (480, 640, "rgb8", 1920, 0, "camera")
    assert got["sha256"] == hashlib.sha256(frame.tobytes()).hexdigest()
    cloud_reader = stream_peer("read", topic + "/cloud", "Float32MultiArray")
    points = np.arange(12, dtype=np.float32).reshape(4, 3)
    wait_until(lambda: cam.cloud.write(points) and cloud_reader.poll("sample", timeout=0.5), timeout=20,
               message="the peer never read the cloud")
    got = cloud_reader.events[-1]
    assert got["data"] == points.reshape(-1).tolist() and got["data_offset"] == 0
    assert got["dim"] == [["dim0", 4, 12], ["dim1", 3, 3]]


@pytest.mark.integration
def test_a_6mb_image_and_a_multi_array_from_an_independent_peer_arrive_as_read_only_arrays(
        domain: int, topic: str, stream_peer, deployer: Deployer) -> None:
    viewer = deployer.add(Viewer("viewer"))
    deployer.stream("viewer.image", _ros2(topic + "/image", ConnPolicy.buffer(2)), {"domain": str(domain)})
    deployer.stream("viewer.grid", _ros2(topic + "/grid", ConnPolicy.buffer(2)), {"domain": str(domain)})
    stream_peer("write", topic + "/image", "Image",
                [{"height": 1080, "width": 1920, "encoding": "rgb8", "channels": 3, "seed": 5}]).next_event("acked")
    (image,) = wait_until(lambda: viewer.newest("image"), timeout=20, message="the 6.2 MB image never arrived")
    assert image.shape == (1080, 1920, 3) and image.dtype == np.uint8 and not image.flags.writeable
    assert np.array_equal(image.reshape(-1), pattern(1080 * 1920 * 3, 5))
    stream_peer("write", topic + "/grid", "Float64MultiArray",
                [{"data": list(range(8)), "dim": [["rows", 2, 8], ["cols", 4, 4]]}]).next_event("acked")
    (grid,) = wait_until(lambda: viewer.newest("grid"), timeout=20, message="the multi-array never arrived")
    assert grid.shape == (2, 4) and np.array_equal(grid, np.arange(8.0).reshape(2, 4)) and not grid.flags.writeable
    (listed,) = [lk for lk in deployer.links() if lk.sink == "viewer.image"]
    assert (listed.samples, listed.dropped) == (1, 0)


ROS2 = get_typestore(Stores.ROS2_JAZZY)
BagImage = ROS2.types["sensor_msgs/msg/Image"]


def image(height: int, width: int, seed: int) -> Any:
    """A rosbags Image of the peer's pattern() bytes."""
    header = ROS2.types["std_msgs/msg/Header"](stamp=ROS2.types["builtin_interfaces/msg/Time"](sec=1, nanosec=2),
                                               frame_id="camera")
    return BagImage(header=header, height=height, width=width, encoding="rgb8", is_bigendian=0, step=width * 3,
                    data=pattern(height * width * 3, seed))


class BagCamera(TaskContext):
    image = OutputPort(BagImage)


class BagViewer(TaskContext):
    image = InputPort(BagImage)

    def newest(self) -> list[Any]:
        flow, value = self.image.read()
        return [value] if flow is FlowStatus.NEW_DATA else []


@pytest.mark.integration
def test_a_rosbags_image_port_is_a_ros2_topic_both_ways(domain: int, topic: str, stream_peer) -> None:
    deployer = Deployer()
    cam, viewer = deployer.add(BagCamera("cam")), deployer.add(BagViewer("viewer"))
    try:
        deployer.stream("cam.image", ConnPolicy.data().with_(transport="ros2", topic=topic + "/out"),
                        {"domain": str(domain)})
        deployer.stream("viewer.image", ConnPolicy.buffer(2).with_(transport="ros2", topic=topic + "/in"),
                        {"domain": str(domain)})
        reader = stream_peer("read", topic + "/out", "Image")
        sent = image(480, 640, 3)
        wait_until(lambda: cam.image.write(sent) and reader.poll("sample", timeout=0.5), timeout=20,
                   message="the peer never read the image")
        got = reader.events[-1]
        assert (got["height"], got["width"], got["encoding"], got["frame_id"]) == (480, 640, "rgb8", "camera")
        assert got["sha256"] == hashlib.sha256(sent.data.tobytes()).hexdigest()
        stream_peer("write", topic + "/in", "Image",
                    [{"height": 48, "width": 64, "encoding": "rgb8", "channels": 3, "seed": 3}]).next_event("acked")
        (back,) = wait_until(viewer.newest, timeout=20, message="the peer's image never arrived")
        assert type(back) is type(sent) and (back.height, back.width) == (48, 64)
        assert np.array_equal(back.data, image(48, 64, 3).data) and isinstance(back.data, np.ndarray)
    finally:
        for name in list(deployer.streams()):
            deployer.unstream(name)
    assert load("ros2").participants() == {}
