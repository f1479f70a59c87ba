"""Array ports (:mod:`scart_wire.arrays`) as ROS 2 messages: an image-shaped array as
``sensor_msgs/msg/Image`` (its ``encoding`` the array's: ``rgb8``...), any array as the
``std_msgs`` multi-array of its element type with its shape in the ``layout`` (written
from the array's, read back into it), or as another message whose ``data`` is an array
of that element type.

They cross as CDR made and read by rosbags (:meth:`MessageTypes.to_cdr`,
:meth:`~MessageTypes.from_cdr`), written and taken as bytes: publishing copies the array
once, into the sample's bytes; reading gives a read-only view of the bytes received.
Cyclone's Python serialiser is not used for them: it packs a ``uint8[]`` value by value
(0.2 s for one 6 MB frame) and unpacks it into a list.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rosbags.typesys.base import Nodetype

from scart_wire.arrays import ArraySpec

from scart_ros2.msgs import MessageTypes

from .._rosarrays import ELEMENT, MULTI, array_in, flat_data, image_data, image_in, layout_dims
from .._rosplan import ConversionProblem

__all__ = ["IMAGE", "default_array_type", "plan_array"]

IMAGE = "sensor_msgs/msg/Image"
LAYOUT = "std_msgs/msg/MultiArrayLayout"


def default_array_type(spec: ArraySpec) -> str | None:
    """The ROS 2 message an array port maps onto without being told, or None."""
    if spec.image:
        return IMAGE
    short = MULTI.get(spec.dtype)
    return f"std_msgs/msg/{short}" if short else None


def plan_array(types: MessageTypes, spec: ArraySpec, name: str, outgoing: bool,
               frame_id: str) -> tuple[str, Callable[..., object]] | ConversionProblem:
    """How arrays of ``spec`` cross to message ``name`` (see the module docstring): how
    (``image`` or ``array``) and the function (publishing, ``to_cdr(value, t_ns)``;
    reading, ``from_cdr(data)``), or the problem."""
    fields = dict(types.fields(name))
    data = fields.get("data")
    if name == IMAGE or (data is not None and "encoding" in fields and "step" in fields):
        if spec.image is None:
            return ConversionProblem(f"{spec.name} is not an image (height x width, 1, 3 or 4 channels of "
                                     f"uint8, uint16 or float32): it cannot be a {name}")
        if outgoing:
            return "image", _image_out(types, spec, name, frame_id)
        return "image", _from_cdr(types, name, image_in(spec))
    element, count = _data_array(data)
    if element is None or ELEMENT.get(element, element) != spec.dtype:
        found = f"{element}[]" if element is not None else "no data array"
        default = default_array_type(spec) if not spec.image else None
        return ConversionProblem(f"{spec.name} maps onto a message whose 'data' is an array of {spec.dtype} "
                                 f"({default or 'std_msgs/msg/...MultiArray'}), not {name} ({found})")
    layout = fields.get("layout") == (Nodetype.NAME, LAYOUT)
    if outgoing:
        return "array", _array_out(types, name, layout, count, element)
    return "array", _from_cdr(types, name, array_in(spec, layout))


def _data_array(desc: Any) -> tuple[str | None, int]:
    """The element type of a ``data`` field that is an array or sequence of a base type,
    and its fixed length (0 for a sequence); ``(None, 0)`` for another field."""
    if desc is None or desc[0] not in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return None, 0
    inner, size = desc[1]
    if inner[0] != Nodetype.BASE:
        return None, 0
    return inner[1][0], size if desc[0] == Nodetype.ARRAY else 0


def _from_cdr(types: MessageTypes, name: str, value_of: Callable[[Any], Any]) -> Callable[[Any], Any]:
    return lambda data: value_of(types.from_cdr(name, data))


def _image_out(types: MessageTypes, spec: ArraySpec, name: str, frame_id: str) -> Callable[[object, int], object]:
    cls = types.message_class(name)
    header_cls, time_cls = types.message_class("std_msgs/msg/Header"), types.message_class("builtin_interfaces/msg/Time")
    encoding = spec.image

    def to_cdr(value: Any, t_ns: int) -> Any:
        height, width = value.shape[:2]
        header = header_cls(stamp=time_cls(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000),
                            frame_id=frame_id)
        step, data = image_data(value)
        return types.to_cdr(name, cls(header=header, height=height, width=width, encoding=encoding, is_bigendian=0,
                                      step=step, data=data))
    return to_cdr


def _array_out(types: MessageTypes, name: str, layout: bool, count: int, element: str) -> Callable[[object, int], object]:
    cls = types.message_class(name)
    zero = types.zero(name)
    rest = {f: getattr(zero, f) for f, _ in types.fields(name) if f not in ("data", "layout")}
    dim_cls = types.message_class("std_msgs/msg/MultiArrayDimension")
    layout_cls = types.message_class(LAYOUT)

    def to_cdr(value: object, _t_ns: int) -> object:
        flat = flat_data(value, count, element)  # a view: the one copy is the serialiser's
        if not layout:
            return types.to_cdr(name, cls(**rest, data=flat))
        dims = [dim_cls(label=f"dim{k}", size=size, stride=stride) for k, (size, stride) in enumerate(layout_dims(value))]
        return types.to_cdr(name, cls(**rest, layout=layout_cls(dim=dims, data_offset=0), data=flat))
    return to_cdr
