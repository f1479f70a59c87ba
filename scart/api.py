"""The Python implementation API: declarations read by the runtime from a plain class.

The Python mirror of SCA's Java annotations::

    @scart.interface(callback=Notifying)
    class Commands(Protocol):
        @scart.oneway
        def move(self, values: list[float]) -> None: ...

    @scart.component(services=[Commands])
    class Driver:
        host: str = scart.prop(default="127.0.0.1")
        caller: Notifying = scart.callback()
        planner: Planner = scart.reference()        # 1..1
        ctx: scart.ComponentContext = scart.context()
        @scart.init
        def open(self) -> None: ...

Rules: a service declared with ``services=[I]`` is named ``I.__name__``; with none, the
class offers its own public methods as one service named after the class. References
and properties are named by their attribute names; types come from annotations.
:func:`component_type` reads all of it into a :class:`ComponentType`
(cached on the class itself; pure introspection otherwise).
"""

from __future__ import annotations

import contextvars
import copy
import inspect
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Final, TypeVar, overload

from scart.errors import NoCallbackError
from scart.settings import Settings

T = TypeVar("T")
C = TypeVar("C", bound=type)
F = TypeVar("F", bound=Callable[..., object])

_MISSING: Final = object()

#: The callback target of the call being executed (set by bindings; read by ``callback()``).
CURRENT_CALLBACK: contextvars.ContextVar[object] = contextvars.ContextVar(
    "scart_current_callback", default=None
)


# --- decorators ------------------------------------------------------------------------


@overload
def component(cls: C, *, services: list[type] | None = None, scope: str = "composite",
              eager_init: bool = True) -> C: ...
@overload
def component(cls: None = None, *, services: list[type] | None = None, scope: str = "composite",
              eager_init: bool = True) -> Callable[[C], C]: ...


def component(
    cls: C | None = None,
    *,
    services: list[type] | None = None,
    scope: str = "composite",
    eager_init: bool = True,
) -> C | Callable[[C], C]:
    """Mark a class as an SCA component implementation (usable bare or with arguments).

    ``scope`` is "composite" (one instance per component) or "stateless" (one per call);
    ``eager_init=False`` defers a composite-scoped instance to its first use.
    Raises ``ValueError`` for an unknown scope.
    """
    if scope not in ("composite", "stateless"):
        raise ValueError(f"scope must be 'composite' or 'stateless', not {scope!r}")

    def mark(klass: C) -> C:
        klass.__scart_component__ = {  # type: ignore[attr-defined]  # our mark on the user's class
            "services": list(services or []),
            "scope": scope,
            "eager_init": eager_init,
        }
        if _CTYPE_ATTR in vars(klass):  # declarations changed: read them again
            delattr(klass, _CTYPE_ATTR)
        return klass

    return mark(cls) if cls is not None else mark


@overload
def interface(cls: C, *, callback: type | None = None, remotable: bool = False) -> C: ...
@overload
def interface(cls: None = None, *, callback: type | None = None, remotable: bool = False) -> Callable[[C], C]: ...


def interface(
    cls: C | None = None, *, callback: type | None = None, remotable: bool = False
) -> C | Callable[[C], C]:
    """Mark a class as a service interface; ``callback`` is the interface callers implement;
    ``remotable=True`` gives pass-by-value semantics even in-process."""

    def mark(klass: C) -> C:
        klass.__scart_interface__ = {"callback": callback, "remotable": remotable}  # type: ignore[attr-defined]  # mark
        return klass

    return mark(cls) if cls is not None else mark


def oneway(func: F) -> F:
    """Mark an operation one-way: the caller returns at once; it must return ``None``."""
    func.__scart_oneway__ = True  # type: ignore[attr-defined]  # our mark on the user's function
    return func


def init(func: F) -> F:
    """Mark the method called after injection, before the first call (targets first)."""
    func.__scart_init__ = True  # type: ignore[attr-defined]  # our mark on the user's function
    return func


def destroy(func: F) -> F:
    """Mark the method called when the component stops (reverse of init order)."""
    func.__scart_destroy__ = True  # type: ignore[attr-defined]  # our mark on the user's function
    return func


class _Spec:
    name: str = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name


class PropSpec(_Spec):
    """Declared by :func:`prop`: ``default`` (copied per instance) and ``required``."""

    def __init__(self, default: object, required: bool) -> None:
        self.default = default
        self.required = required

    def default_value(self) -> object:
        """A fresh copy of the default (mutable defaults are never shared)."""
        return None if self.default is _MISSING else copy.deepcopy(self.default)


class RefSpec(_Spec):
    """Declared by :func:`reference`."""

    def __init__(self, required: bool, multiple: bool) -> None:
        self.required = required
        self.multiple = multiple

    @property
    def multiplicity(self) -> str:
        """"1..1", "0..1", "1..n" or "0..n"."""
        return ("1.." if self.required else "0..") + ("n" if self.multiple else "1")


class CallbackSpec(_Spec):
    """Declared by :func:`callback`: reading it yields the current caller's callback proxy."""

    def __get__(self, obj: object, owner: type | None = None) -> Any:  # Any: the caller's proxy, of its interface
        if obj is None:
            return self
        target = CURRENT_CALLBACK.get()
        if target is None:
            raise NoCallbackError(
                f"{type(obj).__name__}.{self.name}: no callback: not inside a call made "
                "through a bidirectional interface by a component"
            )
        return target


class ContextSpec(_Spec):
    """Declared by :func:`context`: injected with the component's :class:`ComponentContext`."""


def prop(default: object = _MISSING, *, required: bool = False) -> Any:
    """Declare a property (named by the attribute, typed by its annotation).

    ``required=True`` is SCA mustSupply; without a default and not required the value is None.
    """
    return PropSpec(default, required)


def reference(*, required: bool = True, multiple: bool = False) -> Any:
    """Declare a reference: 1..1 by default, 0..1 (``required=False``), 1..n
    (``multiple=True``, annotated ``list[I]``), or 0..n (both)."""
    return RefSpec(required, multiple)


def callback() -> Any:
    """Declare the proxy back to the component that made the current call."""
    return CallbackSpec()


def context() -> Any:
    """Declare an attribute injected with this component's :class:`ComponentContext`."""
    return ContextSpec()


@dataclass(frozen=True)
class ComponentContext:
    """What a component knows of itself: its ``name`` (qualified by enclosing components with
    "/"), ``service(name)`` to look up a service of the runtime, like ``Runtime.service``,
    and the runtime's ``settings`` (:class:`scart.Settings`: name service, timeouts...)."""

    name: str
    lookup: Callable[[str], object] = field(repr=False)
    settings: Settings = field(default_factory=Settings, repr=False)

    def service(self, name: str) -> Any:
        """A proxy to the named service (see ``Runtime.service``)."""
        return self.lookup(name)


# --- introspection ---------------------------------------------------------------------


@dataclass(frozen=True)
class Operation:
    """One operation of an interface: its name, one-way flag and whether it returns a value."""

    name: str
    oneway: bool = False
    returns_value: bool = False


@dataclass(frozen=True)
class InterfaceInfo:
    """An interface as the runtime sees it: name, operations, callback interface, remotable."""

    name: str
    operations: dict[str, Operation]
    callback: InterfaceInfo | None = None
    remotable: bool = False
    python_type: type | None = None


@dataclass(frozen=True)
class ComponentType:
    """What an implementation class declares (the SCA componentType)."""

    cls: type
    services: dict[str, InterfaceInfo]
    references: dict[str, tuple[RefSpec, type | None]]
    properties: dict[str, tuple[PropSpec, object]]
    callbacks: tuple[str, ...]
    contexts: tuple[str, ...]
    init: tuple[str, ...]
    destroy: tuple[str, ...]
    scope: str
    eager_init: bool


_CTYPE_ATTR = "__scart_component_type__"  # the ComponentType of a class, cached on the class itself
_IFACE_ATTR = "__scart_interface_info__"


def _cached(cls: type, attr: str, kind: type[T]) -> T | None:
    """The ``kind`` cached on ``cls`` itself (never inherited from a base class), or None."""
    found: T | None = vars(cls).get(attr)  # only _cache puts it there, as a kind
    return found


def _cache(cls: type, attr: str, value: T) -> T:
    try:
        setattr(cls, attr, value)
    except (TypeError, AttributeError):  # a built-in or extension type: not cached
        pass
    return value


def interface_info(iface: type) -> InterfaceInfo:
    """The :class:`InterfaceInfo` of a Python class: its public functions are operations.

    Cached per class. Never raises for a class (an empty class has no operations).
    """
    cached = _cached(iface, _IFACE_ATTR, InterfaceInfo)
    if cached is not None:
        return cached
    meta = getattr(iface, "__scart_interface__", {}) if "__scart_interface__" in vars(iface) else {}
    ops: dict[str, Operation] = {}
    for klass in reversed(iface.__mro__):
        if klass in (object, typing.Protocol, typing.Generic) or klass.__module__ == "typing":
            continue
        for name, member in vars(klass).items():
            if name.startswith("_") or isinstance(member, _Spec):
                continue
            func = member.__func__ if isinstance(member, (classmethod, staticmethod)) else member
            if not inspect.isfunction(func):
                continue
            if getattr(func, "__scart_init__", False) or getattr(func, "__scart_destroy__", False):
                continue
            ops[name] = Operation(name, bool(getattr(func, "__scart_oneway__", False)), _returns(func))
    cb = meta.get("callback")
    info = InterfaceInfo(
        iface.__name__, ops, interface_info(cb) if cb is not None else None,
        bool(meta.get("remotable", False)), iface,
    )
    return _cache(iface, _IFACE_ATTR, info)


def _returns(func: Callable[..., object]) -> bool:
    ann = getattr(func, "__annotations__", {}).get("return", _MISSING)
    return ann is not _MISSING and ann not in (None, "None", type(None))


def _hints(cls: type) -> dict[str, object]:
    try:
        return typing.get_type_hints(cls)
    except Exception:  # unresolvable forward refs: fall back to raw annotations
        merged: dict[str, object] = {}
        for klass in reversed(cls.__mro__):
            merged.update(getattr(klass, "__annotations__", {}))
        return merged


def component_type(cls: type) -> ComponentType:
    """Read the declarations of ``cls`` (decorated with :func:`component` or not). Cached."""
    cached = _cached(cls, _CTYPE_ATTR, ComponentType)
    if cached is not None:
        return cached
    meta = getattr(cls, "__scart_component__", {})
    hints = _hints(cls)
    props: dict[str, tuple[PropSpec, object]] = {}
    refs: dict[str, tuple[RefSpec, type | None]] = {}
    callbacks: list[str] = []
    contexts: list[str] = []
    inits: list[str] = []
    destroys: list[str] = []
    for klass in reversed(cls.__mro__):
        for name, member in vars(klass).items():
            if isinstance(member, PropSpec):
                props[name] = (member, hints.get(name, str))
            elif isinstance(member, RefSpec):
                refs[name] = (member, _element_type(hints.get(name), member.multiple))
            elif isinstance(member, CallbackSpec):
                callbacks.append(name)
            elif isinstance(member, ContextSpec):
                contexts.append(name)
            elif inspect.isfunction(member):
                if getattr(member, "__scart_init__", False) and name not in inits:
                    inits.append(name)
                if getattr(member, "__scart_destroy__", False) and name not in destroys:
                    destroys.append(name)
    declared = meta.get("services") or [cls]
    services = {iface.__name__: interface_info(iface) for iface in declared}
    ctype = ComponentType(
        cls, services, refs, props, tuple(callbacks), tuple(contexts), tuple(inits),
        tuple(destroys), meta.get("scope", "composite"), meta.get("eager_init", True),
    )
    return _cache(cls, _CTYPE_ATTR, ctype)


def _element_type(ann: object, multiple: bool) -> type | None:
    if multiple and typing.get_origin(ann) in (list, typing.List):  # noqa: UP006
        args = typing.get_args(ann)
        ann = args[0] if args else None
    if typing.get_origin(ann) in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        members = [a for a in typing.get_args(ann) if a is not type(None)]
        ann = members[0] if len(members) == 1 else None
    return ann if isinstance(ann, type) else None
