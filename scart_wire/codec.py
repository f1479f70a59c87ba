"""The one codec between Python values and the wire's ``scart.dataflow.v1.Value``.

Every value that crosses a process (port samples, properties, operation arguments and
results, binding.grpc calls) goes through :func:`encode` and :func:`decode`:

================  ===========================================================
type name         what it holds
================  ===========================================================
``""``            ``None``
registered name   a value of a registered type, encoded by :data:`scart_wire.types.registry`
                  (``float64``, ``float64[]``, pydantic models...; see
                  :mod:`scart_wire.types`)
``scart.json``    JSON text, for a value the registry has no name for (a dict, a
                  mixed list, a list of models, an int beyond int64)
anything else     decodes to :class:`~scart_wire.types.UnknownValue`, a mapping that
                  keeps its type name: never an error
================  ===========================================================

``encode(value, py_type)`` with a port's or property's type encodes the value as that
type (the data-flow side, where types are declared). Without one, the value's own type
decides, as in the table. inf and NaN survive both ways.

Importing this module imports protobuf (the ``Value`` message class), never grpc.
"""

from __future__ import annotations

import struct
from types import MappingProxyType
from typing import Any

import pydantic
import pydantic_core

from scart_wire import rosmsgs
from scart_wire.arrays import ArraySpec
from scart_wire.errors import PortTypeError
from scart_wire.proto.scart.dataflow.v1.value_pb2 import Value
from scart_wire.types import UnknownValue, model_json, registry

__all__ = ["FLOAT_LIST", "JSON_TYPE", "NONE_TYPE", "Payload", "Value", "decode", "encode"]

NONE_TYPE = ""
JSON_TYPE = "scart.json"
FLOAT_LIST = registry.type_name(list[float])  # "float64[]": packed little-endian doubles

_PLAIN = (float, int, bool, str, bytes)
#: A number written to a port of its own type, without the registry's lookups (the hot case).
_NUMBER = MappingProxyType({float: (registry.type_name(float), struct.Struct("<d").pack),
                            int: (registry.type_name(int), struct.Struct("<q").pack)})
_UNPACK = MappingProxyType({registry.type_name(float): struct.Struct("<d").unpack,
                            registry.type_name(int): struct.Struct("<q").unpack})
#: A registered model class → its name and serializer's ``to_json``; its name → its
#: validator's ``validate_json``. The registry fills them at a class's first encode and a
#: name's first decode; later samples skip its lookups: the same serializer and check.
_MODEL_OUT = registry.model_encoders
_MODEL_IN = registry.model_decoders


def encode(value: Any, py_type: object = None) -> Value:  # Any: narrowed by its exact type
    """``value`` as a ``Value`` message (as ``py_type`` when given, see the module docstring).

    Raises :class:`~scart_wire.errors.PortTypeError` naming the type when the value cannot be sent."""
    if value is None:
        return Value(type_name=NONE_TYPE)
    try:
        if type(value) is py_type:  # a port's own type: the hot cases without the registry's lookups
            if py_type in _NUMBER:
                name, pack = _NUMBER[py_type]
                return Value(type_name=name, data=pack(value))
            if py_type in _MODEL_OUT:
                name, to_json = _MODEL_OUT[py_type]
                data = to_json(value)  # as model_json (find, not `in`): null may be inf or NaN, made again
                return Value(type_name=name, data=data if data.find(b"null") < 0 else model_json(value))
        if py_type is not None:
            enc = registry.encode(value, py_type)
            return Value(type_name=enc.type_name, data=enc.data)
        return _encode_untyped(value)
    except (struct.error, OverflowError):  # e.g. an int beyond int64: JSON has no such limit
        return _json(value)


def _encode_untyped(value: Any) -> Value:
    kind = type(value)
    if kind in _PLAIN or isinstance(value, (pydantic.BaseModel, UnknownValue)) or \
            (kind.__name__ == "ndarray" and kind.__module__ == "numpy"):
        enc = registry.encode(value)
        return Value(type_name=enc.type_name, data=enc.data)
    if kind is list or kind is tuple:
        if value and type(value[0]) is float:  # the hot case (joint vectors...): pack directly
            try:
                return Value(type_name=FLOAT_LIST, data=struct.pack(f"<{len(value)}d", *value))
            except struct.error:  # not all numbers: the general path below
                pass
        list_type = _list_type(value)
        if list_type is not None:
            enc = registry.encode(list(value), list_type)
            return Value(type_name=enc.type_name, data=enc.data)
    elif registry.python_type(registry.type_name(kind)) is kind:
        enc = registry.encode(value)
        return Value(type_name=enc.type_name, data=enc.data)
    return _json(value)


def _json(value: object) -> Value:
    try:
        return Value(type_name=JSON_TYPE, data=pydantic_core.to_json(value, inf_nan_mode="constants"))
    except pydantic_core.PydanticSerializationError as exc:
        raise PortTypeError(f"cannot encode a value of type {type(value).__qualname__}: {exc}") from None


def _list_type(value: list[object] | tuple[object, ...]) -> object:
    if not value:
        return list[float]
    first = type(value[0])
    if first in (float, int, str) and all(type(v) is first for v in value):
        return {float: list[float], int: list[int], str: list[str]}[first]
    return None


class Payload:
    """A value's type name and its bytes held elsewhere than in a ``Value`` message: a
    buffer (shared memory) that a decoded array keeps alive and views without a copy."""

    __slots__ = ("type_name", "data")

    def __init__(self, type_name: str, data: Any) -> None:  # Any: a buffer (shm's memoryview, bytes)
        self.type_name = type_name
        self.data = data


def decode(msg: Value | Payload) -> Any:
    """The Python value of a ``Value`` message (see the module docstring), or of a
    :class:`Payload`: an array type's value is then a read-only view of its buffer, any
    other type's is made of a copy of the bytes.

    Raises :class:`~scart_wire.errors.PortTypeError` when the bytes do not fit their type name."""
    if type(msg) is Payload:
        spec = registry.python_type(msg.type_name)
        if isinstance(spec, ArraySpec) or rosmsgs.is_message_class(spec):
            try:  # a view of the buffer: no copy
                return spec.decode(msg.data) if isinstance(spec, ArraySpec) else rosmsgs.decode(spec, msg.data)
            except ValueError as exc:
                raise PortTypeError(f"cannot decode {msg.type_name}: {exc}") from None
        msg = Value(type_name=msg.type_name, data=bytes(msg.data))
    name = msg.type_name
    if name in _UNPACK:  # a number, without the registry's lookups (the hot case)
        try:
            return _UNPACK[name](msg.data)[0]
        except struct.error as exc:
            raise PortTypeError(f"cannot decode {name}: {exc}") from None
    if name in _MODEL_IN:  # a registered model, straight through its validator (the hot case)
        try:
            return _MODEL_IN[name](msg.data)
        except pydantic.ValidationError as exc:
            raise PortTypeError(f"cannot decode {name}: {exc}") from None
    if name == NONE_TYPE:
        return None
    if name == FLOAT_LIST:  # the hot case, without the registry's lookups
        data = msg.data
        if len(data) % 8:
            raise PortTypeError(f"cannot decode {FLOAT_LIST}: {len(data)} bytes is not a whole number of doubles")
        return list(struct.unpack(f"<{len(data) // 8}d", data))
    if name == JSON_TYPE:
        try:
            return pydantic_core.from_json(msg.data, allow_inf_nan=True)
        except ValueError as exc:
            raise PortTypeError(f"cannot decode {JSON_TYPE}: {exc}") from None
    return registry.decode(name, msg.data)
