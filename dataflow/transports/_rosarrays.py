"""What the ``ros1`` and ``ros2`` transports share about array ports
(:mod:`scart_wire.arrays`): which message an array maps onto by default, and the
functions between an array and the fields of a rosbags message, which are the same on
both ROS versions (an image's ``height``, ``width``, ``encoding``, ``step`` and ``data``;
a multi-array's ``layout`` and ``data``).

Reading, an array is a read-only view of the message's ``data`` (itself, in rosbags, a
view of the bytes received): no copy. Publishing, the message's ``data`` is a view of
the port's array (a C-contiguous one; another is made contiguous, its one copy), so the
only copy is the serialiser's, into the message's bytes.
"""

from __future__ import annotations

from collections.abc import Callable
from types import MappingProxyType
from typing import Any

import numpy

from scart_wire.arrays import ArraySpec

__all__ = ["ELEMENT", "MULTI", "array_in", "flat_data", "image_data", "image_in", "layout_dims"]

#: The std_msgs multi-array of each element type (its short name: ``Float64MultiArray``).
MULTI = MappingProxyType({"float64": "Float64MultiArray", "float32": "Float32MultiArray", "int64": "Int64MultiArray",
                          "int32": "Int32MultiArray", "int16": "Int16MultiArray", "int8": "Int8MultiArray",
                          "uint64": "UInt64MultiArray", "uint32": "UInt32MultiArray", "uint16": "UInt16MultiArray",
                          "uint8": "UInt8MultiArray"})
#: ROS's element types as numpy's (an array port's element type must be the field's own).
ELEMENT = MappingProxyType({"byte": "int8", "char": "uint8", "bool": "bool"})


def image_data(value: numpy.ndarray) -> tuple[int, numpy.ndarray]:
    """An image array's ``step`` and its bytes as a flat ``uint8`` view (a copy only when
    the array is not C-contiguous)."""
    step = value.strides[0] if value.flags.c_contiguous else value[0].nbytes
    return step, numpy.ascontiguousarray(value).reshape(-1).view(numpy.uint8)


def flat_data(value: object, count: int, label: str) -> numpy.ndarray:
    """An array's values as a flat view (a copy only when it is not C-contiguous);
    ``ValueError`` when ``count`` (a fixed array's length, 0 for none) is not its size."""
    flat = numpy.ascontiguousarray(value).reshape(-1)
    if count and flat.size != count:
        raise ValueError(f"{flat.size} values for a {label}[{count}]")
    return flat


def layout_dims(value: Any) -> list[tuple[int, int]]:  # an array port's value: its shape
    """A multi-array layout's dimensions of ``value``: ``(size, stride)`` each, as ROS
    counts strides (in elements, the whole remaining block)."""
    return [(int(size), int(numpy.prod(value.shape[k:]))) for k, size in enumerate(value.shape)]


def array_in(spec: ArraySpec, layout: bool) -> Callable[[Any], numpy.ndarray]:
    """A multi-array message's data as the port's array: shaped by its layout (else by
    the port's shape), a read-only view of the received bytes."""
    def from_ros(msg: Any) -> numpy.ndarray:  # msg: rosbags' message class, made at run time
        data = msg.data
        shape: tuple[int, ...] | None = None
        if layout and msg.layout.dim:
            offset = int(msg.layout.data_offset)
            shape = tuple(int(d.size) for d in msg.layout.dim)
            data = data[offset:offset + int(numpy.prod(shape))]
        elif spec.shape is not None and len(spec.shape) != 1:
            shape = tuple(-1 if s is None else s for s in spec.shape)
        value = data.reshape(shape) if shape is not None else data
        value.flags.writeable = False
        return value
    return from_ros


def image_in(spec: ArraySpec) -> Callable[[Any], numpy.ndarray]:
    """An image message as the port's array (its ``encoding`` must be the port's): a
    read-only view of the received bytes, rows past ``width`` (a padded ``step``) left out."""
    channels = 1 if spec.shape is None or len(spec.shape) == 2 else spec.shape[2]

    def from_ros(msg: Any) -> numpy.ndarray:  # msg: rosbags' message class, made at run time
        if msg.encoding != spec.image:
            raise ValueError(f"an image of encoding {msg.encoding!r}, not {spec.image!r} ({spec.name})")
        height, width, step = int(msg.height), int(msg.width), int(msg.step)
        rows = msg.data[:height * step].reshape(height, step)  # a view of the received bytes
        row = width * (channels or 1) * numpy.dtype(spec.dtype).itemsize
        value = rows[:, :row].view(spec.dtype)
        value = value.reshape((height, width, channels) if spec.shape is not None and len(spec.shape) == 3
                              else (height, width))
        value.flags.writeable = False
        return value
    return from_ros
