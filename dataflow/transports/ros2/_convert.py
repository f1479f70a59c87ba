"""How a scart port's values become ROS 2 messages and back: planned and type-checked once,
when a stream is declared (``<scart:stream>`` at load) or made, then applied per sample.

======================================  ===================================================
the port's type                         the ROS 2 message (``type`` option)
======================================  ===================================================
``int`` / ``float`` / ``bool`` / ``str``  its ``data`` field; default ``std_msgs/msg/Int64``,
                                        ``Float64``, ``Bool``, ``String``
``list[float]`` / ``list[int]``         ``data`` (a sequence); default
                                        ``std_msgs/msg/Float64MultiArray`` / ``Int64MultiArray``
``bytes``                               ``data`` (octets); default ``std_msgs/msg/UInt8MultiArray``
a pydantic model                        **by field names**: each field of the model has a
                                        namesake in the message (nested models in nested
                                        messages, lists in sequences); the message's other
                                        fields are ROS's zero going out, ignored coming in
anything, with ``converter=mod:func``   ``func(value) -> message`` out of an output port
                                        (a rosbags message of the type, or a mapping of its
                                        fields); ``func(message) -> value`` into an input
                                        port (given the rosbags message)
======================================  ===================================================

The checks, each a :class:`~dataflow.transports.StreamProblem` with its code: a type name
that is not ROS 2's (``pkg/msg/Type``) or not known, a converter that cannot be imported
or does not take one argument (``SCART-T005``); a field whose types cannot carry each
other, a model field without a namesake, a converter whose annotations disagree with the
port's type or the message's (``SCART-B002``, the bridge's code); a converter without
annotations is a warning. Widening is allowed, narrowing is not: an ``int`` port may
publish into a ``float64`` field and read an ``int32`` one, a ``float`` port never fills an
integer field. A value the message cannot hold (an integer out of its range, a list
longer than its bound, a converter that raises) is refused per sample
(:class:`ConversionError`) and counted by the stream.
"""

from __future__ import annotations

import collections.abc
import importlib
import inspect
import types as pytypes
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import pydantic
from rosbags.typesys.base import Nodetype

from dataflow.errors import CONVERT_TYPE, STREAM
from dataflow.transports import StreamProblem

from ._errors import ConversionError
from ._names import split_type_name
from ._types import MessageTypes

__all__ = ["Conversion", "PLAIN_TYPES", "import_ref", "plan"]

#: The ROS 2 message a port of a plain type maps onto when the stream names none.
PLAIN_TYPES: Mapping[Any, str] = MappingProxyType({
    int: "std_msgs/msg/Int64", float: "std_msgs/msg/Float64", bool: "std_msgs/msg/Bool", str: "std_msgs/msg/String",
    list[float]: "std_msgs/msg/Float64MultiArray", list[int]: "std_msgs/msg/Int64MultiArray",
    bytes: "std_msgs/msg/UInt8MultiArray"})
_INTS = frozenset({"byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64"})
_OCTETS = frozenset({"byte", "char", "uint8"})
_FLOATS = frozenset({"float32", "float64"})
_UNKNOWN: Any = None
_Conv = Callable[[Any], Any]


@dataclass(frozen=True)
class Conversion:
    """A port's values as one ROS 2 message type: ``to_idl(value)`` (out of an output
    port: the IDL instance to write) or ``from_idl(obj)`` (into an input port: a value
    the port's check then validates). Both raise :class:`ConversionError` for a value
    that cannot be carried. ``how``: ``data``, ``fields`` or ``converter``."""

    ros_type: str
    how: str
    to_idl: _Conv
    from_idl: _Conv


def import_ref(ref: str) -> object:
    """``module:attr`` imported (``importlib``); raises ``ValueError``/``ImportError``/``AttributeError``."""
    module, colon, attr = ref.partition(":")
    if not colon or not module or not attr:
        raise ValueError(f"{ref!r} is not of the form 'module:function'")
    obj: object = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def plan(port_type: Any, inbound: bool, types: MessageTypes, ros_type: str | None = None,
         converter: str | None = None, importer: Callable[[str], object] | None = None,
         ) -> tuple[Conversion | None, list[StreamProblem]]:
    """The conversion of a port of ``port_type`` (``inbound``: an input port fed from the
    topic) to ``ros_type`` (default: the plain type's, see :data:`PLAIN_TYPES`), through
    ``converter`` if given; and the problems found (None when any is an error)."""
    problems: list[StreamProblem] = []
    name = ros_type or PLAIN_TYPES.get(port_type)
    if name is None:
        return None, [StreamProblem(STREAM, f"a {_shown(port_type)} port needs type=pkg/msg/Type (the ROS 2 "
                                            "message type); only plain types have a default")]
    try:
        split_type_name(name)
        if split_type_name(name)[1] != "msg":
            raise ValueError(f"{name!r} is a service type; a topic carries a message type (pkg/msg/Type)")
    except ValueError as exc:
        return None, [StreamProblem(STREAM, str(exc))]
    if not types.has(name):
        return None, [StreamProblem(STREAM, f"unknown ROS 2 message type {name!r} (ROS 2 {types.distro})")]
    if converter:
        conv = _by_converter(port_type, inbound, types, name, converter, importer or import_ref, problems)
    elif _is_model(port_type):
        conv = _by_fields(port_type, inbound, types, name, problems)
    else:
        conv = _by_data(port_type, inbound, types, name, problems)
    if any(not p.warning for p in problems):
        return None, problems
    return conv, problems


# --- plain types: the message's data field ------------------------------------------------

def _by_data(port_type: Any, inbound: bool, types: MessageTypes, name: str,
             problems: list[StreamProblem]) -> Conversion | None:
    fields = dict(types.fields(name))
    desc = fields.get("data")
    if desc is None:
        problems.append(StreamProblem(CONVERT_TYPE, f"a {_shown(port_type)} port maps onto a message's data field; "
                                                    f"{name} has none (fields: {', '.join(fields) or 'none'}): give "
                                                    "converter=module:function"))
        return None
    why = _fits(port_type, desc, inbound, types, f"{name}.data")
    if why:
        problems.append(StreamProblem(CONVERT_TYPE, f"a {_shown(port_type)} port cannot {_verb(inbound)} {why}"))
        return None
    if inbound:
        take = _from_member(port_type, desc, types)
        return Conversion(name, "data", _refuse_out, lambda obj: take(obj.data))

    def to_idl(value: Any) -> Any:
        return types.to_idl(name, {"data": value})
    return Conversion(name, "data", to_idl, _refuse_in)


# --- pydantic models: by field names ------------------------------------------------------

def _by_fields(model: Any, inbound: bool, types: MessageTypes, name: str,
               problems: list[StreamProblem]) -> Conversion | None:
    before = len(problems)
    _check_model(model, name, inbound, types, problems, name)
    if len(problems) > before:
        return None
    if inbound:
        take = _from_model(model, name, types)
        return Conversion(name, "fields", _refuse_out, take)
    give = _to_model_fields(model, types, name)

    def to_idl(value: Any) -> Any:
        return types.to_idl(name, give(value))
    return Conversion(name, "fields", to_idl, _refuse_in)


def _check_model(model: Any, name: str, inbound: bool, types: MessageTypes, problems: list[StreamProblem],
                 where: str) -> None:
    fields = dict(types.fields(name))
    for field, info in model.model_fields.items():
        desc = fields.get(field)
        if desc is None:
            problems.append(StreamProblem(CONVERT_TYPE, f"{_shown(model)}.{field} has no namesake in {where} "
                                                        f"({name}: {', '.join(fields) or 'no fields'}): give "
                                                        "converter=module:function"))
            continue
        why = _fits(info.annotation, desc, inbound, types, f"{where}.{field}")
        if why:
            problems.append(StreamProblem(CONVERT_TYPE, f"{_shown(model)}.{field} ({_shown(info.annotation)}) "
                                                        f"cannot {_verb(inbound)} {why}"))


def _to_model_fields(model: Any, types: MessageTypes, name: str) -> _Conv:
    """A model instance as the mapping of its message's fields (nested models too)."""
    fields = dict(types.fields(name))
    parts = {f: _to_member(info.annotation, fields[f], types) for f, info in model.model_fields.items()}

    def give(value: Any) -> dict[str, Any]:
        if not isinstance(value, model):
            raise ConversionError(f"expected a {_shown(model)}, got {type(value).__name__}")
        return {f: conv(getattr(value, f)) for f, conv in parts.items()}
    return give


def _to_member(tp: Any, desc: Any, types: MessageTypes) -> _Conv:
    kind, detail = desc
    if kind == Nodetype.NAME and _is_model(tp):
        return _to_model_fields(tp, types, detail)
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and detail[0][0] == Nodetype.NAME:
        item = _to_member(_item_type(tp), detail[0], types)
        return lambda values: [item(v) for v in values]
    return _same


def _from_model(model: Any, name: str, types: MessageTypes) -> _Conv:
    """An IDL instance as the mapping of ``model``'s fields (the port's check validates it)."""
    fields = dict(types.fields(name))
    parts = {f: _from_member(info.annotation, fields[f], types) for f, info in model.model_fields.items()}

    def take(obj: Any) -> dict[str, Any]:
        return {f: conv(getattr(obj, f)) for f, conv in parts.items()}
    return take


def _from_member(tp: Any, desc: Any, types: MessageTypes) -> _Conv:
    kind, detail = desc
    if kind == Nodetype.NAME and _is_model(tp):
        return _from_model(tp, detail, types)
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        inner = detail[0]
        if inner[0] == Nodetype.NAME:
            item = _from_member(_item_type(tp), inner, types)
            return lambda values: [item(v) for v in values]
        if tp is bytes:
            return bytes
        return list  # octets arrive as bytes, other sequences as lists: a list either way
    return _same


# --- a converter ----------------------------------------------------------------------------

def _by_converter(port_type: Any, inbound: bool, types: MessageTypes, name: str, ref: str,
                  importer: Callable[[str], object], problems: list[StreamProblem]) -> Conversion | None:
    try:
        fn = importer(ref)
    except Exception as exc:  # noqa: BLE001 - any import failure is the declaration's problem
        problems.append(StreamProblem(STREAM, f"converter {ref!r} cannot be imported: {type(exc).__name__}: {exc}"))
        return None
    if not callable(fn):
        problems.append(StreamProblem(STREAM, f"converter {ref!r} is not callable"))
        return None
    params, hints = _hints(fn)
    required = [p for p in params if p.default is inspect.Parameter.empty
                and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    if not params or len(required) > 1:
        problems.append(StreamProblem(STREAM, f"converter {ref} must take one argument (the "
                                              f"{'message' if inbound else 'sample'})"))
        return None
    takes, gives = hints.get(params[0].name, _UNKNOWN), hints.get("return", _UNKNOWN)
    if inbound:  # message -> converter -> the port
        port_ok, port_side, port_what, msg_side, msg_what = _same_type(gives, port_type), gives, "returns", takes, "takes"
    else:  # the port -> converter -> message
        port_ok, port_side, port_what, msg_side, msg_what = _same_type(port_type, takes), takes, "takes", gives, "returns"
    if not port_ok:
        problems.append(StreamProblem(CONVERT_TYPE, f"converter {ref} {port_what} {_shown(_plain(port_side))}, but "
                                                    f"the port is {_shown(port_type)}"))
    msgtype = getattr(_plain(msg_side), "__msgtype__", None)
    if msgtype is not None and msgtype != name:
        problems.append(StreamProblem(CONVERT_TYPE, f"converter {ref} {msg_what} {msgtype}, but the stream's type "
                                                    f"is {name}"))
    missing = [w for w, n in (("parameter", params[0].name), ("return", "return")) if n not in hints]
    if missing:
        problems.append(StreamProblem(STREAM, f"converter {ref} has no type annotation on its "
                                              f"{' and '.join(missing)}: what it is given and gives is not checked "
                                              "at load; annotate it", warning=True))
    call = typing.cast(_Conv, fn)
    if inbound:
        def from_idl(obj: Any) -> Any:
            message = types.from_idl(name, obj)
            try:
                return call(message)
            except Exception as exc:  # noqa: BLE001 - the converter's: this sample is refused
                raise ConversionError(f"converter {ref} raised {type(exc).__name__}: {exc}") from None
        return Conversion(name, "converter", _refuse_out, from_idl)

    def to_idl(value: Any) -> Any:
        try:
            message = call(value)
        except Exception as exc:  # noqa: BLE001 - the converter's: this sample is refused
            raise ConversionError(f"converter {ref} raised {type(exc).__name__}: {exc}") from None
        return types.to_idl(name, message)
    return Conversion(name, "converter", to_idl, _refuse_in)


def _hints(fn: Any) -> tuple[list[inspect.Parameter], dict[str, Any]]:
    try:
        hints = typing.get_type_hints(fn)
    except Exception:  # noqa: BLE001 - unresolvable annotations: unchecked
        hints = {}
    try:
        params = list(inspect.signature(fn).parameters.values())
    except (TypeError, ValueError):
        params = []
    return params, hints


# --- whether a Python type and a ROS field carry each other ---------------------------------

def _fits(tp: Any, desc: Any, inbound: bool, types: MessageTypes, where: str) -> str | None:
    """Why values of ``tp`` cannot go into (``inbound``: come from) the ROS field ``desc``
    at ``where``; None when they can."""
    kind, detail = desc
    if kind == Nodetype.BASE:
        base = detail[0]
        if _base_fits(tp, base, inbound):
            return None
        return f"{'from' if inbound else 'into'} {where} ({base})"
    if kind == Nodetype.NAME:
        if not _is_model(tp):
            return f"{'from' if inbound else 'into'} {where} (a {detail} message): map it with a pydantic model " \
                   "of its fields or a converter"
        problems: list[StreamProblem] = []
        _check_model(tp, detail, inbound, types, problems, where)
        return "; ".join(p.message for p in problems) or None
    inner = detail[0]
    if tp is bytes and inner[0] == Nodetype.BASE and inner[1][0] in _OCTETS:
        return None
    origin = typing.get_origin(tp) or tp
    if origin not in (list, tuple, collections.abc.Sequence):
        size = f"[{detail[1]}]" if kind == Nodetype.ARRAY else "[]"
        return f"{'from' if inbound else 'into'} {where} (a sequence{size}): the port's field is no list"
    return _fits(_item_type(tp), inner, inbound, types, f"{where}[]")


def _base_fits(tp: Any, base: str, inbound: bool) -> bool:
    if base == "bool":
        return tp is bool
    if base == "string":
        return tp is str
    if base in _INTS:
        return tp is int or (inbound and tp is float)  # an integer widens to a float, never back
    if base in _FLOATS:
        return tp is float or (not inbound and tp is int)
    return False  # wstring, wchar: not carried


def _item_type(tp: Any) -> Any:
    args = [a for a in typing.get_args(tp) if a is not Ellipsis]
    return args[0] if len(set(args)) == 1 else _UNKNOWN


def _is_model(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, pydantic.BaseModel)


def _plain(tp: Any) -> Any:
    """``T | None`` → ``T``; ``Any``/missing → unknown."""
    if tp in (None, inspect.Parameter.empty, Any, object):
        return _UNKNOWN
    if typing.get_origin(tp) in (typing.Union, pytypes.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return _plain(args[0]) if len(args) == 1 else _UNKNOWN
    return tp


def _same_type(given: Any, wanted: Any) -> bool:
    """Can values of ``given`` stand where ``wanted`` is declared? (The bridge's rule:
    unknown is compatible, an int may stand for a float, a subclass for its base, lists
    compare their items; a mapping or a message class on the ROS side is not compared.)"""
    given, wanted = _plain(given), _plain(wanted)
    if given is _UNKNOWN or wanted is _UNKNOWN or given == wanted or (given is int and wanted is float):
        return True
    g_args, w_args = typing.get_args(given), typing.get_args(wanted)
    g_origin, w_origin = typing.get_origin(given) or given, typing.get_origin(wanted) or wanted
    if not g_args and not w_args:
        return isinstance(given, type) and isinstance(wanted, type) and issubclass(given, wanted) \
            and given is not bool
    sequences = (list, tuple, collections.abc.Sequence)
    if not (g_origin in sequences and w_origin in sequences):
        return False
    if not g_args or not w_args:
        return True
    return _same_type(_item_type(given), _item_type(wanted))


def _shown(tp: Any) -> str:
    if tp is _UNKNOWN:
        return "unknown"
    if isinstance(tp, type) and typing.get_origin(tp) is None:
        return tp.__name__
    return str(tp).replace("typing.", "")


def _verb(inbound: bool) -> str:
    return "be fed" if inbound else "be published"


def _same(value: Any) -> Any:
    return value


def _refuse_in(obj: Any) -> Any:
    raise ConversionError("this conversion publishes an output port; it reads nothing")


def _refuse_out(value: Any) -> Any:
    raise ConversionError("this conversion feeds an input port; it publishes nothing")
