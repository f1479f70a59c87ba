"""Array ports on ROS 1 (the conversion, planned once and checked): an image array is a
``sensor_msgs/Image`` and any array a ``std_msgs`` multi-array of its element type, with
its shape in the layout; published with one copy (into the message's bytes), read as a
read-only view of the bytes received — numpy end to end, never a list."""

from __future__ import annotations

import numpy as np
import pytest

from dataflow import Array
from scart_ros1 import MessageTypes
from dataflow.transports.ros1.convert import default_type, plan

IMAGE = Array[np.uint8, (480, 640, 3)]
GRID = Array[np.float64, (None, 4)]


@pytest.fixture(scope="module")
def ros_types() -> MessageTypes:
    return MessageTypes()


def _both(ros_types: MessageTypes, spec, ros_type: str | None = None):
    out, problems = plan(ros_types, spec, ros_type, outgoing=True)
    back, more = plan(ros_types, spec, ros_type, outgoing=False)
    assert out is not None and back is not None, problems + more
    return out, back


def test_an_image_array_is_a_sensor_msgs_image_copied_once_out_and_viewed_in(ros_types: MessageTypes) -> None:
    assert default_type(IMAGE) == "sensor_msgs/Image"
    out, back = _both(ros_types, IMAGE)
    frame = np.random.default_rng(3).integers(0, 255, (480, 640, 3), dtype=np.uint8)
    msg = out.to_ros(frame, 7, 1_500_000_000)
    assert (msg.height, msg.width, msg.encoding, msg.step) == (480, 640, "rgb8", 1920)
    assert (msg.header.seq, msg.header.stamp.sec, msg.header.stamp.nanosec) == (7, 1, 500_000_000)
    assert np.shares_memory(msg.data, frame)  # no copy before rosbags writes the message's bytes
    wire = ros_types.msg("sensor_msgs/Image").serialize(msg)
    got = back.from_ros(ros_types.msg("sensor_msgs/Image").deserialize(wire))
    assert got.shape == (480, 640, 3) and np.array_equal(got, frame) and not got.flags.writeable
    assert np.shares_memory(got, np.frombuffer(wire, dtype=np.uint8))  # a view of the bytes received
    mono = ros_types.msg("sensor_msgs/Image").new(height=2, width=2, encoding="mono8", step=2, data=[1, 2, 3, 4])
    with pytest.raises(ValueError, match="encoding 'mono8', not 'rgb8'"):
        back.from_ros(mono)


def test_an_array_is_a_multi_array_of_its_element_type_with_its_shape_in_the_layout(ros_types: MessageTypes) -> None:
    assert default_type(GRID) == "std_msgs/Float64MultiArray"
    assert default_type(Array[np.int32, (8,)]) == "std_msgs/Int32MultiArray"
    out, back = _both(ros_types, GRID)
    grid = np.arange(12, dtype=np.float64).reshape(3, 4)
    msg = out.to_ros(grid, 1, 1)
    assert [(d.size, d.stride) for d in msg.layout.dim] == [(3, 12), (4, 4)]
    wire = ros_types.msg("std_msgs/Float64MultiArray").serialize(msg)
    got = back.from_ros(ros_types.msg("std_msgs/Float64MultiArray").deserialize(wire))
    assert got.shape == (3, 4) and np.array_equal(got, grid) and not got.flags.writeable
    flat = ros_types.msg("std_msgs/Float64MultiArray").new(data=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0])
    assert back.from_ros(flat).shape == (2, 4)  # no layout: the port's shape says how


def test_arrays_that_do_not_fit_the_message_are_refused_when_planned(ros_types: MessageTypes) -> None:
    for spec, ros_type, said in ((Array[np.float32, (None,)], "std_msgs/Float64MultiArray", "an array of float32"),
                                 (GRID, "sensor_msgs/Image", "is not an image"),
                                 (IMAGE, "std_msgs/Float64", "'data' is an array of uint8")):
        conv, problems = plan(ros_types, spec, ros_type, outgoing=True)
        assert conv is None and said in problems[0].message, problems
