"""The wire side of ``binding.grpc`` (private): its messages, values, faults.

Messages are the code protoc made of ``scart/sca/v1/sca.proto`` (:mod:`scart_wire.proto`).
Values go through the one codec, :mod:`scart_wire.codec` (the type registry, plus ``""``
for None and ``"scart.json"`` for values the registry has no name for). On the
receiving side, values are coerced to the parameter / return annotations of the
interface (pydantic, lax), so an unregistered pydantic model arrives as that model.
"""

from __future__ import annotations

import functools
import inspect
import logging
import secrets
import typing
from types import MappingProxyType
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any, TypeVar

import pydantic

from scart_wire import codec
from scart_wire.bounds import argument_adapter, check_argument
from scart_wire.errors import bounded
from dataflow.errors import DataflowError, PortTypeError
from scart_wire.proto.scart.sca.v1 import sca_pb2 as pb
from scart_wire.proto.scart.sca.v1 import sca_pb2_grpc as pb_grpc  # noqa: F401  (the two sides use it)
from scart_wire.security import Role, roles_of_service
from scart_wire.types import registry
from scart.errors import InvocationError, RemoteError, RuntimeStateError, ServiceNotFoundError

if TYPE_CHECKING:
    from typing_extensions import TypeForm

SCA_SERVICE = pb.DESCRIPTOR.services_by_name["ScaService"]
#: The role each method needs on a server with an auth file: listing needs ``read``, calling ``operate``.
SCA_ROLES: MappingProxyType[str, Role] = MappingProxyType(roles_of_service(SCA_SERVICE.full_name, reads={"ListServices"}))
PATHS: MappingProxyType[str, str] = MappingProxyType(
    {m.name: f"/{SCA_SERVICE.full_name}/{m.name}" for m in SCA_SERVICE.methods})
log = logging.getLogger("scart.bindings.grpc")
NONE_TYPE = codec.NONE_TYPE
JSON_TYPE = codec.JSON_TYPE
T = TypeVar("T")


def encode(value: object) -> codec.Value:
    """``value`` as a ``scart.dataflow.v1.Value``; raises ``InvocationError`` if it cannot be sent."""
    try:
        return codec.encode(value)
    except PortTypeError as exc:
        raise InvocationError(f"binding.grpc: cannot send a value of type {type(value).__qualname__}: {exc}") from None


def decode(value: codec.Value) -> object:
    """The Python value of a ``Value`` message; raises ``InvocationError`` for malformed bytes."""
    try:
        return codec.decode(value)
    except PortTypeError as exc:
        raise InvocationError(f"binding.grpc: malformed value: {exc}") from None


# --- coercion to annotations -----------------------------------------------------------

#: Coerces a decoded value to an annotation (:func:`converter`).
Converter = Callable[[object], object]
#: Decodes a ``Value`` message and coerces it (:func:`reader`).
Reader = Callable[[codec.Value], object]


def _identity(value: T) -> T:
    return value


@functools.lru_cache(maxsize=512)
def _adapter(annotation: TypeForm[object]) -> pydantic.TypeAdapter[object]:
    return pydantic.TypeAdapter(annotation)


def converter(annotation: object) -> Converter:
    """A function coercing a decoded value to ``annotation`` (identity when unannotated).

    Raises ``InvocationError`` (from the returned function) when the value does not fit."""
    if annotation in (None, inspect.Parameter.empty, Any, object) or isinstance(annotation, (str, typing.TypeVar)):
        return _identity
    try:
        adapter = _adapter(annotation)
    except Exception:  # an annotation pydantic cannot handle (or unhashable): pass values through
        return _identity
    exact = annotation if isinstance(annotation, type) else None
    base = typing.get_args(annotation)[0] if typing.get_origin(annotation) is typing.Annotated else annotation
    shown = getattr(base, "__name__", None) or repr(base)

    def convert(value: object) -> object:
        if exact is not None and type(value) is exact:
            return value
        try:
            return adapter.validate_python(value)
        except pydantic.ValidationError as exc:
            raise InvocationError(f"expected {shown}, got {type(value).__name__} {value!r:.80}: "
                                  f"{exc.errors()[0]['msg']}") from None

    return convert


def reader(annotation: object) -> Reader:
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

    def read(v: codec.Value) -> object:
        value = decode(v)
        return value if v.type_name == exact else conv(value)
    return read


class Signature:
    """Per-operation readers: parameters by position and by name, each decoded and then
    checked by the one check of operation arguments from outside that every entry uses
    (:func:`scart_wire.bounds.check_argument`: declared type, numbers strict, bounds,
    finiteness; a refusal says ``LABEL.op(param): VALUE refused: REASON``), the result
    (see :func:`reader`)."""

    __slots__ = ("positional", "named", "result", "label", "_shape")

    def __init__(self, func: Callable[..., object] | None, label: str = "") -> None:
        """``label``: what refusals name the operation (default: the function's name)."""
        self.positional: list[Reader] = []
        self.named: dict[str, Reader] = {}
        self.result: Reader = decode
        self.label = label
        self._shape: inspect.Signature | None = None
        if func is None:
            return
        try:
            hints = typing.get_type_hints(func, include_extras=True)  # keep Annotated bounds
            params = [p for p in inspect.signature(func).parameters.values() if p.name != "self"]
        except Exception:  # unresolvable annotations: values pass as decoded
            return
        op = self.label = label or func.__name__
        self._shape = inspect.Signature(params)
        for p in params:
            read = _checked_reader(f"{op}({p.name})", hints.get(p.name))
            if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD):
                self.positional.append(read)
            self.named[p.name] = read
        self.result = reader(hints.get("return"))

    def args(self, values: Iterable[codec.Value]) -> tuple[object, ...]:
        """Decoded and coerced positional arguments (``Value`` messages in)."""
        pos = self.positional
        n = len(pos)
        return tuple(pos[i](v) if i < n else decode(v) for i, v in enumerate(values))

    def kwargs(self, values: Mapping[str, codec.Value]) -> dict[str, object]:
        """Decoded and coerced keyword arguments (``Value`` messages in)."""
        named = self.named
        return {k: named.get(k, decode)(v) for k, v in values.items()}

    @property
    def params(self) -> list[str]:
        """The parameters' names, in order (empty when the function is not known)."""
        return list(self._shape.parameters) if self._shape is not None else []

    def check_shape(self, n_args: int, names: typing.Iterable[str]) -> None:
        """Raise :class:`ArgumentRefused` when ``n_args`` positional arguments and the
        keyword arguments ``names`` do not fit the operation (one missing, one too many,
        an unknown name): the caller's mistake, said in one line, never a traceback."""
        if self._shape is None:
            return
        try:
            self._shape.bind(*range(n_args), **dict.fromkeys(names))
        except TypeError as exc:
            raise ArgumentRefused(f"{self.label}({', '.join(self._shape.parameters)}): {exc}") from None


def _checked_reader(where: str, hint: object) -> Reader:
    """``Value`` message -> the argument, decoded and checked (see :class:`Signature`)."""
    if argument_adapter(hint) is None:
        return decode

    def read(v: codec.Value) -> object:
        try:
            return check_argument(where, hint, decode(v))
        except DataflowError as exc:  # the same refusal, in this side's error tree
            raise ArgumentRefused(str(exc)) from None
    return read


def signatures(iface_cls: type | None, names: typing.Iterable[str], label: str = "") -> dict[str, Signature]:
    """A :class:`Signature` per operation name, read from ``iface_cls`` (None: no coercion);
    ``label`` (e.g. the component) starts the refusals' ``where``."""
    return {n: Signature(getattr(iface_cls, n, None) if iface_cls is not None else None, f"{label}.{n}" if label else n)
            for n in names}


def fill_invocation(msg: pb.Invocation | pb.CallbackCall, args: tuple[object, ...],
                    kwargs: Mapping[str, object]) -> None:
    """Encode ``args``/``kwargs`` into a message with ``args`` and ``kwargs`` fields."""
    if args:
        msg.args.extend([encode(a) for a in args])
    for k, v in kwargs.items():
        msg.kwargs[k].CopyFrom(encode(v))


# --- faults ---------------------------------------------------------------------------


class UnknownSessionError(InvocationError):
    """A one-way call named a callback session the server does not have (it restarted):
    the client reopens its session and sends again, once."""


class ArgumentRefused(InvocationError):
    """An argument refused by the one check of operation arguments (a fault's INVALID_ARGUMENT)."""


def fault_code(exc: BaseException) -> str:
    """What a fault is, for programs (see ``Fault.code`` in ``sca.proto``)."""
    if isinstance(exc, ArgumentRefused) or (isinstance(exc, InvocationError) and "malformed value" in str(exc)):
        return "INVALID_ARGUMENT"
    if isinstance(exc, (ServiceNotFoundError, UnknownSessionError)) or (
            isinstance(exc, InvocationError) and " has no operation " in str(exc)):
        return "NOT_FOUND"
    if isinstance(exc, RuntimeStateError) or str(exc).startswith("server stopping"):
        return "UNAVAILABLE"
    return "FAILED"


def fault(exc: BaseException) -> pb.Fault:
    """A ``Fault`` message describing ``exc`` to the caller: its type, message, code and a
    reference. The traceback (with this side's paths) never leaves: it is logged here
    under that reference (a warning when the operation itself failed)."""
    kind = type(exc)
    name = kind.__qualname__ if kind.__module__ == "builtins" else f"{kind.__module__}.{kind.__qualname__}"
    message = bounded(exc.remote_message if isinstance(exc, RemoteError) else str(exc))
    code, reference = fault_code(exc), secrets.token_hex(6)
    failed = code == "FAILED"  # the operation's own failure: its traceback is worth keeping; a refusal's is not
    log.log(logging.WARNING if failed else logging.INFO, "binding.grpc fault %s (%s): %s: %s",
            reference, code, name, message, exc_info=exc if failed else None)
    return pb.Fault(type=name, message=message, code=code, reference=reference)


def failure(where: str, f: pb.Fault) -> RemoteError:
    """The :class:`RemoteError` for a received ``Fault``."""
    return RemoteError(where, f.type, f.message, code=f.code, reference=f.reference)


def outcome_of(fn: Callable[[], object]) -> pb.Outcome:
    """Run ``fn`` and wrap its result or exception in an ``Outcome`` message."""
    try:
        return pb.Outcome(value=encode(fn()))
    except Exception as exc:
        return pb.Outcome(fault=fault(exc))
