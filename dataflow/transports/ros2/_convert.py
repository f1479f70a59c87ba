"""Between a scart port's type and a ROS 2 message type: how a port's values become
messages of a topic and back (a :class:`Conversion`), planned and type-checked once, when a
stream is made or a composite is loaded (:func:`plan`), never per sample. The same rules
as the ``ros1`` transport's (:mod:`dataflow.transports.ros1.convert`), on ROS 2's types.

Three ways, tried in this order:

* **a converter** the user names (``converter="module:function"``): for a topic scart
  publishes, ``function(value)`` returns the message (a rosbags message of the type, or a
  mapping of its fields, nested mappings and lists allowed); for a topic scart reads,
  ``function(msg)`` is given the rosbags message and returns the port's value (checked by
  the port as any outside input). Its annotations, where given, are checked against the
  port's type and the message type. The module must be imported in this process already:
  a stream, which may be asked for over the network, never makes a process import code
  (a composite's converters are imported at load).
* **a plain type** (``float``, ``int``, ``bool``, ``str``, ``list[float]``, ``list[int]``,
  ``bytes``) onto the ``data`` field (or the only field) of a message: by default
  ``std_msgs/msg/Float64``, ``Int64``, ``Bool``, ``String``, ``Float64MultiArray``,
  ``Int64MultiArray``, ``UInt8MultiArray`` (:data:`PLAIN`); ``std_msgs/msg/Float32``,
  ``Int32``... work too.
* **an array type** (``Array[np.uint8, (480, 640, 3)]``, :mod:`scart_wire.arrays`) onto
  ``sensor_msgs/msg/Image`` when image-shaped, else the ``std_msgs`` multi-array of its
  element type, its shape in the layout (:mod:`._arrays`): as CDR bytes made and read by
  rosbags, the array copied once publishing and a read-only view of the bytes reading.
* **one of rosbags' ROS 2 message classes** (:mod:`scart_wire.rosmsgs`) onto its own type,
  the messages as they are (CDR by rosbags: arrays copied once out, views in).
* **a pydantic model** onto a message **by field names**, recursively (nested models in
  nested messages, lists in sequences). Publishing, every field of the model needs a
  field of that name in the message (the message's others are ROS's zero, and a
  ``header`` the model lacks is stamped with the sample's time and the ``frame_id``
  option); reading, every field the model requires needs one in the message (the
  message's others are ignored). ``builtin_interfaces/msg/Time`` and ``Duration`` are
  float seconds.

Numbers widen (an ``int`` into a ``float64`` field, an ``int32`` into a ``float`` port)
but never narrow (a ``float64`` into an ``int`` port is refused at plan time); a value a
field cannot hold (300 into ``uint8``, a list longer than a bound, a fixed array of
another length) refuses that sample, counted. A :class:`Conversion` is immutable and
thread-safe.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import pydantic
from rosbags.typesys.base import Nodetype

from scart_ros2.errors import UnknownTypeError
from scart_ros2.names import split_type_name
from scart_ros2.msgs import MessageTypes

from .._rosplan import (ConversionProblem, Mismatch, check_converter, is_mapping, is_model, is_open,
                        item_type, model_fields, resolve_converter, type_label, unwrap, RosTime)
from scart_wire.arrays import ArraySpec
from scart_wire.rosmsgs import is_message_class, message_type_name

from ._arrays import default_array_type, plan_array

__all__ = ["PLAIN", "Conversion", "ConversionProblem", "plan", "resolve_converter"]

#: The ROS 2 message a port of a plain type maps onto when the stream names none.
PLAIN: Mapping[object, str] = MappingProxyType({
    float: "std_msgs/msg/Float64", int: "std_msgs/msg/Int64", bool: "std_msgs/msg/Bool", str: "std_msgs/msg/String",
    list[float]: "std_msgs/msg/Float64MultiArray", list[int]: "std_msgs/msg/Int64MultiArray",
    bytes: "std_msgs/msg/UInt8MultiArray"})
INTS = frozenset({"byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"})
FLOATS = frozenset({"float32", "float64"})
OCTETS = frozenset({"byte", "char", "uint8"})
TIMES = frozenset({"builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration"})
HEADER = "std_msgs/msg/Header"
MAX_DEPTH = 16  #: nesting of models/messages followed, at most


@dataclass(frozen=True)
class Conversion:
    """How values of one port type become messages of ``ros_type`` — ``to_idl(value,
    t_ns)``, publishing: the IDL instance to write — or come from them — ``from_idl(obj)``,
    reading: a value (or a mapping of a model's fields) the port's check then validates.
    ``via``: ``data field``, ``field names`` or ``converter module:function``. Each function
    raises (:class:`~._errors.ConversionError`, ``ValueError``...) for a sample that
    cannot be converted."""

    ros_type: str
    via: str
    to_idl: Callable[[object, int], object] | None = None
    from_idl: Callable[[object], object] | None = None
    #: The same, to and from the sample's CDR bytes (arrays: no IDL instance is made).
    to_cdr: Callable[[object, int], object] | None = None
    from_cdr: Callable[[bytes], object] | None = None


def plan(types: MessageTypes, py_type: Any, ros_type: str | None, outgoing: bool, converter: str = "",
         frame_id: str = "") -> tuple[Conversion | None, list[ConversionProblem]]:
    """How values of ``py_type`` cross to ``ros_type`` (``outgoing``: scart publishes) —
    ``ros_type`` None: the default of a plain type — and the problems found (a Conversion
    only when there is no error). ``converter``: ``module:function``; ``frame_id``: the
    ``header.frame_id`` stamped on models without a header."""
    spec = unwrap(py_type)
    if is_message_class(spec):
        return _message_plan(types, spec, ros_type)
    name = ros_type or (default_array_type(spec) if isinstance(spec, ArraySpec)
                        else PLAIN.get(py_type) if _hashable(py_type) else None)
    if not name:
        return None, [ConversionProblem(f"a port of type {type_label(py_type)} has no default ROS 2 type: give the "
                                        "topic's type (e.g. type=\"sensor_msgs/msg/JointState\") and, unless its "
                                        "fields match the model's, a converter")]
    try:
        if split_type_name(name)[1] != "msg":
            raise ValueError(f"{name!r} is a service type; a topic carries a message type (pkg/msg/Type)")
        types.fields(name)
    except (ValueError, UnknownTypeError) as exc:
        return None, [ConversionProblem(str(exc))]
    if converter:
        return _with_converter(types, py_type, name, outgoing, converter)
    if isinstance(spec, ArraySpec):
        planned = plan_array(types, spec, name, outgoing, frame_id)
        if isinstance(planned, ConversionProblem):
            return None, [planned]
        via, fn = planned
        return (Conversion(name, via, to_cdr=fn) if outgoing else Conversion(name, via, from_cdr=fn)), []
    planner = _Planner(types, outgoing)
    try:
        if is_model(py_type):
            fn, via = planner.model(py_type, name, 0), "field names"
        else:
            fn, via = planner.plain(unwrap(py_type), name), "data field"
    except Mismatch as exc:
        return None, [ConversionProblem(str(exc))]
    if not outgoing:
        return Conversion(name, via, from_idl=fn), []
    return Conversion(name, via, to_idl=_stamped(types, name, fn, frame_id, is_model(py_type))), []


def _stamped(types: MessageTypes, name: str, fields_of: Callable[[object], dict[str, object]], frame_id: str,
             model: bool) -> Callable[[object, int], object]:
    """Publishing: the message's fields made, a ``header`` the model lacks stamped with the
    sample's time and ``frame_id``, and the IDL instance built (the library checks every
    value against its field: ranges, bounds, lengths)."""
    stamp = model and dict(types.fields(name)).get("header") == (Nodetype.NAME, HEADER)

    def to_idl(value: object, t_ns: int) -> object:
        fields = fields_of(value)
        if stamp and "header" not in fields:
            fields["header"] = {"stamp": {"sec": t_ns // 1_000_000_000, "nanosec": t_ns % 1_000_000_000},
                                "frame_id": frame_id}
        return types.to_idl(name, fields)

    return to_idl


def _message_plan(types: MessageTypes, cls: type, ros_type: str | None) -> tuple[Conversion | None,
                                                                                list[ConversionProblem]]:
    """A port typed with one of rosbags' ROS 2 message classes: its messages as they are,
    as CDR made and read by rosbags (arrays copied once out, views in); the topic's type is
    the class's own, of the stream's distro."""
    name = ros_type or cls.__msgtype__  # type: ignore[attr-defined]  # a message class
    label = message_type_name(cls)
    try:
        own = types.message_class(name)
    except UnknownTypeError as exc:
        return None, [ConversionProblem(str(exc))]
    if own is not cls:
        return None, [ConversionProblem(f"port type {label} is not the {name} of ROS 2 {types.distro} "
                                        f"({message_type_name(own) if is_message_class(own) else own!r}): give the "
                                        "topic's own type, of that distro")]
    return Conversion(name, "message", to_cdr=lambda value, _t_ns: types.to_cdr(name, value),
                      from_cdr=lambda data: types.from_cdr(name, data)), []


# ---- converters -----------------------------------------------------------------------
def _with_converter(types: MessageTypes, py_type: object, name: str, outgoing: bool,
                    ref: str) -> tuple[Conversion | None, list[ConversionProblem]]:
    try:
        fn = resolve_converter(ref)
    except ValueError as exc:
        return None, [ConversionProblem(str(exc))]
    cls = types.message_class(name)
    problems = check_converter(fn, ref, py_type, name, outgoing, lambda a: a is cls or _is_msg(a, name))
    if any(not p.warning for p in problems):
        return None, problems
    via = f"converter {ref}"
    if not outgoing:
        def from_idl(obj: object) -> object:
            return fn(types.from_idl(name, obj))
        return Conversion(name, via, from_idl=from_idl), problems

    def to_idl(value: object, _t_ns: int) -> object:
        return types.to_idl(name, fn(value))  # a rosbags message, a mapping or an IDL instance
    return Conversion(name, via, to_idl=to_idl), problems


def _is_msg(annotation: object, ros_type: str) -> bool:
    return getattr(annotation, "__msgtype__", None) == ros_type


# ---- plain types and models -----------------------------------------------------------
def _hashable(py_type: object) -> bool:
    try:
        hash(py_type)
    except TypeError:
        return False
    return True


def _names(fields: Iterable[tuple[str, object]]) -> str:
    return ", ".join(name for name, _ in fields) or "none"


class _Planner:
    """Builds the conversion functions of one stream, recursively; raises :class:`Mismatch`.
    Publishing, each function gives what the library's ``to_idl`` takes for that field (a
    mapping for a message); reading, it takes what the IDL instance holds."""

    def __init__(self, types: MessageTypes, outgoing: bool) -> None:
        self.types = types
        self.outgoing = outgoing

    def plain(self, py_type: object, ros_type: str) -> Callable[[object], Any]:  # fields out, a value in
        fields = self.types.fields(ros_type)
        target = next((f for f in fields if f[0] == "data"), fields[0] if len(fields) == 1 else None)
        if target is None:
            raise Mismatch(f"a port of type {type_label(py_type)} maps onto a message with a 'data' field "
                            f"(std_msgs/msg/...), not {ros_type} (fields: {_names(fields)}): give a converter")
        key, desc = target
        try:
            conv = self.field(py_type, desc, 0)
        except Mismatch as exc:
            raise Mismatch(f"port type {type_label(py_type)} vs {ros_type}.{key}: {exc}") from None
        if self.outgoing:
            return lambda value: {key: conv(value)}
        return lambda obj: conv(getattr(obj, key))

    def model(self, model: type[pydantic.BaseModel], ros_type: str, depth: int
              ) -> Callable[[object], dict[str, object]]:
        if depth > MAX_DEPTH:
            raise Mismatch(f"{model.__name__} nests deeper than {MAX_DEPTH} levels")
        fields = dict(self.types.fields(ros_type))
        convs = model_fields(model, ros_type, fields, self.outgoing, lambda t, desc: self.field(t, desc, depth))
        pairs = tuple(convs.items())
        if self.outgoing:
            def to_fields(value: object) -> dict[str, object]:
                if not isinstance(value, model):
                    raise TypeError(f"expected a {model.__name__}, got {type(value).__name__}")
                return {name: conv(getattr(value, name)) for name, conv in pairs}
            return to_fields
        return lambda obj: {name: conv(getattr(obj, name)) for name, conv in pairs}

    # -- one field ------------------------------------------------------------------------
    def field(self, py_type: Any, desc: Any, depth: int) -> Callable[[Any], Any]:
        kind, detail = desc
        if is_open(py_type):
            if self.outgoing:
                raise Mismatch("a field of any type cannot be published: give it a type")
            return _same
        if kind == Nodetype.BASE:
            return self.scalar(py_type, detail[0])
        if kind == Nodetype.NAME:
            return self.message(py_type, detail, depth)
        return self.array(py_type, detail[0], detail[1] if kind == Nodetype.ARRAY else 0, depth)

    def scalar(self, py_type: Any, base: str) -> Callable[[Any], Any]:
        ok = ((base in FLOATS and (py_type is float or (self.outgoing and py_type is int)))
              or (base in INTS and (py_type is int or (not self.outgoing and py_type is float)))
              or (base == "bool" and py_type is bool) or (base == "string" and py_type is str))
        if not ok:
            narrows = (py_type is float and base in INTS) if self.outgoing else (py_type is int and base in FLOATS)
            raise Mismatch(f"{type_label(py_type)} and {base}" + (" (a float never narrows to an integer)"
                                                                   if narrows else ""))
        return float if not self.outgoing and py_type is float and base in INTS else _same

    def message(self, py_type: Any, ros_type: str, depth: int) -> Callable[[Any], Any]:
        if ros_type in TIMES:
            if py_type is float or (self.outgoing and py_type is int):
                return _to_time if self.outgoing else _seconds
            raise Mismatch(f"{type_label(py_type)} and {ros_type} (seconds as a float are needed)")
        if is_model(py_type):
            return self.model(py_type, ros_type, depth + 1)
        if py_type is dict or is_mapping(py_type):
            return _same if self.outgoing else _fields_of
        raise Mismatch(f"{type_label(py_type)} and the message {ros_type} (a model with its fields is needed)")

    def array(self, py_type: Any, inner: Any, count: int, depth: int) -> Callable[[Any], Any]:
        kind, detail = inner
        label = f"{detail if kind == Nodetype.NAME else detail[0]}[{count or ''}]"
        if py_type is bytes and kind == Nodetype.BASE and detail[0] in OCTETS:
            return _same if self.outgoing else bytes
        item = item_type(py_type)
        if item is None:
            raise Mismatch(f"{type_label(py_type)} and {label} (a list is needed)")
        conv = self.field(unwrap(item), inner, depth)
        if conv is _same:
            return _same if self.outgoing else list  # octets arrive as bytes, other sequences as lists
        return lambda values: [conv(v) for v in values]


def _same(value: object) -> object:
    return value


def _to_time(seconds: float) -> dict[str, int]:
    ns = round(seconds * 1e9)
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def _seconds(stamp: RosTime) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def _fields_of(obj: object) -> dict[str, object]:
    """An IDL instance as plain data (a field typed ``dict`` in a model)."""
    out = {}
    for name in getattr(obj, "__annotations__", {}):
        value = getattr(obj, name)
        out[name] = _fields_of(value) if hasattr(value, "__idl_typename__") else value
    return out
