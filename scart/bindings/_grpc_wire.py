"""The wire side of ``binding.grpc`` (private): messages from ``proto/``, values, faults.

Messages are built at import time from ``proto/scart/sca/v1/sca.proto`` (never generated
code): :mod:`dataflow.remote._proto` compiles every ``.proto`` under ``proto/`` into the
default descriptor pool, and the classes here are made from that pool. Should that
loader not have the file (it was imported before the file existed), the file is compiled
here the same way.

Values go through the data-flow type registry (``registry.encode`` / ``decode``); two
names are added on top of it: ``""`` is ``None`` and ``"scart.json"`` is JSON text, for
values the registry has no name for (dicts, mixed lists, lists of models). On the
receiving side, values are coerced to the parameter / return annotations of the
interface (pydantic, lax), so an unregistered pydantic model arrives as that model.
"""

from __future__ import annotations

import inspect
import struct
import traceback
import typing
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import pydantic
import pydantic_core
from google.protobuf import descriptor_pool, message_factory
from google.protobuf.descriptor import ServiceDescriptor

from dataflow import registry
from dataflow.types import UnknownValue
from scart.errors import InvocationError, RemoteError

SCA_PROTO = "scart/sca/v1/sca.proto"
SCA_SERVICE_NAME = "scart.sca.v1.ScaService"
NONE_TYPE = ""
JSON_TYPE = "scart.json"
FLOAT_LIST = registry.type_name(list[float])  # "float64[]": packed little-endian doubles


def _load() -> tuple[SimpleNamespace, ServiceDescriptor]:
    from dataflow.remote import _proto  # compiles every proto/ file into the default pool

    pool = descriptor_pool.Default()
    try:
        file_desc = pool.FindFileByName(SCA_PROTO)
    except KeyError:
        for file_proto in _proto.compile_protos([SCA_PROTO]).file:
            pool.Add(file_proto)
        file_desc = pool.FindFileByName(SCA_PROTO)
    space = SimpleNamespace()
    for name, desc in file_desc.message_types_by_name.items():
        setattr(space, name, message_factory.GetMessageClass(desc))
    space.Value = message_factory.GetMessageClass(pool.FindMessageTypeByName("scart.dataflow.v1.Value"))
    return space, pool.FindServiceByName(SCA_SERVICE_NAME)


pb, SCA_SERVICE = _load()
PATHS: dict[str, str] = {m.name: f"/{SCA_SERVICE_NAME}/{m.name}" for m in SCA_SERVICE.methods}

# --- values ---------------------------------------------------------------------------

_PLAIN = (float, int, bool, str, bytes)


def encode(value: Any) -> Any:
    """``value`` as a ``scart.dataflow.v1.Value``; raises ``InvocationError`` if it cannot be sent."""
    try:
        return _encode(value)
    except (struct.error, OverflowError):  # e.g. an int beyond int64: JSON has no such limit
        return _json(value)


def _encode(value: Any) -> Any:
    kind = type(value)
    if value is None:
        return pb.Value(type_name=NONE_TYPE)
    if kind in _PLAIN or isinstance(value, (pydantic.BaseModel, UnknownValue)):
        enc = registry.encode(value)
        return pb.Value(type_name=enc.type_name, data=enc.data)
    if kind is list or kind is tuple:
        if value and type(value[0]) is float:  # the hot case (joint vectors...): pack directly
            try:
                return pb.Value(type_name=FLOAT_LIST, data=struct.pack(f"<{len(value)}d", *value))
            except struct.error:  # not all numbers: the general path below
                pass
        py_type = _list_type(value)
        if py_type is not None:
            enc = registry.encode(list(value), py_type)
            return pb.Value(type_name=enc.type_name, data=enc.data)
    elif registry.python_type(registry.type_name(kind)) is kind:
        enc = registry.encode(value)
        return pb.Value(type_name=enc.type_name, data=enc.data)
    return _json(value)


def _json(value: Any) -> Any:
    try:
        return pb.Value(type_name=JSON_TYPE, data=pydantic_core.to_json(value, inf_nan_mode="constants"))
    except pydantic_core.PydanticSerializationError as exc:
        raise InvocationError(f"binding.grpc: cannot send a value of type {type(value).__qualname__}: {exc}") from None


def _list_type(value: list[Any] | tuple[Any, ...]) -> Any:
    if not value:
        return list[float]
    first = type(value[0])
    if first in (float, int, str) and all(type(v) is first for v in value):
        return {float: list[float], int: list[int], str: list[str]}[first]
    return None


def decode(value: Any) -> Any:
    """The Python value of a ``Value`` message (``UnknownValue`` for an unknown type name)."""
    name = value.type_name
    if name == NONE_TYPE:
        return None
    if name == FLOAT_LIST:
        data = value.data
        if len(data) % 8:
            raise InvocationError(f"malformed {FLOAT_LIST} value: {len(data)} bytes is not a whole number of doubles")
        return list(struct.unpack(f"<{len(data) // 8}d", data))
    if name == JSON_TYPE:
        return pydantic_core.from_json(value.data, allow_inf_nan=True)
    return registry.decode(name, value.data)


# --- coercion to annotations -----------------------------------------------------------

Converter = Callable[[Any], Any]


def _identity(value: Any) -> Any:
    return value


_ADAPTERS: dict[Any, pydantic.TypeAdapter[Any]] = {}


def converter(annotation: Any) -> Converter:
    """A function coercing a decoded value to ``annotation`` (identity when unannotated).

    Raises ``InvocationError`` (from the returned function) when the value does not fit."""
    if annotation in (None, inspect.Parameter.empty, Any, object) or isinstance(annotation, (str, typing.TypeVar)):
        return _identity
    adapter = _ADAPTERS.get(annotation)
    if adapter is None:
        try:
            adapter = _ADAPTERS[annotation] = pydantic.TypeAdapter(annotation)
        except Exception:  # an annotation pydantic cannot handle: pass values through
            return _identity
    exact = annotation if isinstance(annotation, type) else None

    def convert(value: Any) -> Any:
        if exact is not None and type(value) is exact:
            return value
        try:
            return adapter.validate_python(value)
        except pydantic.ValidationError as exc:
            raise InvocationError(f"expected {annotation!r}, got {type(value).__name__} {value!r:.80}: "
                                  f"{exc.errors()[0]['msg']}") from None

    return convert


def reader(annotation: Any) -> Converter:
    """A function ``Value message -> Python value`` decoding and coercing to ``annotation``;
    when the wire type name is the annotation's registered name the value is taken as
    decoded (no validation: the registry built it as that type)."""
    conv = converter(annotation)
    if conv is _identity:
        return decode
    try:
        name = registry.type_name(annotation)
        exact = name if registry.python_type(name) == annotation else None
    except TypeError:  # unhashable annotation
        exact = None

    def read(v: Any) -> Any:
        value = decode(v)
        return value if v.type_name == exact else conv(value)
    return read


class Signature:
    """Per-operation readers (see :func:`reader`): parameters by position and by name, the result."""

    __slots__ = ("positional", "named", "result")

    def __init__(self, func: Callable[..., Any] | None) -> None:
        self.positional: list[Converter] = []
        self.named: dict[str, Converter] = {}
        self.result: Converter = decode
        if func is None:
            return
        try:
            hints = typing.get_type_hints(func)
            params = [p for p in inspect.signature(func).parameters.values() if p.name != "self"]
        except Exception:  # unresolvable annotations: values pass as decoded
            return
        for p in params:
            read = reader(hints.get(p.name))
            if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD):
                self.positional.append(read)
            self.named[p.name] = read
        self.result = reader(hints.get("return"))

    def args(self, values: Any) -> tuple[Any, ...]:
        """Decoded and coerced positional arguments (``Value`` messages in)."""
        pos = self.positional
        n = len(pos)
        return tuple(pos[i](v) if i < n else decode(v) for i, v in enumerate(values))

    def kwargs(self, values: Any) -> dict[str, Any]:
        """Decoded and coerced keyword arguments (``Value`` messages in)."""
        named = self.named
        return {k: named.get(k, decode)(v) for k, v in values.items()}


def signatures(iface_cls: type | None, names: typing.Iterable[str]) -> dict[str, Signature]:
    """A :class:`Signature` per operation name, read from ``iface_cls`` (None: no coercion)."""
    return {n: Signature(getattr(iface_cls, n, None) if iface_cls is not None else None) for n in names}


def fill_invocation(msg: Any, args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
    """Encode ``args``/``kwargs`` into a message with ``args`` and ``kwargs`` fields."""
    if args:
        msg.args.extend([encode(a) for a in args])
    for k, v in kwargs.items():
        msg.kwargs[k].CopyFrom(encode(v))


# --- faults ---------------------------------------------------------------------------


class UnknownSessionError(InvocationError):
    """A one-way call named a callback session the server does not have (it restarted):
    the client reopens its session and sends again, once."""


def fault(exc: BaseException) -> Any:
    """A ``Fault`` message describing ``exc``."""
    kind = type(exc)
    name = kind.__qualname__ if kind.__module__ == "builtins" else f"{kind.__module__}.{kind.__qualname__}"
    message = exc.remote_message if isinstance(exc, RemoteError) else str(exc)
    return pb.Fault(type=name, message=message, traceback="".join(traceback.format_exception(exc))[-4000:])


def failure(where: str, f: Any) -> RemoteError:
    """The :class:`RemoteError` for a received ``Fault``."""
    return RemoteError(where, f.type, f.message, f.traceback)


def outcome_of(fn: Callable[[], Any]) -> Any:
    """Run ``fn`` and wrap its result or exception in an ``Outcome`` message."""
    try:
        return pb.Outcome(value=encode(fn()))
    except Exception as exc:
        return pb.Outcome(fault=fault(exc))
