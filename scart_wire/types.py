"""The type registry: every type that may cross a process, by a stable name.

One process-wide :data:`registry` maps a type name to a Python type and back, and
encodes/decodes values for the wire (the answer to CORBA's ``Any``):

==============  ===================  ===========================================
name            Python type          wire encoding (``Encoded.data``)
==============  ===================  ===========================================
``float64``     ``float``            8 bytes little-endian double
``int64``       ``int``              8 bytes little-endian signed
``bool``        ``bool``             1 byte
``string``      ``str``              UTF-8
``bytes``       ``bytes``            raw (base64 text in JSON)
``float64[]``   ``list[float]``      packed little-endian doubles (compact)
``int64[]``     ``list[int]``        packed little-endian int64
``string[]``    ``list[str]``        JSON array
registered      pydantic model       the model's JSON
``ndarray<..>`` ``Array[dt, shape]``  shape, then raw little-endian data (:mod:`scart_wire.arrays`)
==============  ===================  ===========================================

Array types (``ndarray<uint8>[480,640,3]``) need no registration: their name says all.

An unknown type name decodes to :class:`UnknownValue`, a ``dict`` that keeps its
``type_name`` — never an error. The registry is thread-safe for lookups; register
types at import time (registration takes a lock).
"""

from __future__ import annotations

import base64
import json
import struct
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, TypeGuard, TypeVar, cast

import pydantic
import pydantic_core

from . import rosmsgs
from .arrays import ArraySpec, array_spec
from .errors import PortTypeError

if TYPE_CHECKING:
    from typing_extensions import TypeForm

__all__ = ["TypeRegistry", "registry", "register_type", "UnknownValue", "Encoded", "model_json"]

T = TypeVar("T")
#: A port's check: a value in, the same value as the port's type out (its caller's type,
#: hence Any), or TypeError.
Checker = Callable[[object], Any]


@dataclass(frozen=True)
class Encoded:
    """A value on the wire: its registered type name and its bytes."""

    type_name: str
    data: bytes


class UnknownValue(dict[str, object]):
    """A decoded value whose type name this process does not know: a plain mapping."""

    def __init__(self, type_name: str, *args: Mapping[str, object], **kwargs: object) -> None:
        super().__init__(*args, **kwargs)
        self.type_name = type_name

    def __repr__(self) -> str:
        return f"UnknownValue({self.type_name!r}, {dict.__repr__(self)})"


def model_json(value: pydantic.BaseModel) -> bytes:
    """A model's wire bytes: pydantic's own JSON, in one call (the hot case). pydantic
    writes inf and NaN as null, which would then fail to decode as a float (a sensor
    reading inf must survive), so JSON holding null is made again with inf and NaN as
    ``Infinity`` and ``NaN``."""
    data = value.__pydantic_serializer__.to_json(value)
    if data.find(b"null") < 0:  # not `in`, which first tries the needle as an int (and clears a TypeError)
        return data
    return pydantic_core.to_json(value.model_dump(), inf_nan_mode="constants")


def _is_ndarray(value: object) -> bool:
    """Whether ``value`` is a numpy array (without importing numpy)."""
    kind = type(value)
    return kind.__name__ == "ndarray" and kind.__module__ == "numpy"


def _is_model(py_type: object) -> TypeGuard[type[pydantic.BaseModel]]:
    return isinstance(py_type, type) and issubclass(py_type, pydantic.BaseModel)


def _float_check(v: Any) -> float:  # Any: narrowed by its exact type, which mypy does not follow
    t = type(v)
    if t is float:
        return v
    if t is int:
        return float(v)
    raise TypeError


def _int_check(v: object) -> int:
    if type(v) is int:
        return v
    raise TypeError


def _float_list_check(v: object) -> list[float]:
    if type(v) is list or type(v) is tuple:
        ok = True
        for x in v:
            if type(x) is not float:
                ok = False
                break
        if ok:
            return v if type(v) is list else list(v)
        out = []
        for x in v:
            tx = type(x)
            if tx is float or tx is int:
                out.append(float(x))
            else:
                raise TypeError
        return out
    raise TypeError


def _exact_list_check(item: type) -> Checker:
    def check(v: object) -> list[object]:
        if (type(v) is list or type(v) is tuple) and all(type(x) is item for x in v):
            return v if type(v) is list else list(v)
        raise TypeError

    return check


def _instance_check(py_type: type) -> Checker:
    def check(v: object) -> object:
        if isinstance(v, py_type) and not (py_type is not bool and type(v) is bool):
            return v
        raise TypeError

    return check


class TypeRegistry:
    """Maps stable type names to Python types; encodes, decodes and validates values."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._by_name: dict[str, object] = {}
        self._by_type: dict[object, str] = {}
        self._adapters: dict[object, pydantic.TypeAdapter[object]] = {}
        #: name → its model's JSON validator, once decoded (a name never changes its type):
        #: a model sample, the common case off the number path, without the lookups below.
        self._models: dict[str, Callable[[bytes], object]] = {}
        #: registered model class → its name and its serializer's ``to_json``, once encoded.
        self._model_out: dict[type, tuple[str, Callable[[object], bytes]]] = {}
        #: Read-only views of the two for the codec's hot path (:mod:`scart_wire.codec`): a
        #: model sample straight through pydantic's own serializer and validator.
        self.model_encoders = MappingProxyType(self._model_out)
        self.model_decoders = MappingProxyType(self._models)
        for py_type, name in (
            (float, "float64"),
            (int, "int64"),
            (bool, "bool"),
            (str, "string"),
            (bytes, "bytes"),
            (list[float], "float64[]"),
            (list[int], "int64[]"),
            (list[str], "string[]"),
        ):
            self.register(py_type, name)

    # -- names ---------------------------------------------------------------
    def register(self, py_type: T, name: str | None = None) -> T:
        """Register ``py_type`` under ``name`` (default: its ``__name__``); returns the type.

        Idempotent for the same pair; raises ``ValueError`` if the name is taken by
        another type. Thread-safe.
        """
        name = name or getattr(py_type, "__name__", None) or repr(py_type)
        with self._lock:
            known = self._by_name.get(name)
            if known is not None and known != py_type:
                raise ValueError(f"type name {name!r} is already registered for {known!r}")
            self._by_name[name] = py_type
            self._by_type.setdefault(py_type, name)
        return py_type

    def type_name(self, py_type: object) -> str:
        """The registered name of ``py_type``; an unregistered type gets a descriptive name."""
        name = self._by_type.get(py_type)
        if name is not None:
            return name
        if isinstance(py_type, ArraySpec):
            return py_type.name
        if rosmsgs.is_message_class(py_type):
            return rosmsgs.message_type_name(py_type)
        return getattr(py_type, "__qualname__", None) or repr(py_type)

    def python_type(self, name: str) -> object | None:
        """The Python type registered as ``name`` (or the array type it names), or None."""
        found = self._by_name.get(name)
        if found is not None:
            return found
        return rosmsgs.message_class(name) if name.startswith(rosmsgs.PREFIX) else array_spec(name)

    def names(self) -> list[str]:
        """Every registered type name (sorted)."""
        return sorted(self._by_name)

    def _adapter(self, py_type: object) -> pydantic.TypeAdapter[Any]:  # Any: as the type asked
        adapter = self._adapters.get(py_type)
        if adapter is None:
            adapter = pydantic.TypeAdapter(cast("TypeForm[object]", py_type))  # a type form (or a type pydantic refuses)
            self._adapters[py_type] = adapter
        return adapter

    # -- validation ----------------------------------------------------------
    def checker(self, py_type: object) -> Checker:
        """A fast function ``v -> v'`` for a port's hot path; raises ``TypeError`` on a mismatch.

        Exact types only, except the lossless int→float widening (never bool→number).
        """
        if py_type is float:
            return _float_check
        if py_type is int:
            return _int_check
        if py_type == list[float]:
            return _float_list_check
        if py_type == list[int]:
            return _exact_list_check(int)
        if py_type == list[str]:
            return _exact_list_check(str)
        if isinstance(py_type, ArraySpec):
            return py_type.check
        if isinstance(py_type, type):
            return _instance_check(py_type)
        adapter = self._adapter(py_type)

        def check(v: object) -> object:
            try:
                return adapter.validate_python(v, strict=True)
            except pydantic.ValidationError:
                raise TypeError from None

        return check

    def validate(self, py_type: object, value: object) -> Any:  # Any: the value as the type asked
        """Coerce ``value`` to ``py_type`` (pydantic lax mode) or raise ``PortTypeError``."""
        if rosmsgs.is_message_class(py_type):
            return value if isinstance(value, py_type) else self.from_jsonable(py_type, value)
        try:
            return self._adapter(py_type).validate_python(value)
        except pydantic.ValidationError as exc:
            raise PortTypeError(
                f"expected {self.type_name(py_type)}, got {type(value).__name__} {value!r:.80}: "
                f"{exc.errors()[0]['msg']}"
            ) from None

    # -- JSON ----------------------------------------------------------------
    def to_jsonable(self, value: object) -> object:
        """Plain JSON-able data for ``value`` (what ``scart echo --json`` prints)."""
        if isinstance(value, pydantic.BaseModel):
            return value.model_dump(mode="json")
        if isinstance(value, UnknownValue):
            return dict(value)
        if isinstance(value, (bytes, bytearray)):
            return base64.b64encode(bytes(value)).decode("ascii")
        if hasattr(value, "__array__") and hasattr(value, "tolist"):  # a numpy array
            return value.tolist()
        if isinstance(value, (list, tuple)):
            return [self.to_jsonable(v) for v in value]
        if isinstance(value, dict):
            return {str(k): self.to_jsonable(v) for k, v in value.items()}
        if rosmsgs.is_message_class(type(value)):
            return rosmsgs.to_jsonable(value)
        return value

    def from_jsonable(self, py_type_or_name: object, obj: object) -> Any:  # Any: as validate
        """Build a value of the given type (or registered name) from JSON-able data.

        An unknown name gives an :class:`UnknownValue`; a mismatch raises ``PortTypeError``.
        """
        py_type = py_type_or_name
        if isinstance(py_type_or_name, str):
            py_type = self.python_type(py_type_or_name)
            if py_type is None:
                data = obj if isinstance(obj, dict) else {"value": obj}
                return UnknownValue(py_type_or_name, data)
        if py_type is bytes and isinstance(obj, str):
            try:
                return base64.b64decode(obj, validate=True)
            except ValueError:
                raise PortTypeError(f"expected base64 text for bytes, got {obj!r:.60}") from None
        if rosmsgs.is_message_class(py_type):
            try:
                return rosmsgs.from_jsonable(py_type, obj)
            except (ValueError, TypeError) as exc:
                raise PortTypeError(f"expected {self.type_name(py_type)}: {exc}") from None
        return self.validate(py_type, obj)

    # -- wire ----------------------------------------------------------------
    def encode(self, value: Any, py_type: object = None) -> Encoded:  # Any: packed as py_type says
        """Encode ``value`` (of ``py_type``, default its own type) for the wire."""
        if py_type is None:
            if isinstance(value, UnknownValue):
                return Encoded(value.type_name, json.dumps(dict(value)).encode())
            py_type = type(value)
            if py_type is list:
                py_type = self._guess_list_type(value)
            elif _is_ndarray(value):  # an array of any shape, of its own element type
                py_type = ArraySpec(value.dtype.name)
        name = self.type_name(py_type)
        if py_type is float:
            return Encoded(name, struct.pack("<d", value))
        if py_type is int:
            return Encoded(name, struct.pack("<q", value))
        if py_type is bool:
            return Encoded(name, b"\x01" if value else b"\x00")
        if py_type is str:
            return Encoded(name, value.encode("utf-8"))
        if py_type is bytes:
            return Encoded(name, bytes(value))
        if isinstance(value, pydantic.BaseModel) and _is_model(py_type) and isinstance(value, py_type):
            data = model_json(value)
            if py_type in self._by_type:  # registered: its name is for good
                self._model_out[py_type] = (name, py_type.__pydantic_serializer__.to_json)
            return Encoded(name, data)
        if py_type == list[float]:
            return Encoded(name, struct.pack(f"<{len(value)}d", *value))
        if py_type == list[int]:
            return Encoded(name, struct.pack(f"<{len(value)}q", *value))
        if isinstance(py_type, ArraySpec):
            return Encoded(name, py_type.encode(py_type.check(value)))
        if rosmsgs.is_message_class(py_type):
            if type(value) is not py_type:
                raise PortTypeError(f"expected {name}, got {type(value).__name__}")
            try:
                return Encoded(name, rosmsgs.encode(value))
            except ValueError as exc:
                raise PortTypeError(f"cannot encode {name}: {exc}") from None
        return Encoded(name, pydantic_core.to_json(self._adapter(py_type).dump_python(value), inf_nan_mode="constants"))

    @staticmethod
    def _guess_list_type(value: list[object]) -> object:
        if value and all(type(x) is int for x in value):
            return list[int]
        if value and all(type(x) is str for x in value):
            return list[str]
        return list[float]

    def decode(self, type_name: str, data: bytes) -> Any:  # Any: the value of the type named
        """Decode wire bytes; an unknown ``type_name`` gives an :class:`UnknownValue`.

        Raises ``PortTypeError`` when the bytes do not fit a known type.
        """
        validate = self._models.get(type_name)
        if validate is not None:
            try:
                return validate(data)
            except pydantic.ValidationError as exc:
                raise PortTypeError(f"cannot decode {type_name}: {exc}") from None
        py_type = self.python_type(type_name)
        if py_type is None:
            return self._unknown(type_name, data)
        try:
            if py_type is float:
                return struct.unpack("<d", data)[0]
            if py_type is int:
                return struct.unpack("<q", data)[0]
            if py_type is bool:
                return data != b"\x00"
            if py_type is str:
                return data.decode("utf-8")
            if py_type is bytes:
                return bytes(data)
            if py_type == list[float]:
                return list(struct.unpack(f"<{len(data) // 8}d", data))
            if py_type == list[int]:
                return list(struct.unpack(f"<{len(data) // 8}q", data))
            if isinstance(py_type, ArraySpec):
                return py_type.decode(data)
            if rosmsgs.is_message_class(py_type):
                return rosmsgs.decode(py_type, data)
            if _is_model(py_type):
                value = py_type.model_validate_json(data)
                self._models[type_name] = py_type.__pydantic_validator__.validate_json  # built now: the same check
                return value
            return self._adapter(py_type).validate_json(data)
        except (struct.error, UnicodeDecodeError, pydantic.ValidationError, ValueError) as exc:
            raise PortTypeError(f"cannot decode {type_name}: {exc}") from None

    @staticmethod
    def _unknown(type_name: str, data: bytes) -> UnknownValue:
        try:
            obj = json.loads(data)
        except (ValueError, UnicodeDecodeError):
            return UnknownValue(type_name, {"data": bytes(data).hex()})
        return UnknownValue(type_name, obj if isinstance(obj, dict) else {"value": obj})


registry = TypeRegistry()
"""The process-wide type registry."""


def register_type(name: str | None = None) -> Callable[[type[T]], type[T]]:
    """Class decorator: ``@register_type("YouBotStatus")`` registers a pydantic model."""

    def deco(cls: type[T]) -> type[T]:
        registry.register(cls, name or cls.__name__)
        return cls

    return deco
