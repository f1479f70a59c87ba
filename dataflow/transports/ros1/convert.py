"""Between a scart port's type and a ROS 1 message type: how a port's values become
messages of a topic and back (a :class:`Conversion`), planned and type-checked once, when a
stream is made or a composite is loaded (:func:`plan`), never per sample.

Three ways, tried in this order:

* **a converter** the user names (``converter="module:function"``): for a topic scart
  publishes, ``function(value)`` returns the message (a message object of the type, or a
  mapping of its fields, nested mappings and lists allowed); for a topic scart reads,
  ``function(msg)`` returns the port's value (checked by the port as any outside input).
  Its annotations, where given, are checked against the port's type. The module must be
  imported in this process already: a stream, which may be asked for over the network,
  never makes a process import code (a composite's converters are imported at load).
* **a plain type** (``float``, ``int``, ``bool``, ``str``, ``list[float]``, ``list[int]``)
  onto the ``data`` field of a ``std_msgs`` wrapper: by default ``std_msgs/Float64``,
  ``Int64``, ``Bool``, ``String``, ``Float64MultiArray``, ``Int64MultiArray``
  (:data:`PLAIN`); another message with a ``data`` field of a fitting type works too
  (``std_msgs/Float32``, ``std_msgs/Int32``...).
* **an array type** (``Array[np.float64, (None, 3)]``, :mod:`scart_wire.arrays`) onto the
  ``data`` array of a ``std_msgs`` multi-array of its element type (``Float64MultiArray``...,
  the default; its ``layout`` gives the shape: written from the array's, read back into
  it), or an image-shaped one (height × width, 1, 3 or 4 channels) onto
  ``sensor_msgs/Image`` (the default for those; its ``encoding`` must be the array's,
  ``rgb8``...). The array is copied once, into the message's bytes, when published, and
  read as a read-only view of the received bytes: numpy from end to end, never a list.
* **one of rosbags' ROS 1 message classes** (:mod:`scart_wire.rosmsgs`) onto its own type,
  the messages as they are (numpy fields and all).
* **a pydantic model** onto a message **by field names**, recursively. Publishing, every
  field of the model needs a field of that name in the message (the message's others
  keep ROS's defaults, and a ``header`` the model lacks is stamped with the sample's write
  number and time); reading, every field the model requires needs one in the message
  (the message's others are ignored). ROS's ``time`` and ``duration`` are float seconds.

Numbers widen (an ``int`` into a ``float64`` field, an ``int32`` into a ``float`` port)
but never narrow (a ``float64`` into an ``int`` port is refused at plan time); a value a
field cannot hold (300 into ``uint8``, a fixed array of another length) refuses that
sample, counted. Everything here is pure; a :class:`Conversion` is immutable and
thread-safe.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy
import pydantic

from scart_wire.arrays import ArraySpec
from scart_wire.rosmsgs import is_message_class, message_type_name

from .._rosarrays import ELEMENT, MULTI, array_in, flat_data, image_data, image_in, layout_dims
from .._rosplan import (ConversionProblem, Mismatch, check_converter, is_mapping, is_model, is_open,
                        item_type, model_fields, resolve_converter, type_label, unwrap, RosTime)
from scart_ros1.msgs import FieldDef, MessageTypes, UnknownTypeError

__all__ = ["PLAIN", "Conversion", "ConversionProblem", "default_type", "field_conversion", "plan", "resolve_converter",
           "type_label"]

#: The std_msgs type a port of a plain type maps onto when the stream names none.
PLAIN = MappingProxyType({float: "std_msgs/Float64", int: "std_msgs/Int64", bool: "std_msgs/Bool",
                          str: "std_msgs/String", list[float]: "std_msgs/Float64MultiArray",
                          list[int]: "std_msgs/Int64MultiArray"})

FLOATS = frozenset({"float32", "float64"})
INTS = frozenset({"int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64", "byte", "char"})
TIMES = frozenset({"time", "duration"})
_DTYPE = MappingProxyType({"byte": "int8", "char": "uint8", "bool": "bool_"})
_NOT_FIELDS = frozenset({"__msgtype__", "structure_needs_at_least_one_member"})  # rosbags' own, not ROS's
MAX_DEPTH = 16  #: nesting of models/messages followed, at most


@dataclass(frozen=True)
class Conversion:
    """How values of one port type become messages of ``ros_type`` (``to_ros(value, n,
    t_ns)``, publishing) or come from them (``from_ros(msg)``, reading). ``via`` says how:
    ``data field``, ``field names`` or ``converter module:function``. Each function raises
    (``ValueError``, ``TypeError``...) for a sample that cannot be converted."""

    ros_type: str
    via: str
    to_ros: Callable[[object, int, int], object] | None = None
    from_ros: Callable[[object], object] | None = None
    #: The same, straight from and to ROS 1 bytes where the message is one fixed field or a
    #: string (``std_msgs/Float64``...): no message object is made (``to_frame`` gives the
    #: whole TCPROS frame, its length first).
    from_bytes: Callable[[bytes], object] | None = None
    to_frame: Callable[[object, int, int], bytes] | None = None


def default_type(py_type: Any) -> str | None:
    """The std_msgs type a port of ``py_type`` maps onto without being told, or None."""
    if isinstance(py_type, ArraySpec):
        return IMAGE if py_type.image else _MULTI.get(py_type.dtype)
    try:
        return PLAIN.get(py_type)
    except TypeError:  # an unhashable annotation
        return None


def plan(types_: MessageTypes, py_type: Any, ros_type: str | None, outgoing: bool, converter: str = "",
         frame_id: str = "") -> tuple[Conversion | None, list[ConversionProblem]]:
    """How values of ``py_type`` cross to ``ros_type`` (``outgoing``: scart publishes) —
    ``ros_type`` None: the default of a plain type — and the problems found (a Conversion
    only when there is no error). ``converter``: ``module:function``; ``frame_id``: the
    ``header.frame_id`` stamped on models without a header."""
    if is_message_class(unwrap(py_type)):
        return _message_plan(types_, unwrap(py_type), ros_type)
    name = ros_type or default_type(py_type)
    if not name:
        return None, [ConversionProblem(f"a port of type {type_label(py_type)} has no default ROS type: give the "
                                        "topic's type (e.g. type=\"sensor_msgs/JointState\") and, unless its "
                                        "fields match the model's, a converter")]
    try:
        types_.msg(name)
    except UnknownTypeError as exc:
        return None, [ConversionProblem(str(exc))]
    if converter:
        return _with_converter(types_, py_type, name, outgoing, converter)
    spec = unwrap(py_type)
    if isinstance(spec, ArraySpec):
        return _array_plan(types_, spec, name, outgoing, frame_id)
    try:
        if is_model(py_type):
            fn = _Planner(types_, outgoing, frame_id).top_model(py_type, name)
            via = "field names"
        else:
            fn = _Planner(types_, outgoing, frame_id).top_plain(py_type, name)
            via = "data field"
    except Mismatch as exc:
        return None, [ConversionProblem(str(exc))]
    fast = _wire_fast(types_, unwrap(py_type), name, outgoing) if via == "data field" else None
    if outgoing:
        return Conversion(name, via, to_ros=fn, to_frame=fast), []
    return Conversion(name, via, from_ros=fn, from_bytes=fast), []


def field_conversion(types_: MessageTypes, py_type: object, fdef: FieldDef, outgoing: bool) -> Callable[[object], object]:
    """How a value of ``py_type`` becomes the field ``fdef`` (``outgoing``) or comes from
    it, as a stream's fields do; raises ``ValueError`` saying why they do not fit."""
    try:
        return _Planner(types_, outgoing, "").field(unwrap(py_type), fdef, 0)
    except Mismatch as exc:
        raise ValueError(str(exc)) from None


# ---- rosbags' own messages ------------------------------------------------------------------
def _message_plan(types_: MessageTypes, cls: Any, ros_type: str | None) -> tuple[Conversion | None,
                                                                               list[ConversionProblem]]:
    """A port typed with one of rosbags' ROS 1 message classes: its messages as they are
    (arrays and all); the topic's type is the class's own."""
    name = ros_type or cls.__msgtype__.replace("/msg/", "/")
    try:
        own = types_.msg(name).cls
    except UnknownTypeError as exc:
        return None, [ConversionProblem(str(exc))]
    if own is not cls:
        return None, [ConversionProblem(f"port type {message_type_name(cls)} is not ROS 1's {name} "
                                        f"({message_type_name(own) if is_message_class(own) else own!r})")]
    return Conversion(name, "message", to_ros=lambda value, _n, _t: value, from_ros=lambda msg: msg), []


# ---- arrays ------------------------------------------------------------------------------
IMAGE = "sensor_msgs/Image"
_MULTI = MappingProxyType({dtype: f"std_msgs/{short}" for dtype, short in MULTI.items()})


def _array_plan(types_: MessageTypes, spec: ArraySpec, name: str, outgoing: bool,
                frame_id: str) -> tuple[Conversion | None, list[ConversionProblem]]:
    """An array port onto an image or a multi-array (see the module docstring)."""
    fields = {f.name: f for f in types_.fields(name)}
    data = fields.get("data")
    if name == IMAGE or (data is not None and "encoding" in fields and "step" in fields):
        if spec.image is None:
            return None, [ConversionProblem(f"{spec.name} is not an image (height x width, 1, 3 or 4 channels of "
                                            f"uint8, uint16 or float32): it cannot be a {name}")]
        if outgoing:
            return Conversion(name, "image", to_ros=_image_out(types_, spec, name, frame_id)), []
        return Conversion(name, "image", from_ros=image_in(spec)), []
    if data is None or data.array is None or data.is_message or ELEMENT.get(data.type, data.type) != spec.dtype:
        found = f"{data.type}[]" if data is not None and data.array is not None else "no data array"
        return None, [ConversionProblem(f"{spec.name} maps onto a message whose 'data' is an array of {spec.dtype} "
                                        f"({_MULTI.get(spec.dtype, 'std_msgs/...MultiArray')}), not {name} "
                                        f"({found})")]
    layout = "layout" in fields and fields["layout"].type == "std_msgs/MultiArrayLayout"
    msgtype = types_.msg(name)
    if outgoing:
        dim_cls = types_.msg("std_msgs/MultiArrayDimension").cls if layout else None
        layout_cls = types_.msg("std_msgs/MultiArrayLayout").cls if layout else None
        cls, count, label = msgtype.cls, data.array or 0, data.type
        rest = {f: v for f, v in ((f.name, getattr(msgtype.new(), f.name)) for f in fields.values())
                if f not in ("data", "layout")}

        def to_ros(value: object, _n: int, _t: int) -> object:
            flat = flat_data(value, count, label)  # a view: the one copy is rosbags'
            if layout_cls is None:
                return cls(**rest, data=flat)
            dims = [dim_cls(label=f"dim{k}", size=size, stride=stride)  # type: ignore[misc]  # set with layout_cls
                    for k, (size, stride) in enumerate(layout_dims(value))]
            return cls(**rest, layout=layout_cls(dim=dims, data_offset=0), data=flat)
        return Conversion(name, "array", to_ros=to_ros), []
    return Conversion(name, "array", from_ros=array_in(spec, layout)), []


def _image_out(types_: MessageTypes, spec: ArraySpec, name: str, frame_id: str) -> Callable[[object, int, int], object]:
    cls = types_.msg(name).cls
    header_cls, time_cls = types_.msg("std_msgs/Header").cls, types_.time_class("time")
    encoding = spec.image

    def to_ros(value: Any, n: int, t_ns: int) -> object:
        height, width = value.shape[:2]
        header = header_cls(seq=n & 0xFFFFFFFF, stamp=time_cls(sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000),
                            frame_id=frame_id)
        step, data = image_data(value)
        return cls(header=header, height=height, width=width, encoding=encoding, is_bigendian=0, step=step, data=data)
    return to_ros


# ---- ROS 1 bytes straight -------------------------------------------------------------
_STRUCT = MappingProxyType({"float64": "d", "float32": "f", "int8": "b", "uint8": "B", "int16": "h",
                            "uint16": "H", "int32": "i", "uint32": "I", "int64": "q", "uint64": "Q",
                            "bool": "?", "byte": "b", "char": "B"})


def _wire_fast(types_: MessageTypes, py_type: object, ros_type: str, outgoing: bool) -> Callable[..., Any] | None:
    """For a message that is one fixed-size field (or one string), the value straight from
    its bytes (reading) or to its frame (publishing); None for any other message. Bytes of
    another length, or a value the field cannot hold, raise (``struct.error``, ``ValueError``)."""
    fields = types_.fields(ros_type)
    if len(fields) != 1 or fields[0].array is not None or py_type not in (float, int, bool, str):
        return None
    t = fields[0].type
    if t == "string" and py_type is str:
        return _string_frame if outgoing else _string_value
    code = _STRUCT.get(t)
    if code is None:
        return None
    if outgoing:
        frame = struct.Struct("<I" + code)
        size = frame.size - 4
        return lambda value, _n, _t: frame.pack(size, value)
    unpack = struct.Struct("<" + code).unpack
    if py_type is float and t not in FLOATS:
        return lambda data: float(unpack(data)[0])
    return lambda data: unpack(data)[0]


def _string_frame(value: str, _n: int, _t: int) -> bytes:
    data = value.encode("utf-8")
    return struct.pack("<II", len(data) + 4, len(data)) + data


def _string_value(data: bytes) -> str:
    (size,) = struct.unpack_from("<I", data)
    if size != len(data) - 4:
        raise ValueError(f"a string of {size} bytes in a {len(data) - 4}-byte message")
    return data[4:].decode("utf-8")


# ---- converters -----------------------------------------------------------------------
def _with_converter(types_: MessageTypes, py_type: object, name: str, outgoing: bool,
                    ref: str) -> tuple[Conversion | None, list[ConversionProblem]]:
    try:
        fn = resolve_converter(ref)
    except ValueError as exc:
        return None, [ConversionProblem(str(exc))]
    problems = check_converter(fn, ref, py_type, name, outgoing, lambda a: a is types_.msg(name).cls)
    if any(not p.warning for p in problems):
        return None, problems
    via = f"converter {ref}"
    if not outgoing:
        return Conversion(name, via, from_ros=fn), problems
    msgtype = types_.msg(name)
    cls, new = msgtype.cls, msgtype.new

    def to_ros(value: object, _n: int, _t_ns: int) -> object:
        msg = fn(value)
        if type(msg) is cls:
            return msg
        if isinstance(msg, Mapping):
            return new(**msg)
        raise TypeError(f"converter {ref} returned a {type(msg).__name__}, not a {name} or a mapping of its fields")

    return Conversion(name, via, to_ros=to_ros), problems


# ---- by field names -------------------------------------------------------------------
class _Planner:
    """Builds the conversion functions of one stream, recursively; raises :class:`Mismatch`."""

    def __init__(self, types_: MessageTypes, outgoing: bool, frame_id: str) -> None:
        self.types = types_
        self.outgoing = outgoing
        self.frame_id = frame_id
        self.time_cls = types_.time_class("time")

    def top_plain(self, py_type: object, ros_type: str) -> Callable[..., object]:
        fields = self.types.fields(ros_type)
        target = next((f for f in fields if f.name == "data"), fields[0] if len(fields) == 1 else None)
        if target is None:
            raise Mismatch(f"a port of type {type_label(py_type)} maps onto a message with a 'data' field "
                            f"(std_msgs/...), not {ros_type} (fields: {_names(fields)}): give a converter")
        try:
            conv = self.field(unwrap(py_type), target, 0)
        except Mismatch as exc:
            raise Mismatch(f"port type {type_label(py_type)} vs {ros_type}.{target.name}: {exc}") from None
        msgtype = self.types.msg(ros_type)
        if not self.outgoing:
            name = target.name
            return lambda msg: conv(getattr(msg, name))
        cls, key = msgtype.cls, target.name
        rest = {f.name: v for f, v in self._defaults(ros_type).items() if f.name != key}
        if not rest:
            return lambda value, _n, _t: cls(**{key: conv(value)})
        return lambda value, _n, _t: cls(**rest, **{key: conv(value)})

    def top_model(self, model: type[pydantic.BaseModel], ros_type: str) -> Callable[..., object]:
        return self.model(model, ros_type, 0)

    def model(self, model: type[pydantic.BaseModel], ros_type: str, depth: int) -> Callable[..., object]:
        if depth > MAX_DEPTH:
            raise Mismatch(f"{model.__name__} nests deeper than {MAX_DEPTH} levels")
        fields = {f.name: f for f in self.types.fields(ros_type)}
        convs = model_fields(model, ros_type, fields, self.outgoing, lambda t, fdef: self.field(t, fdef, depth))
        if not self.outgoing:
            pairs = tuple(convs.items())
            return lambda msg: {name: conv(getattr(msg, name)) for name, conv in pairs}
        return self._to_msg(ros_type, convs, fields, stamped=depth == 0)

    def _to_msg(self, ros_type: str, convs: dict[str, Callable[[object], object]], fields: dict[str, FieldDef],
                stamped: bool) -> Callable[..., object]:
        """A message from a model; a ``header`` the model lacks is stamped (the top level
        only) with the sample's write number, its time and the stream's frame id."""
        cls = self.types.msg(ros_type).cls
        defaults = {f.name: v for f, v in self._defaults(ros_type).items() if f.name not in convs}
        stamp = stamped and "header" in defaults and fields["header"].type == "std_msgs/Header"
        if stamp:
            del defaults["header"]
        pairs = tuple(convs.items())
        header_cls = self.types.msg("std_msgs/Header").cls if stamp else None
        time_cls, frame_id = self.time_cls, self.frame_id

        def build(value: object, n: int = 0, t_ns: int = 0) -> object:
            kwargs = {name: conv(getattr(value, name)) for name, conv in pairs}
            if header_cls is not None:
                kwargs["header"] = header_cls(seq=n & 0xFFFFFFFF, stamp=time_cls(sec=t_ns // 1_000_000_000,
                                              nanosec=t_ns % 1_000_000_000), frame_id=frame_id)
            return cls(**defaults, **kwargs)

        return build

    def _defaults(self, ros_type: str) -> dict[FieldDef, object]:
        """ROS's default of each field of ``ros_type`` (shared: only ever serialised)."""
        msg = self.types.msg(ros_type).new()
        return {f: getattr(msg, f.name) for f in self.types.fields(ros_type)}

    # -- one field ------------------------------------------------------------------------
    def field(self, py_type: object, fdef: FieldDef, depth: int) -> Callable[[object], object]:
        if is_open(py_type):
            if self.outgoing:
                raise Mismatch("a field of any type cannot be published: give it a type")
            return _plain_value
        if fdef.array is None:
            return self.scalar(py_type, fdef, depth)
        return self.array(py_type, fdef, depth)

    def scalar(self, py_type: Any, fdef: FieldDef, depth: int) -> Callable[[Any], Any]:
        t = fdef.type
        if fdef.is_message:
            if is_model(py_type):
                return self.model(py_type, t, depth + 1)
            if py_type is dict or is_mapping(py_type):
                new = self.types.msg(t).new
                return (lambda v: new(**v)) if self.outgoing else _plain_value
            raise Mismatch(f"{type_label(py_type)} and the message {t} (a model with its fields is needed)")
        if t in TIMES:
            if py_type is float or (self.outgoing and py_type is int):
                return self._time_out(t) if self.outgoing else _seconds
            raise Mismatch(f"{type_label(py_type)} and {t} (seconds as a float are needed)")
        ok = ((t in FLOATS and (py_type is float or (self.outgoing and py_type is int)))
              or (t in INTS and (py_type is int or (not self.outgoing and py_type is float)))
              or (t == "bool" and py_type is bool) or (t == "string" and py_type is str))
        if not ok:
            raise Mismatch(f"{type_label(py_type)} and {t}" + (" (a float never narrows to an integer)"
                                                                 if py_type is int and t in FLOATS else ""))
        if not self.outgoing:
            return float if py_type is float and t in INTS else _same
        return _same

    def array(self, py_type: Any, fdef: FieldDef, depth: int) -> Callable[[Any], Any]:
        t, count = fdef.type, fdef.array or 0
        if py_type is bytes and t in ("uint8", "char", "byte"):
            if self.outgoing:
                return _sized(lambda v: numpy.frombuffer(v, dtype=numpy.uint8), count, t)
            return lambda v: bytes(numpy.asarray(v, dtype=numpy.uint8))
        item = item_type(py_type)
        if item is None:
            raise Mismatch(f"{type_label(py_type)} and {t}[{count or ''}] (a list is needed)")
        item = unwrap(item)
        if fdef.is_message or t in TIMES or t == "string":
            conv = self.field(item, FieldDef(fdef.name, t), depth)
            if conv is _same:
                return _sized(list, count, t) if self.outgoing else list
            return _sized(lambda v: [conv(x) for x in v], count, t) if self.outgoing else (lambda v: [conv(x) for x in v])
        self.scalar(item, FieldDef(fdef.name, t), depth)  # the item types fit (raises if not)
        if self.outgoing:
            dtype = numpy.dtype(_DTYPE.get(t, t))
            return _sized(lambda v: numpy.asarray(v, dtype=dtype), count, t)
        if item is float:
            return lambda v: numpy.asarray(v, dtype=numpy.float64).tolist()
        return lambda v: numpy.asarray(v).tolist()

    def _time_out(self, word: str) -> Callable[[Any], Any]:
        cls = self.types.time_class(word)

        def to_time(seconds: float) -> object:
            ns = round(seconds * 1e9)
            return cls(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

        return to_time


def _same(value: object) -> object:
    return value


def _seconds(stamp: RosTime) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def _sized(conv: Callable[[Any], Any], count: int, t: str) -> Callable[[Any], Any]:
    """``conv``, refusing a value that is not ``count`` long when the array is fixed."""
    if not count:
        return conv

    def fixed(value: Any) -> Any:
        if len(value) != count:
            raise ValueError(f"{len(value)} values for a {t}[{count}]")
        return conv(value)

    return fixed


def _plain_value(value: object) -> object:
    """A message (or part of one) as plain data: mappings, lists, numbers, strings."""
    if isinstance(value, numpy.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain_value(v) for v in value]
    fields = getattr(value, "__dataclass_fields__", None)
    if fields is not None:
        return {name: _plain_value(getattr(value, name)) for name in fields if name not in _NOT_FIELDS}
    return value


def _names(fields: Iterable[FieldDef]) -> str:
    return ", ".join(f.name for f in fields) or "none"
