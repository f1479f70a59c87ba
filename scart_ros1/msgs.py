"""ROS 1 message and service types: rosbags' Noetic store plus the user's ``.msg``/``.srv``.

:class:`MessageTypes` answers, for a ROS 1 type name ``pkg/Type``, a :class:`MsgType`: its
md5sum (genmsg's), its full ``message_definition`` as ROS sends it in a connection header
(the type's text, then each dependency after a line of 80 ``=`` and ``MSG: pkg/Dep``, as
genmsg's ``compute_full_text``), and ROS 1 (de)serialisation of rosbags message objects.
For ``pkg/Srv`` it answers a :class:`SrvType`: the service md5sum (of the request's and
the response's md5 texts, as genmsg) and the two message types ``pkg/SrvRequest`` and
``pkg/SrvResponse``.

Types come from rosbags' ROS 1 Noetic store, from std_srvs' ``Empty``, ``Trigger`` and
``SetBool``, roscpp's ``Empty``, ``GetLoggers`` and ``SetLoggerLevel`` (rosbags has no
services), and from text or files the user adds
(:meth:`MessageTypes.add_msg`, :meth:`~MessageTypes.add_srv`, :meth:`~MessageTypes.add_file`),
and, for a type asked for and not known, from ``PKG/msg/Type.msg`` or ``PKG/srv/Type.srv``
in a package found through ``ROS_PACKAGE_PATH``, as rospy finds them.
A user type keeps its own text (comments too) in its definition; a store type's text is
written from its fields. Numeric arrays are numpy arrays (rosbags' form);
:meth:`MsgType.new` builds a message from keywords, lists and nested dicts included.

Thread-safe: types are registered under a lock; a :class:`MsgType` is immutable.
"""

from __future__ import annotations

import hashlib
import os
import struct
import threading
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

__all__ = ["FieldDef", "MessageTypes", "MsgType", "SrvType", "TypeDefinitionError", "UnknownTypeError"]

MAX_DEFINITION_BYTES = 1 << 20  #: a .msg/.srv text or file larger than this is refused
MAX_ROOTS, MAX_DEPTH, MAX_VISITS = 64, 3, 20_000  #: bounds of the search through ROS_PACKAGE_PATH
SEPARATOR = "=" * 80
_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4  # rosbags' Nodetype values
_ROS1_BUILTIN = MappingProxyType({"builtin_interfaces/msg/Time": "time", "builtin_interfaces/msg/Duration": "duration"})
_DTYPES = MappingProxyType({"bool": "bool_", "char": "uint8"})  # numpy's names where ROS's differ (as rosbags)
_LEN = struct.Struct("<I")

BUILTIN_SRVS = MappingProxyType({
    "std_srvs/Empty": "---\n",
    # roscpp's: in every ROS 1 installation (rosservice knows them); every node serves the last two
    "roscpp/Empty": "---\n",
    "roscpp/GetLoggers": "---\nLogger[] loggers\n",
    "roscpp/SetLoggerLevel": "string logger\nstring level\n---\n",
    "std_srvs/Trigger": "---\nbool success   # indicate successful run of triggered service\n"
    "string message # informational, e.g. for error messages\n",
    "std_srvs/SetBool": "bool data # e.g. for hardware enabling / disabling\n---\n"
    "bool success   # indicate successful run of triggered service\n"
    "string message # informational, e.g. for error messages\n",
})


@dataclass(frozen=True)
class FieldDef:
    """One field of a message type, in ROS 1's words: ``type`` is a base type (``float64``,
    ``string``, ``time``, ``duration``...) or a message type (``std_msgs/Header``);
    ``array`` is None for one value, 0 for a variable-length array, N for N values."""

    name: str
    type: str
    array: int | None = None

    @property
    def is_message(self) -> bool:
        """Whether the field (or each item of it) is a message."""
        return "/" in self.type


class UnknownTypeError(LookupError):
    """A type name that no store, built-in or user file defines."""


class TypeDefinitionError(ValueError):
    """A ``.msg``/``.srv`` text or file that cannot be read (says which and why)."""


def _split(name: str) -> tuple[str, str]:
    """``pkg/Type`` (or ``pkg/msg/Type``) → ``(pkg, Type)``; raises :class:`UnknownTypeError`."""
    parts = name.split("/") if isinstance(name, str) else []
    if len(parts) == 3 and parts[1] in ("msg", "srv"):
        parts = [parts[0], parts[2]]
    if len(parts) != 2 or not all(p.replace("_", "a").isalnum() and p[0].isalpha() for p in parts):
        raise UnknownTypeError(f"bad ROS 1 type name {name!r}: expected 'package/Type'")
    return parts[0], parts[1]


def _store_name(name: str) -> str:
    pkg, typ = _split(name)
    return f"{pkg}/msg/{typ}"


def _ros1_name(store_name: str) -> str:
    pkg, _, typ = store_name.split("/")
    return f"{pkg}/{typ}"


class MsgType:
    """One ROS 1 message type: name, md5sum, definition, and its (de)serialisers.

    ``serialize``/``frame``/``deserialize`` are thread-safe and raise ``ValueError``
    (rosbags' ``SerdeError`` or ``struct.error``) on bad input.
    """

    __slots__ = ("_de", "_getsize", "_ser", "_store", "cls", "definition", "md5sum", "name")

    def __init__(self, name: str, md5sum: str, definition: str, store: Any, store_name: str) -> None:
        msgdef = store.get_msgdef(store_name)
        self.name, self.md5sum, self.definition = name, md5sum, definition
        self.cls: type = msgdef.cls
        self._store = store
        self._getsize, self._ser, self._de = msgdef.getsize_ros1, msgdef.serialize_ros1, msgdef.deserialize_ros1

    def __repr__(self) -> str:
        return f"MsgType({self.name!r}, md5sum={self.md5sum!r})"

    def serialize(self, msg: object) -> bytes:
        """ROS 1 bytes of ``msg`` (a message object of this type)."""
        return bytes(self.frame(msg))[4:]

    def frame(self, msg: object) -> bytearray:
        """``msg`` as one TCPROS frame: the 4-byte little-endian length, then its bytes."""
        size = self._getsize(0, msg, self._store)
        buf = bytearray(4 + size)
        _LEN.pack_into(buf, 0, size)
        self._ser(memoryview(buf)[4:], 0, msg, self._store)
        return buf

    def deserialize(self, data: bytes | bytearray | memoryview) -> object:
        """The message object in ``data``; raises ``ValueError`` if ``data`` is not one."""
        try:
            msg, pos = self._de(data, 0, self.cls, self._store)
        except (struct.error, UnicodeDecodeError, ValueError, IndexError) as exc:
            raise ValueError(f"bad {self.name} message: {exc}") from exc
        if pos != len(data):
            raise ValueError(f"bad {self.name} message: {len(data) - pos} bytes left over")
        return msg

    def new(self, **fields: object) -> object:
        """A message of this type: unnamed fields take ROS's defaults (0, '', [], ...).

        Lists become numpy arrays where rosbags wants them; a dict for a nested message
        is built recursively. Raises ``TypeError`` for an unknown field.
        """
        return _build(self._store, _store_name(self.name), fields)


def _build(store: Any, store_name: str, fields: dict[str, Any]) -> object:
    _, entries = _fielddefs(store)[store_name]
    names = {n for n, _ in entries}
    unknown = set(fields) - names
    if unknown:
        raise TypeError(f"{_ros1_name(store_name)} has no field {', '.join(sorted(unknown))}")
    values = {name: _value(store, desc, fields[name] if name in fields else None) for name, desc in entries}
    return store.types[store_name](**values)


def _value(store: Any, desc: tuple, given: Any) -> Any:
    kind, arg = desc
    if kind == _BASE:
        return given if given is not None else ("" if arg[0] == "string" else False if arg[0] == "bool" else 0)
    if kind == _NAME:
        return given if given is not None and not isinstance(given, dict) else _build(store, arg, given or {})
    (subkind, subarg), count = arg
    if subkind == _BASE and subarg[0] != "string":
        dtype = getattr(numpy, _DTYPES.get(subarg[0], subarg[0]))
        return numpy.asarray(given if given is not None else [0] * (count if kind == _ARRAY else 0), dtype=dtype)
    items = list(given) if given is not None else [None] * (count if kind == _ARRAY else 0)
    return [_value(store, (subkind, subarg), item) for item in items]


class SrvType:
    """One ROS 1 service type: name, md5sum, and its request and response message types."""

    __slots__ = ("md5sum", "name", "request", "response")

    def __init__(self, name: str, md5sum: str, request: MsgType, response: MsgType) -> None:
        self.name, self.md5sum, self.request, self.response = name, md5sum, request, response

    def __repr__(self) -> str:
        return f"SrvType({self.name!r}, md5sum={self.md5sum!r})"


class MessageTypes:
    """ROS 1 types by name: rosbags' Noetic store, std_srvs, and the user's additions.

    ``msg_files``/``srv_files`` are added as :meth:`add_file` adds them. Building one
    loads rosbags' store (about 0.1 s); nodes may share one.
    """

    def __init__(self, files: Iterable[str | Path] = (), package_path: str | None = None) -> None:
        #: where unknown types are looked for (``ROS_PACKAGE_PATH`` unless given)
        self.package_path = [Path(p) for p in (os.environ.get("ROS_PACKAGE_PATH", "") if package_path is None
                                               else package_path).split(os.pathsep) if p][:MAX_ROOTS]
        self._looked: set[str] = set()  # types looked for there already (found or not)
        self._store = get_typestore(Stores.ROS1_NOETIC)
        self._defs = _fielddefs(self._store)  # the store's own dict: register() updates it
        self._lock = threading.RLock()
        self._files: dict[Path, str] = {}  # files added (resolved) -> the type each defines
        self._texts: dict[str, str] = {}  # store name → the user's own text
        self._srvs: dict[str, tuple[str, str]] = {}  # ros1 name → (request store name, response store name)
        self._msg_cache: dict[str, MsgType] = {}
        self._srv_cache: dict[str, SrvType] = {}
        self.add_msg("roscpp/Logger", "string name\nstring level\n")
        for name, text in BUILTIN_SRVS.items():
            self.add_srv(name, text)
        for path in files:
            self.add_file(path)

    # -- adding types ---------------------------------------------------------------------
    def add_msg(self, name: str, text: str) -> None:
        """Add message type ``name`` (``pkg/Type``) defined by ``text`` (a ``.msg`` body).

        Raises :class:`TypeDefinitionError` if it does not parse or clashes with a known
        type of the same name but other fields.
        """
        self._register({_store_name(name): text}, where=name)

    def add_srv(self, name: str, text: str) -> None:
        """Add service type ``name`` (``pkg/Srv``) from ``text`` (request ``---`` response)."""
        pkg, typ = _split(name)
        request, sep, response = _split_srv(text)
        if not sep:
            raise TypeDefinitionError(f"{name}: a .srv text needs a '---' line between request and response")
        req, resp = f"{pkg}/msg/{typ}Request", f"{pkg}/msg/{typ}Response"
        self._register({req: request, resp: response}, where=name, offsets={resp: request.count("\n") + 1})
        with self._lock:
            self._srvs[f"{pkg}/{typ}"] = (req, resp)

    def add_file(self, path: str | Path, package: str | None = None) -> str:
        """Add a ``.msg`` or ``.srv`` file; returns the type name it defines.

        The package is ``package`` or, as in a ROS package's layout ``PKG/msg/Type.msg``,
        the name of the folder above ``msg``/``srv``. A file added before is not read again
        (every stream and service naming it asks). Raises :class:`TypeDefinitionError`.
        """
        path = Path(path)
        if path.suffix not in (".msg", ".srv"):
            raise TypeDefinitionError(f"{path}: not a .msg or .srv file")
        key = path.resolve()
        with self._lock:
            known = self._files.get(key)
        if known is not None and package is None:
            return known
        pkg = package or key.parent.parent.name
        try:
            if path.stat().st_size > MAX_DEFINITION_BYTES:
                raise TypeDefinitionError(f"{path}: larger than {MAX_DEFINITION_BYTES} bytes")
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise TypeDefinitionError(f"{path}: {exc}") from exc
        name = f"{pkg}/{path.stem}"
        try:
            (self.add_msg if path.suffix == ".msg" else self.add_srv)(name, text)
        except (TypeDefinitionError, UnknownTypeError) as exc:
            raise TypeDefinitionError(f"{path}: {exc}") from exc
        if package is None:
            with self._lock:
                self._files[key] = name
        return name

    def _register(self, texts: dict[str, str], where: str, offsets: dict[str, int] | None = None) -> None:
        parsed: dict = {}
        for store_name, text in texts.items():
            if len(text.encode()) > MAX_DEFINITION_BYTES:
                raise TypeDefinitionError(f"{where}: definition larger than {MAX_DEFINITION_BYTES} bytes")
            try:
                parsed.update(get_types_from_msg(text, store_name))
            except (TypesysError, ValueError) as exc:
                bad = _bad_line(text, store_name, (offsets or {}).get(store_name, 0))
                raise TypeDefinitionError(f"{where}: {bad or exc}") from None
        try:
            with self._lock:
                self._store.register(parsed)
                self._texts.update(texts)
                self._msg_cache.clear()
                self._srv_cache.clear()
        except (TypesysError, ValueError, KeyError) as exc:
            raise TypeDefinitionError(f"{where}: {exc}") from None

    # -- looking types up -----------------------------------------------------------------
    def names(self) -> list[str]:
        """Every message type name known, in ROS 1 form, sorted."""
        with self._lock:
            return sorted(_ros1_name(n) for n in self._defs if "/msg/" in n)

    def fields(self, name: str) -> tuple[FieldDef, ...]:
        """The fields of message type ``name`` (``pkg/Type``), in order; raises
        :class:`UnknownTypeError` (what a caller maps its own values onto)."""
        store_name = _store_name(name)
        with self._lock:
            self._check_known(store_name, name)
            entries = self._defs[store_name][1]
        return tuple(_field_def(n, desc) for n, desc in entries if n != "structure_needs_at_least_one_member")

    def time_class(self, word: str = "time") -> type:
        """The class of ROS 1's ``time`` or ``duration`` (fields ``sec``, ``nanosec``)."""
        for store_name, ros1 in _ROS1_BUILTIN.items():
            if ros1 == word:
                return self._store.types[store_name]
        raise UnknownTypeError(f"{word!r} is not a ROS 1 built-in type (time, duration)")

    def msg(self, name: str) -> MsgType:
        """The message type ``name`` (``pkg/Type``); raises :class:`UnknownTypeError`."""
        store_name = _store_name(name)
        with self._lock:
            found = self._msg_cache.get(store_name)
            if found is None:
                self._check_known(store_name, name)
                md5sum = _md5(self._md5_text(store_name, {}))
                found = MsgType(_ros1_name(store_name), md5sum, self._full_text(store_name), self._store, store_name)
                self._msg_cache[store_name] = found
            return found

    def srv(self, name: str) -> SrvType:
        """The service type ``name`` (``pkg/Srv``); raises :class:`UnknownTypeError`."""
        pkg, typ = _split(name)
        key = f"{pkg}/{typ}"
        with self._lock:
            found = self._srv_cache.get(key)
            if found is None:
                if key not in self._srvs and not self._look_up(pkg, typ, "srv"):
                    raise UnknownTypeError(f"unknown ROS 1 service type {name!r} (add its .srv file, or its "
                                           "package's folder to ROS_PACKAGE_PATH)")
                req, resp = self._srvs[key]
                md5sum = _md5(self._md5_text(req, {}) + self._md5_text(resp, {}))
                found = SrvType(key, md5sum, self.msg(_ros1_name(req)), self.msg(_ros1_name(resp)))
                self._srv_cache[key] = found
            return found

    def _look_up(self, pkg: str, typ: str, kind: str) -> bool:
        """Add ``pkg/typ`` from its ``.msg``/``.srv`` file found through the package path
        (once per type); True when it was found and added."""
        key = f"{pkg}/{kind}/{typ}"
        if not self.package_path or key in self._looked:
            return False
        self._looked.add(key)
        found = find_definition(self.package_path, pkg, typ, kind)
        if found is None:
            return False
        self.add_file(found, pkg)
        return True

    def _check_known(self, store_name: str, asked: str) -> None:
        """Raise :class:`UnknownTypeError` if ``store_name`` or any type it uses is unknown
        (after looking for it through the package path)."""
        todo, seen = [store_name], set()
        while todo:
            current = todo.pop()
            if current in seen:
                continue
            seen.add(current)
            if current not in self._defs:
                pkg, _, typ = current.partition("/msg/")
                self._look_up(pkg, typ, "msg")
            if current not in self._defs:
                what = "" if current == store_name else f" (used by {asked})"
                raise UnknownTypeError(f"unknown ROS 1 message type {_ros1_name(current)!r}{what}: add its .msg file, "
                                       "or its package's folder to ROS_PACKAGE_PATH")
            todo.extend(self._deps(current))

    # -- genmsg's texts -------------------------------------------------------------------
    def _deps(self, store_name: str) -> list[str]:
        """The message types ``store_name``'s fields use, in field order (no time/duration)."""
        out = []
        for _, (kind, arg) in self._defs[store_name][1]:
            sub = arg if kind == _NAME else arg[0][1] if kind in (_ARRAY, _SEQUENCE) and arg[0][0] == _NAME else None
            if sub is not None and sub not in _ROS1_BUILTIN and sub not in out:
                out.append(sub)
        return out

    def _lines(self, store_name: str, md5s: dict[str, str] | None) -> list[str]:
        """genmsg's lines for a type: constants, then fields; with md5s, the md5 text's form."""
        consts, fields = self._defs[store_name]
        lines = [f"{typ} {name}={value}" for name, typ, value in consts]
        for name, (kind, arg) in fields:
            if name == "structure_needs_at_least_one_member":
                continue
            if kind in (_BASE, _NAME):
                lines.append(f"{self._type_text(kind, arg, md5s)} {name}")
                continue
            (subkind, subarg), count = arg
            if md5s is not None and subkind == _NAME and subarg not in _ROS1_BUILTIN:
                lines.append(f"{md5s[subarg]} {name}")  # genmsg: a message array hashes as its md5 alone
                continue
            size = "" if count == 0 else str(count) if kind == _ARRAY else f"<={count}"
            lines.append(f"{self._type_text(subkind, subarg, None)}[{size}] {name}")
        return lines

    def _type_text(self, kind: int, arg: Any, md5s: dict[str, str] | None) -> str:
        if kind == _BASE:
            typ, bound = arg
            return f"string<={bound}" if typ == "string" and bound else typ
        if arg in _ROS1_BUILTIN:
            return _ROS1_BUILTIN[arg]
        return md5s[arg] if md5s is not None else _ros1_name(arg)

    def _md5_text(self, store_name: str, memo: dict[str, str]) -> str:
        md5s = {}
        for dep in self._deps(store_name):
            if dep not in memo:
                memo[dep] = _md5(self._md5_text(dep, memo))
            md5s[dep] = memo[dep]
        return "\n".join(self._lines(store_name, md5s))

    def _text(self, store_name: str) -> str:
        own = self._texts.get(store_name)
        return own if own is not None else "\n".join([*self._lines(store_name, None), ""])

    def _full_text(self, store_name: str) -> str:
        """genmsg's ``compute_full_text``: the type's text, then each dependency, depth first."""
        parts = [self._text(store_name), "\n"]
        order: list[str] = []
        self._all_deps(store_name, order)
        for dep in order:
            parts += [SEPARATOR, "\n", f"MSG: {_ros1_name(dep)}\n", self._text(dep), "\n"]
        return "".join(parts)[:-1]

    def _all_deps(self, store_name: str, order: list[str]) -> None:
        for dep in self._deps(store_name):
            if dep not in order:
                order.append(dep)
                self._all_deps(dep, order)


def find_definition(roots: Iterable[Path], pkg: str, typ: str, kind: str) -> Path | None:
    """``PKG/KIND/TYPE.KIND`` under one of ``roots`` (``ROS_PACKAGE_PATH``'s folders): a root
    that is the package, a package folder in a root, or one found at most
    :data:`MAX_DEPTH` folders down (a catkin workspace's ``src``), as rospack finds
    packages; hidden folders are skipped and the search is bounded (:data:`MAX_VISITS`)."""
    wanted = Path(kind) / f"{typ}.{kind}"
    visits = 0
    for root in roots:
        level = [root]
        for _ in range(MAX_DEPTH + 1):
            deeper = []
            for folder in level:
                visits += 1
                if visits > MAX_VISITS:
                    return None
                if folder.name == pkg and (folder / wanted).is_file():
                    return folder / wanted
                try:
                    deeper += [f for f in folder.iterdir() if f.is_dir() and not f.name.startswith(".")
                               and f.name not in ("msg", "srv")]
                except OSError:
                    continue
            level = deeper
    return None


def _field_def(name: str, desc: tuple) -> FieldDef:
    kind, arg = desc
    if kind in (_BASE, _NAME):
        return FieldDef(name, _type_word(kind, arg))
    (subkind, subarg), count = arg
    return FieldDef(name, _type_word(subkind, subarg), count if kind == _ARRAY else 0)


def _type_word(kind: int, arg: Any) -> str:
    if kind == _BASE:
        return str(arg[0])
    return _ROS1_BUILTIN.get(arg) or _ros1_name(arg)


def _fielddefs(store: Any) -> dict:
    """The store's parse trees by type name (``FIELDDEFS`` before rosbags 0.10.x renamed it)."""
    return store.fielddefs if hasattr(store, "fielddefs") else store.FIELDDEFS


def _md5(text: str) -> str:
    return hashlib.md5(text.encode(), usedforsecurity=False).hexdigest()


def _bad_line(text: str, store_name: str, offset: int) -> str:
    """``line N: TEXT cannot be parsed`` for the first line of ``text`` rosbags refuses."""
    for number, line in enumerate(text.splitlines(), 1 + offset):
        try:
            get_types_from_msg(line, store_name)
        except (TypesysError, ValueError):
            return f"line {number}: {line.strip()[:80]!r} cannot be parsed"
    return ""


def _split_srv(text: str) -> tuple[str, str, str]:
    """A .srv text's request, separator (empty if none) and response."""
    lines = text.splitlines(keepends=True)
    for i, line in enumerate(lines):
        if line.strip() == "---":
            return "".join(lines[:i]), "---", "".join(lines[i + 1 :])
    return text, "", ""
