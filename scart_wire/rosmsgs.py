"""rosbags' message classes as port types, numpy fields and all::

    from rosbags.typesys import Stores, get_typestore
    from dataflow import InputPort, OutputPort

    Image = get_typestore(Stores.ROS2_JAZZY).types["sensor_msgs/msg/Image"]
    camera = OutputPort(Image)                          # a ROS 2 sensor_msgs/msg/Image

A class is known to every process by its name alone, ``rosbags:<store>:<type>``
(``rosbags:ros2_dashing:sensor_msgs/msg/Image``): rosbags keeps each class in a module of
the store that first defined it (later distros with the same definition share it), and
another process finds it there (only in rosbags' own store modules: a name never makes a
process import anything else). Each sample is checked once, as every sample is: an
instance of the class.

On scart's own transports a value is its store's bytes (CDR for ROS 2, ROS 1's own
serialisation for ROS 1), made and read by rosbags: an array field is copied once into
the bytes, and read as a read-only view of the bytes received (of the shared memory, on
``shm``). As JSON (``scart echo``, ``record``, ``play``, ``write``) a value is its fields,
a ``uint8`` array as base64 text (an image's bytes), any other array as a list.
"""

from __future__ import annotations

import base64
import dataclasses
import functools
import importlib
import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Protocol, TypeGuard, cast

if TYPE_CHECKING:
    import numpy
    from rosbags.typesys.store import Typestore

__all__ = ["PREFIX", "decode", "encode", "from_jsonable", "is_message_class", "message_class", "message_type_name",
           "to_jsonable"]

PREFIX = "rosbags:"
_STORES = "rosbags.typesys.stores."
_NAME = re.compile(r"^rosbags:(ros[12]_[a-z0-9]{1,32}):([A-Za-z][A-Za-z0-9_]{0,99}/msg/[A-Za-z][A-Za-z0-9_]{0,99})$")
MAX_DEPTH = 16  #: nesting of messages built from JSON, at most


class _NumpyLike(Protocol):
    """What :func:`to_jsonable` reads of an array field (a numpy array)."""

    @property
    def dtype(self) -> numpy.dtype: ...
    def tobytes(self) -> bytes: ...
    def tolist(self) -> object: ...


def is_message_class(py_type: object) -> TypeGuard[type]:
    """Whether ``py_type`` is a message class of one of rosbags' ROS 1 or ROS 2 stores."""
    return (isinstance(py_type, type) and isinstance(getattr(py_type, "__msgtype__", None), str)
            and py_type.__module__.startswith(_STORES + "ros"))


def message_type_name(cls: type) -> str:
    """The port type name of message class ``cls``: ``rosbags:ros2_dashing:sensor_msgs/msg/Image``."""
    return f"{PREFIX}{cls.__module__[len(_STORES):]}:{cls.__msgtype__}"  # type: ignore[attr-defined]  # checked


def message_class(name: str) -> type | None:
    """The message class called ``name`` (see :func:`message_type_name`), or None for a name
    that is not one or names no class of rosbags' stores."""
    found = _NAME.match(name)
    if found is None:
        return None
    store, msgtype = found.groups()
    try:
        module = importlib.import_module(_STORES + store)  # rosbags' own store modules only (the pattern)
    except ImportError:
        return None
    cls: object = getattr(module, msgtype.replace("/", "__"), None)
    return cls if is_message_class(cls) and getattr(cls, "__msgtype__", None) == msgtype else None


@functools.lru_cache(maxsize=16)
def _store(cls_module: str) -> Typestore:
    """rosbags' type store of the store module ``cls_module`` (built once: 0.1 s)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores(cls_module[len(_STORES):]))


def _ros1(cls: type) -> bool:
    return cls.__module__.startswith(_STORES + "ros1_")


def encode(value: object) -> bytes:
    """A message as its store's bytes (each array field copied once into them). Raises
    ``ValueError`` for a value a field cannot hold."""
    cls = type(value)
    store, msgtype = _store(cls.__module__), cls.__msgtype__  # type: ignore[attr-defined]  # a message
    try:
        data = store.serialize_ros1(value, msgtype) if _ros1(cls) else store.serialize_cdr(value, msgtype)
    except Exception as exc:  # rosbags raises struct.error, TypeError, its own errors
        raise ValueError(f"{msgtype}: {type(exc).__name__}: {exc}") from None
    return bytes(data)  # (a Value's data field holds bytes)


def decode(cls: type, data: bytes | bytearray | memoryview) -> object:
    """The message of class ``cls`` in ``data`` (``bytes`` or a buffer): its array fields
    read-only views of ``data``. Raises ``ValueError`` for bytes that are not one."""
    store, msgtype = _store(cls.__module__), cls.__msgtype__  # type: ignore[attr-defined]  # a message class
    view = memoryview(data).toreadonly()  # (a slice of bytes would copy them)
    try:
        return store.deserialize_ros1(view, msgtype) if _ros1(cls) else store.deserialize_cdr(view, msgtype)
    except Exception as exc:  # rosbags' SerdeError, or what a truncated buffer raises
        raise ValueError(f"not a {msgtype}: {exc}") from None


def to_jsonable(value: object) -> object:
    """A message (or a field of one) as JSON-able data (see the module docstring)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: to_jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)
                if not f.name.startswith("__")}  # (rosbags' __msgtype__)
    if hasattr(value, "__array__") and hasattr(value, "tolist"):  # a numpy array
        array = cast("_NumpyLike", value)
        if array.dtype.name == "uint8":
            return base64.b64encode(array.tobytes()).decode("ascii")
        return array.tolist()
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    return value


def from_jsonable(cls: type, obj: object) -> object:
    """A message of class ``cls`` from :func:`to_jsonable`'s form (a field left out takes
    ROS's zero value). Raises ``ValueError`` saying which field does not fit."""
    return _build(_store(cls.__module__), cls.__msgtype__, obj, 0)  # type: ignore[attr-defined]  # a message class


def _build(store: Any, msgtype: str, obj: object, depth: int) -> object:  # Any: rosbags' field definitions,
    # a union tagged by their Nodetype, which mypy cannot narrow
    import numpy

    from rosbags.typesys.base import Nodetype

    if depth > MAX_DEPTH or not isinstance(obj, Mapping):
        raise ValueError(f"{msgtype}: expected a mapping of its fields, got {type(obj).__name__}")
    fields = dict(store.fielddefs[msgtype][1])
    unknown = [k for k in obj if k not in fields]
    if unknown:
        raise ValueError(f"{msgtype} has no field {unknown[0]!r}")
    cls = store.types[msgtype]
    if set(obj) != set(fields):  # ROS's zero values for what is left out
        obj = {**_jsonable_zero(store, msgtype), **obj}
    kwargs = {}
    for name, (kind, detail) in fields.items():
        value = obj[name]
        if kind == Nodetype.NAME:
            kwargs[name] = _build(store, detail, value, depth + 1)
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            (inner_kind, inner), _ = detail
            if inner_kind == Nodetype.NAME:
                kwargs[name] = [_build(store, inner, v, depth + 1) for v in value]
            elif inner[0] == "string":
                kwargs[name] = [str(v) for v in value]
            elif isinstance(value, str):  # base64: an image's bytes
                kwargs[name] = numpy.frombuffer(base64.b64decode(value, validate=True), dtype=_dtype(inner[0]))
            else:
                kwargs[name] = numpy.asarray(value, dtype=_dtype(inner[0]))
        else:
            kwargs[name] = value
    return cls(**kwargs)


def _dtype(base: str) -> str:
    return {"bool": "bool", "byte": "int8", "char": "uint8"}.get(base, base)


def _jsonable_zero(store: Any, msgtype: str) -> dict[str, object]:  # Any: as _build's
    """ROS's zero value of each field of ``msgtype``, in :func:`to_jsonable`'s form."""
    from rosbags.typesys.base import Nodetype

    out: dict[str, object] = {}
    for name, (kind, detail) in store.fielddefs[msgtype][1]:
        if kind == Nodetype.NAME:
            out[name] = _jsonable_zero(store, detail)
        elif kind == Nodetype.SEQUENCE:
            out[name] = []
        elif kind == Nodetype.ARRAY:
            (inner_kind, inner), size = detail
            zero = _jsonable_zero(store, inner) if inner_kind == Nodetype.NAME else \
                "" if inner[0] == "string" else False if inner[0] == "bool" else 0
            out[name] = [zero] * size
        else:
            out[name] = {"string": "", "bool": False, "float32": 0.0, "float64": 0.0}.get(detail[0], 0)
    return out
