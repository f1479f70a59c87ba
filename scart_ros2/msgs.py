"""ROS 2 message definitions (rosbags) made into Cyclone DDS IDL types, and conversions.

A ROS 2 type ``pkg/msg/Type`` comes from rosbags' store of a ROS 2 distro (Humble, Iron,
Jazzy, Kilted), from a ``.msg``/``.srv`` definition the user adds, or from one found in an
installed ROS 2 package: ``PREFIX/share/PKG/msg/Type.msg`` (``srv/Type.srv``) under the
prefixes of ``AMENT_PREFIX_PATH``, as ament lays packages out (looked for once per type,
in at most :data:`MAX_PREFIXES` prefixes, no folder walked). It becomes a
cyclonedds ``IdlStruct`` named ``pkg::msg::dds_::Type_``, final (XCDR1, plain CDR), whose
members are the message's fields in order: the same bytes rmw_cyclonedds puts on the wire
(the test suite checks them against rosbags' own CDR serialiser, which is what rosbag2
stores). Built once per type and cached.

====================  ====================================  ==============================
ROS 2 field           IDL member                            rosbags value
====================  ====================================  ==============================
``bool``              ``boolean``                           ``bool``
``byte``              ``octet``                             ``int`` (arrays: ``int8``)
``char``              ``uint8``                             ``int`` (arrays: ``uint8``)
``int8`` … ``uint64``  the same                              ``int`` (arrays: numpy)
``float32/64``        ``float``/``double``                  ``float`` (arrays: numpy)
``string``            ``string`` (``string<N>`` if bounded)  ``str``
``T[N]``              ``T member[N]``                       numpy array or list
``T[]``/``T[<=N]``    ``sequence<T>``/``sequence<T, N>``    numpy array or list
``pkg/Other``         the nested struct                     the nested message
====================  ====================================  ==============================

``wstring``/``wchar`` (UTF-16, rare) are refused when the type is built.

Values come in as rosbags message objects of the type, as plain mappings (missing fields
take ROS's zero value, unknown keys are refused) or as instances of the IDL type; they
leave as rosbags message objects or plain dicts. A value that does not fit raises
:class:`ConversionError` naming ``type.field``. Finiteness and ranges beyond what the
type's bits can hold are the caller's concern (see the ``accept`` hooks).

Thread-safe: a lock guards building and adding definitions; conversion is lock-free.
"""

from __future__ import annotations

import dataclasses
import numbers
import operator
import os
import struct
import sys
import threading
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np
from cyclonedds.idl import IdlStruct, make_idl_struct
from cyclonedds.idl import types as t
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import Nodetype

if TYPE_CHECKING:
    from rosbags.interfaces.typing import Constdefs, Fielddefs, Typesdict

from .errors import ConversionError, UnknownTypeError
from .names import dds_type_name, split_type_name

__all__ = ["MessageTypes", "DISTROS", "message_to_dict"]

#: the ROS 2 distros whose message definitions rosbags ships, by their ROS name
DISTROS = MappingProxyType({"humble": Stores.ROS2_HUMBLE, "iron": Stores.ROS2_IRON, "jazzy": Stores.ROS2_JAZZY,
           "kilted": Stores.ROS2_KILTED})
_HASHED = frozenset({"iron", "jazzy", "kilted"})  # rmw puts RIHS01 type hashes in user data since Iron
MAX_PREFIXES = 64  #: AMENT_PREFIX_PATH's prefixes looked in, at most
MAX_FILE_BYTES = 1 << 20  #: a definition file found there larger than this is refused

#: a few standard service definitions, so that they work without a .srv file
STANDARD_SERVICES = MappingProxyType({
    "std_srvs/srv/Empty": "---\n",
    "std_srvs/srv/Trigger": "---\nbool success\nstring message\n",
    "std_srvs/srv/SetBool": "bool data\n---\nbool success\nstring message\n",
    "example_interfaces/srv/AddTwoInts": "int64 a\nint64 b\n---\nint64 sum\n",
    # a node's parameter services (rcl_interfaces), as ros2 param calls them
    "rcl_interfaces/srv/GetParameters": "string[] names\n---\nrcl_interfaces/msg/ParameterValue[] values\n",
    "rcl_interfaces/srv/SetParameters": "rcl_interfaces/msg/Parameter[] parameters\n---\n"
                                        "rcl_interfaces/msg/SetParametersResult[] results\n",
    "rcl_interfaces/srv/ListParameters": "uint64 DEPTH_RECURSIVE=0\nstring[] prefixes\nuint64 depth\n---\n"
                                         "rcl_interfaces/msg/ListParametersResult result\n",
    "rcl_interfaces/srv/DescribeParameters": "string[] names\n---\n"
                                             "rcl_interfaces/msg/ParameterDescriptor[] descriptors\n",
    "rcl_interfaces/srv/GetParameterTypes": "string[] names\n---\nuint8[] types\n",
    # and its logger services (rclpy's since Iron)
    "rcl_interfaces/srv/GetLoggerLevels": "string[] names\n---\nrcl_interfaces/msg/LoggerLevel[] levels\n",
    "rcl_interfaces/srv/SetLoggerLevels": "rcl_interfaces/msg/LoggerLevel[] levels\n---\n"
                                          "rcl_interfaces/msg/SetLoggerLevelsResult[] results\n",
})
#: rmw_cyclonedds' cdds_request_header_t {uint64 guid; int64 seq}, as IDL members whose
#: trailing ``_`` no ROS field name has (so they never clash with a request's fields)
REQUEST_HEADER = MappingProxyType({"guid_": t.uint64, "seq_": t.int64})

_INT = MappingProxyType({"byte": (-128, 255, t.byte), "char": (0, 255, t.uint8), "int8": (-128, 127, t.int8),
        "uint8": (0, 255, t.uint8), "int16": (-(1 << 15), (1 << 15) - 1, t.int16),
        "uint16": (0, (1 << 16) - 1, t.uint16), "int32": (-(1 << 31), (1 << 31) - 1, t.int32),
        "uint32": (0, (1 << 32) - 1, t.uint32), "int64": (-(1 << 63), (1 << 63) - 1, t.int64),
        "uint64": (0, (1 << 64) - 1, t.uint64)})
_DTYPE = MappingProxyType({"bool": np.bool_, "byte": np.int8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
          "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32,
          "int64": np.int64, "uint64": np.uint64, "float32": np.float32, "float64": np.float64})
_FLOAT32_MAX = float(np.finfo(np.float32).max)
_Conv = Callable[[Any], Any]


class _Struct:
    """What one ROS 2 struct compiles to: IDL members, converters and zero values."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.members: dict[str, object] = {}
        self.to_idl: dict[str, _Conv] = {}
        self.from_idl: dict[str, _Conv] = {}
        self.zero: dict[str, Callable[[], object]] = {}


class MessageTypes:
    """ROS 2 message definitions of one distro plus the user's, as Cyclone DDS IDL types.

    ``distro`` is ``humble``, ``iron``, ``jazzy`` (default) or ``kilted``; raises
    ``ValueError`` for another. ``prefix_path``: where unknown types are looked for (the
    module docstring; ``os.pathsep``-separated, default ``AMENT_PREFIX_PATH``). Thread-safe;
    types are built on first use and cached.
    """

    def __init__(self, distro: str = "jazzy", prefix_path: str | None = None) -> None:
        if distro not in DISTROS:
            raise ValueError(f"unknown ROS 2 distro {distro!r}: one of {', '.join(DISTROS)}")
        self.distro = distro
        text = os.environ.get("AMENT_PREFIX_PATH", "") if prefix_path is None else prefix_path
        #: the install prefixes whose ``share/PKG/msg|srv`` folders unknown types are looked for in
        self.prefixes = tuple(Path(p) for p in text.split(os.pathsep) if p)[:MAX_PREFIXES]
        self._looked: set[str] = set()  # types looked for there already (found or not)
        self._store = get_typestore(DISTROS[distro])
        self._lock = threading.RLock()
        self._structs: dict[str, _Struct] = {}
        self._idl: dict[str, type[IdlStruct]] = {}
        self._services: dict[str, tuple[str, str]] = {}
        self._hashes: dict[str, str | None] = {}

    # ----------------------------------------------------------------- definitions
    def add_msg(self, name: str, text: str) -> None:
        """Add message ``pkg/msg/Name`` from its ``.msg`` text (its references resolve in
        ``pkg`` and the store). Raises ``ValueError`` for a bad name or definition."""
        package, kind, short = split_type_name(name)
        if kind != "msg":
            raise ValueError(f"{name!r}: a message type is named pkg/msg/Type")
        self._register({name: self._parse(f"{package}/msg/{short}", text, name)})

    def add_msg_file(self, path: str | Path, name: str | None = None) -> str:
        """Add the message in ``path`` (``.../pkg/msg/Name.msg`` names itself; else give
        ``name``); returns its type name. Raises ``OSError``/``ValueError``."""
        file = Path(path)
        if name is None:
            name = f"{file.parent.parent.name}/{file.parent.name}/{file.stem}"
        self.add_msg(name, file.read_text(encoding="utf-8"))
        return name

    def add_srv(self, name: str, text: str) -> None:
        """Add service ``pkg/srv/Name`` from its ``.srv`` text (request ``---`` response)."""
        package, kind, short = split_type_name(name)
        if kind != "srv":
            raise ValueError(f"{name!r}: a service type is named pkg/srv/Type")
        lines = text.splitlines()
        cuts = [i for i, line in enumerate(lines) if line.strip() == "---"]
        if len(cuts) != 1:
            raise ValueError(f"{name!r}: a .srv definition has one '---' line between request and response")
        parts = {"Request": lines[:cuts[0]], "Response": lines[cuts[0] + 1:]}
        defs = {f"{name}_{part}": self._parse(f"{package}/msg/{short}_{part}", "\n".join(body) + "\n", name)
                for part, body in parts.items()}
        self._register(defs)
        self._services[name] = (f"{name}_Request", f"{name}_Response")

    def add_srv_file(self, path: str | Path, name: str | None = None) -> str:
        """Add the service in ``path`` (``.../pkg/srv/Name.srv``); returns its name."""
        file = Path(path)
        if name is None:
            name = f"{file.parent.parent.name}/{file.parent.name}/{file.stem}"
        self.add_srv(name, file.read_text(encoding="utf-8"))
        return name

    def _parse(self, parse_name: str, text: str, shown: str) -> tuple[Constdefs, Fielddefs]:
        if not text.strip():  # rosidl gives an empty struct one uint8 member
            text = "uint8 structure_needs_at_least_one_member\n"
        try:
            (definition,) = get_types_from_msg(text, parse_name).values()
        except Exception as exc:  # rosbags raises its own parse errors
            raise ValueError(f"{shown}: bad definition: {exc}") from None
        return definition

    def _register(self, defs: Typesdict) -> None:
        with self._lock:
            for name in defs:
                if name in self._store.fielddefs:
                    raise ValueError(f"{name} is already defined")
            self._store.register(defs)

    def names(self) -> tuple[str, ...]:
        """Every message type name known, sorted."""
        return tuple(sorted(self._store.fielddefs))

    def has(self, name: str) -> bool:
        """Whether message type ``name`` is known."""
        return name in self._store.fielddefs

    def fields(self, name: str) -> Fielddefs:
        """The fields of message ``name`` in order: ``(field, rosbags field description)``;
        raises :class:`UnknownTypeError`."""
        return self._fields(name)

    def message_class(self, name: str) -> type:
        """The rosbags message class of ``name``; raises :class:`UnknownTypeError`."""
        self._fields(name)
        return self._store.types[name]

    def service(self, name: str) -> tuple[str, str]:
        """The request and response message names of service ``pkg/srv/Name`` (a standard
        one is added on first use); raises :class:`UnknownTypeError`."""
        with self._lock:
            if name not in self._services and name in STANDARD_SERVICES:
                self.add_srv(name, STANDARD_SERVICES[name])
            if name not in self._services:
                self._look_up(name)
            if name not in self._services:
                raise UnknownTypeError(f"unknown ROS 2 service type {name!r}: add its .srv with add_srv (or its "
                                       "package's install prefix to AMENT_PREFIX_PATH)")
            return self._services[name]

    def _look_up(self, name: str) -> None:
        """Add ``pkg/msg/Type`` (``pkg/srv/Type``) from its file under :attr:`prefixes`
        when there is one (once per type). A file found there that is not a definition
        raises ``UnknownTypeError`` naming it."""
        with self._lock:
            if name in self._looked or not self.prefixes:
                return
            self._looked.add(name)
            try:
                package, kind, short = split_type_name(name)
            except ValueError:
                return
            if kind not in ("msg", "srv"):
                return
            for prefix in self.prefixes:
                file = prefix / "share" / package / kind / f"{short}.{kind}"
                try:
                    if not file.is_file():
                        continue
                    if file.stat().st_size > MAX_FILE_BYTES:
                        raise ValueError(f"larger than {MAX_FILE_BYTES} bytes")
                    (self.add_srv_file if kind == "srv" else self.add_msg_file)(file, name)
                except (OSError, UnicodeDecodeError, ValueError) as exc:
                    raise UnknownTypeError(f"ROS 2 type {name!r}: {file}: {exc}") from None
                return

    def type_hash(self, name: str) -> str | None:
        """The RIHS01 type hash rmw announces for ``name`` (Iron and later), else None."""
        if self.distro not in _HASHED:
            return None
        with self._lock:
            if name not in self._hashes:
                self._fields(name)
                self._hashes[name] = self._store.hash_rihs01(name)
            return self._hashes[name]

    # ----------------------------------------------------------------- IDL types
    def idl_type(self, name: str) -> type[IdlStruct]:
        """The cyclonedds ``IdlStruct`` of message ``name`` (DDS type name
        ``pkg::msg::dds_::Type_``); cached. Raises :class:`UnknownTypeError`."""
        found = self._idl.get(name)
        if found is None:
            with self._lock:
                found = self._idl.get(name)
                if found is None:
                    found = self._make_idl(name, dds_type_name(name), {})
                    self._idl[name] = found
        return found

    def service_idl_type(self, part_name: str) -> type[IdlStruct]:
        """The IDL struct of a service request or response message (``pkg/srv/Name_Request``)
        as rmw_cyclonedds sends it: the request header (``guid_``: uint64,
        ``seq_``: int64) then the message's fields."""
        key = "#" + part_name
        found = self._idl.get(key)
        if found is None:
            with self._lock:
                found = self._idl.get(key) or self._make_idl(
                    part_name, dds_type_name(part_name), dict(REQUEST_HEADER))
                self._idl[key] = found
        return found

    def _make_idl(self, name: str, typename: str, head: dict[str, object]) -> type[IdlStruct]:
        struct = self._struct(name)
        clash = set(head) & set(struct.members)
        if clash:
            raise ConversionError(f"{name}: field {sorted(clash)[0]!r} clashes with rmw's request header")
        return make_idl_struct(typename.rsplit("::", 1)[-1], typename, {**head, **struct.members})

    def _fields(self, name: str) -> Fielddefs:
        definition = self._store.fielddefs.get(name)
        if definition is None:
            self._look_up(name)
            definition = self._store.fielddefs.get(name)
        if definition is None:
            raise UnknownTypeError(f"unknown ROS 2 message type {name!r} (ROS 2 {self.distro}): add its .msg with "
                                   "add_msg (or its package's install prefix to AMENT_PREFIX_PATH)")
        return list(definition[1])

    def _struct(self, name: str) -> _Struct:
        found = self._structs.get(name)
        if found is not None:
            return found
        with self._lock:
            return self._structs.get(name) or self._build_struct(name)

    def _build_struct(self, name: str) -> _Struct:
        struct = _Struct(name)
        for field, desc in self._fields(name):
            where = f"{name}.{field}"
            struct.members[field] = self._member(desc, where)
            struct.to_idl[field] = self._to_conv(desc, where)
            struct.from_idl[field] = self._from_conv(desc)
            struct.zero[field] = self._zero(desc)
        self._structs[name] = struct
        return struct

    def _member(self, desc: Any, where: str) -> Any:
        kind, detail = desc
        if kind == Nodetype.BASE:
            return _base_member(detail, where)
        if kind == Nodetype.NAME:
            return self.idl_type(detail)
        inner, size = detail
        element = self._member(inner, where)
        if kind == Nodetype.ARRAY:
            return t.array[element, size]  # type: ignore[misc]  # cyclonedds: subscripted at run time, untyped
        return t.sequence[element, size] if size else t.sequence[element]  # type: ignore[misc]  # (as array)

    # ----------------------------------------------------------------- conversions
    def to_idl(self, name: str, value: object) -> IdlStruct:
        """``value`` (a rosbags message of ``name``, a mapping, or an instance of the IDL
        type) as an instance of :meth:`idl_type`. Raises :class:`ConversionError`."""
        cls = self.idl_type(name)
        if type(value) is cls:
            return value
        return cls(**self.to_fields(name, value))

    def to_fields(self, name: str, value: object) -> dict[str, object]:
        """The IDL member values of ``value`` by field name (see :meth:`to_idl`)."""
        struct = self._struct(name)
        if getattr(value, "__msgtype__", None) == name or _is_idl_of(value, name):  # the hot path first
            try:
                return {f: conv(getattr(value, f)) for f, conv in struct.to_idl.items()}
            except AttributeError as exc:
                raise ConversionError(f"{name}: {exc}") from None
        if isinstance(value, Mapping):
            unknown = [k for k in value if k not in struct.to_idl]
            if unknown:
                raise ConversionError(f"{name} has no field {unknown[0]!r}")
            return {f: (conv(value[f]) if f in value else struct.zero[f]())
                    for f, conv in struct.to_idl.items()}
        msgtype = getattr(value, "__msgtype__", None)
        raise ConversionError(f"expected a {name} message or a mapping, got {msgtype or type(value).__name__}")

    def from_idl(self, name: str, obj: object) -> object:
        """The rosbags message of ``name`` holding the fields of IDL instance ``obj``.
        Raises :class:`ConversionError` if ``obj`` lacks a field."""
        struct = self._structs.get(name) or self._struct(name)
        try:
            kwargs = {f: getattr(obj, f) if conv is _identity else conv(getattr(obj, f))
                      for f, conv in struct.from_idl.items()}
        except (AttributeError, TypeError, ValueError) as exc:
            raise ConversionError(f"{name}: {exc}") from None
        return self._store.types[name](**kwargs)

    def zero(self, name: str) -> Any:  # an instance of the IDL class made at run time
        """A rosbags message of ``name`` with ROS's zero values (0, "", empty sequences)."""
        return self.from_idl(name, self.to_idl(name, {}))

    def serialize(self, name: str, value: object) -> bytes:
        """``value`` as rmw's CDR bytes (4-byte encapsulation header, XCDR1 little-endian)."""
        return self.to_idl(name, value).serialize(use_version_2=False)

    def deserialize(self, name: str, data: bytes) -> object:
        """The rosbags message in CDR ``data``; raises :class:`ConversionError`."""
        try:
            obj = self.idl_type(name).deserialize(data)
        except Exception as exc:  # cyclonedds raises bare exceptions on bad bytes
            raise ConversionError(f"{name}: malformed CDR: {exc}") from None
        return self.from_idl(name, obj)

    # ----------------------------------------------------------------- CDR by rosbags
    def to_cdr(self, name: str, message: object) -> bytearray:
        """A rosbags message of ``name`` as rmw's CDR bytes, by rosbags' serialiser: each
        numpy array field copied once, straight into the bytes (Cyclone's Python
        serialiser packs a ``uint8[]`` value by value: 0.2 s for 6 MB). Padded to 4 bytes,
        as Cyclone's writer pads. Raises :class:`ConversionError` for a message that is
        not one of ``name`` or a value its field cannot hold."""
        if getattr(message, "__msgtype__", None) != name:
            raise ConversionError(f"expected a {name} message, got {type(message).__name__}")
        try:
            msgdef = self._store.get_msgdef(name)
            size = 4 + msgdef.getsize_cdr(0, message, self._store)
            data = bytearray((size + 3) & ~3)
            data[1] = sys.byteorder == "little"  # the encapsulation: plain CDR, this host's order
            serialize = msgdef.serialize_cdr_le if sys.byteorder == "little" else msgdef.serialize_cdr_be
            serialize(memoryview(data)[4:], 0, message, self._store)
        except (struct.error, TypeError, ValueError, AttributeError, OverflowError) as exc:
            raise ConversionError(f"{name}: {type(exc).__name__}: {exc}") from None
        return data

    def from_cdr(self, name: str, data: bytes) -> object:
        """The rosbags message of ``name`` in CDR ``data``, by rosbags' deserialiser: its
        numpy array fields are read-only views of ``data`` (no copy). Raises
        :class:`ConversionError` for malformed bytes."""
        try:
            return self._store.deserialize_cdr(memoryview(data), name)  # (a slice of bytes would copy them)
        except Exception as exc:  # rosbags' SerdeError, or what a truncated buffer raises
            raise ConversionError(f"{name}: malformed CDR: {exc}") from None

    def _to_conv(self, desc: Any, where: str) -> _Conv:
        kind, detail = desc
        if kind == Nodetype.BASE:
            return _base_to(detail[0], detail[1], where)
        if kind == Nodetype.NAME:
            return _nested_to(self, detail)
        inner, size = detail
        element = self._to_conv(inner, where)
        base = inner[1][0] if inner[0] == Nodetype.BASE else None
        return _sequence_to(element, base, size, kind == Nodetype.ARRAY, where)

    def _from_conv(self, desc: Any) -> _Conv:
        kind, detail = desc
        if kind == Nodetype.BASE:
            return _identity
        if kind == Nodetype.NAME:
            return _nested_from(self, detail)
        inner, _ = detail
        if inner[0] == Nodetype.BASE and inner[1][0] == "byte":  # octets on the wire (0..255), int8 as rosbags has them
            return lambda v: (np.frombuffer(v, dtype=np.uint8).copy() if isinstance(v, (bytes, bytearray))
                              else np.array(v, dtype=np.uint8)).view(np.int8)
        if inner[0] == Nodetype.BASE and inner[1][0] in _DTYPE:
            dtype = _DTYPE[inner[1][0]]
            return lambda v: (np.frombuffer(v, dtype=dtype).copy() if isinstance(v, (bytes, bytearray))
                              else np.array(v, dtype=dtype))
        element = self._from_conv(inner)
        return lambda v: [element(x) for x in v]

    def _zero(self, desc: Any) -> Callable[[], Any]:
        kind, detail = desc
        if kind == Nodetype.BASE:
            value = {"bool": False, "string": "", "float32": 0.0, "float64": 0.0}.get(detail[0], 0)
            return lambda: value
        if kind == Nodetype.NAME:
            return lambda: self.to_idl(detail, {})
        if kind == Nodetype.SEQUENCE:
            return list
        inner, size = detail
        element = self._zero(inner)
        return lambda: [element() for _ in range(size)]


def _is_idl_of(value: object, name: str) -> bool:
    idl = getattr(type(value), "__idl_typename__", None)
    return idl is not None and idl.replace(".", "::") == dds_type_name(name)


def _identity(value: object) -> object:
    return value


def _base_member(detail: tuple[str, int], where: str) -> object:
    base, bound = detail
    if base == "bool":
        return bool
    if base in ("float32", "float64"):
        return t.float32 if base == "float32" else t.float64
    if base == "string":
        return t.bounded_str[bound] if bound else str  # type: ignore[misc]  # as array: subscripted at run time
    if base in _INT:
        return _INT[base][2]
    raise ConversionError(f"{where}: ROS 2 type {base!r} is not supported (wstring, wchar, float128)")


def _base_to(base: str, bound: int, where: str) -> _Conv:
    if base in _INT:
        low, high, _ = _INT[base]
        return _int_to(low, high, where, base == "byte")
    if base in ("float32", "float64"):
        return _float_to(where, base == "float32")
    if base == "bool":
        def to_bool(value: object) -> bool:
            if isinstance(value, (bool, np.bool_)) or value in (0, 1):
                return bool(value)
            raise ConversionError(f"{where}: expected a bool, got {value!r}")
        return to_bool
    if base == "string":
        def to_str(value: object) -> str:
            if not isinstance(value, str):
                raise ConversionError(f"{where}: expected a str, got {type(value).__name__}")
            if bound and len(value) > bound:
                raise ConversionError(f"{where}: {len(value)} characters, the bound is {bound}")
            return value
        return to_str
    raise ConversionError(f"{where}: ROS 2 type {base!r} is not supported (wstring, wchar, float128)")


def _int_to(low: int, high: int, where: str, octet: bool) -> _Conv:
    def to_int(value: Any) -> int:
        try:
            number = operator.index(value)
        except TypeError:
            raise ConversionError(f"{where}: expected an integer, got {type(value).__name__}") from None
        if not low <= number <= high:
            raise ConversionError(f"{where}: {number} is out of range [{low}, {high}]")
        return number & 0xFF if octet else number
    return to_int


def _float_to(where: str, single: bool) -> _Conv:
    def to_float(value: object) -> float:
        if type(value) is not float:
            if not isinstance(value, numbers.Real):
                raise ConversionError(f"{where}: expected a number, got {type(value).__name__}")
            value = float(value)
        if single and abs(value) > _FLOAT32_MAX and value == value and abs(value) != float("inf"):
            raise ConversionError(f"{where}: {value} does not fit a float32")
        return value
    return to_float


def _nested_to(types: MessageTypes, name: str) -> _Conv:
    return lambda value: types.to_idl(name, value)


def _nested_from(types: MessageTypes, name: str) -> _Conv:
    return lambda obj: types.from_idl(name, obj)


def _sequence_to(element: _Conv, base: str | None, size: int, fixed: bool, where: str) -> _Conv:
    """Converter of a ROS array (``fixed``) or sequence (``size`` = bound, 0 for none)."""
    octets = base in ("uint8", "byte", "char")

    def to_sequence(value: Any) -> Any:
        if isinstance(value, np.ndarray):
            if value.ndim != 1:
                raise ConversionError(f"{where}: expected a 1-d array, got {value.ndim}-d")
            items: np.ndarray | Sequence[object] = value
        elif isinstance(value, (bytes, bytearray, memoryview)) and octets:
            items = bytes(value)
        elif isinstance(value, (list, tuple)):
            items = value
        else:
            raise ConversionError(f"{where}: expected a sequence, got {type(value).__name__}")
        if fixed and len(items) != size:
            raise ConversionError(f"{where}: {len(items)} elements, the array holds {size}")
        if not fixed and size and len(items) > size:
            raise ConversionError(f"{where}: {len(items)} elements, the bound is {size}")
        if octets and isinstance(items, (bytes, np.ndarray)):
            if isinstance(items, np.ndarray):
                if items.dtype.kind not in "iub":
                    raise ConversionError(f"{where}: expected integers, got {items.dtype}")
                items = items.astype(np.uint8).tobytes()
            return items if not fixed else list(items)
        if isinstance(items, np.ndarray) and base in ("float32", "float64") and items.dtype.kind in "fiu":
            return items.astype(np.float64).tolist()
        if isinstance(items, np.ndarray):
            items = items.tolist()
        return [element(x) for x in items]
    return to_sequence


def message_to_dict(message: object) -> Any:  # a dict, list, number or str: as the message holds
    """A rosbags message (or any value in one) as plain Python: dicts, lists, numbers, str."""
    if dataclasses.is_dataclass(message):  # not __msgtype__, nor constants (ROS names them in capitals)
        return {f.name: message_to_dict(getattr(message, f.name)) for f in dataclasses.fields(message)
                if f.name != "__msgtype__" and not f.name.isupper()}
    if isinstance(message, np.ndarray):
        return message.tolist()
    if isinstance(message, (list, tuple)):
        return [message_to_dict(x) for x in message]
    if isinstance(message, np.generic):
        return message.item()
    return message
