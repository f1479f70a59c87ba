"""The binding plug-in interface: how a service is exported and a reference is called.

A binding kind is registered under its XML element's local name (``binding.sca``,
``binding.grpc``, ``binding.dataflow``) with :func:`register_binding`, giving a
:class:`ServiceBinding` class (service side) and/or a :class:`ReferenceBinding` class
(reference side). The runtime creates them while wiring, starts service bindings after
every component is initialised, and stops them (reverse order) before any is destroyed.

* **Service side** — ``ServiceBinding(model, endpoint, host)``: ``start()``, ``stop()``,
  ``address`` (the real address once started, e.g. "127.0.0.1:50321"). Requests arriving
  from outside become :class:`Invocation` s passed to ``endpoint.invoke()``; one-way
  operations are queued on the runtime's pool there, and ``Invocation.callback`` is the
  object the provider's ``scart.callback()`` yields (for a remote caller: a proxy that
  sends callback operations back over the call's own channel).
* **Reference side** — ``ReferenceBinding(model, interface, host)``: ``invoker(operation,
  callback)`` returns one plain callable per operation, built once at wiring time
  (no per-call lookups); ``callback`` is the calling component's callback target (an
  object with one attribute per callback operation) or None. ``start()``/``stop()``.

The local binding (:mod:`scart.bindings.local`) is the reference implementation.
"""

from __future__ import annotations

import copy
import re
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from scart.api import CURRENT_CALLBACK, InterfaceInfo, Operation
from scart.errors import Problem
from scart.model import Binding


@dataclass(frozen=True, slots=True)
class Invocation:
    """One call: operation name, arguments, and the callback target (or None)."""

    operation: str
    args: tuple[Any, ...] = ()
    kwargs: dict[str, Any] = field(default_factory=dict)
    callback: object | None = None


class BindingHost(Protocol):
    """What the runtime offers bindings."""

    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> None:
        """Run ``fn(*args, **kwargs)`` on the runtime's bounded one-way pool; errors are logged and counted."""

    def endpoint(self, name: str) -> ServiceEndpoint:
        """The endpoint of a local service ("Component/Service"); raises ``ServiceNotFoundError``."""


class ServiceEndpoint(Protocol):
    """A component service as bindings see it (implemented by the runtime)."""

    component: str
    service: str
    interface: InterfaceInfo

    def method(self, operation: str) -> Callable[..., Any]:
        """The raw callable for ``operation`` on the right instance (scope handled); no
        callback, one-way or pass-by-value handling. Raises ``KeyError`` if unknown."""

    def operation(self, name: str, callback: object | None) -> Callable[..., Any]:
        """The full callable for ``name`` (callback routed, one-way queued, by-value copied)."""

    def invoke(self, invocation: Invocation) -> Any:
        """Perform ``invocation``; returns the result (None at once for one-way)."""


class _Checked:
    """What both sides of a binding share: the static check of their XML element."""

    @classmethod
    def check(cls, model: Binding, interface: InterfaceInfo | None, contribution: object) -> list[Problem]:
        """Static problems of this binding element (before anything starts); default none.
        ``contribution`` is the :class:`scart.contribution.Contribution` (folder, imports)."""
        return []


class ServiceBinding(_Checked, ABC):
    """Service side of a binding: exports ``endpoint`` until stopped."""

    def __init__(self, model: Binding, endpoint: ServiceEndpoint, host: BindingHost) -> None:
        self.model = model
        self.endpoint = endpoint
        self.host = host

    @abstractmethod
    def start(self) -> None:
        """Start accepting calls. Called once, after every component is initialised."""

    @abstractmethod
    def stop(self) -> None:
        """Stop accepting calls and release resources; idempotent; blocks until done."""

    @property
    def address(self) -> str | None:
        """The real address once started (None for bindings without one)."""
        return None


class ReferenceBinding(_Checked, ABC):
    """Reference side of a binding: one callable per operation of ``interface``."""

    def __init__(self, model: Binding | None, interface: InterfaceInfo, host: BindingHost) -> None:
        self.model = model
        self.interface = interface
        self.host = host

    @abstractmethod
    def invoker(self, operation: Operation, callback: object | None) -> Callable[..., Any]:
        """A callable performing ``operation``; built once, called many times, thread-safe."""

    def start(self) -> None:
        """Open connections if needed (default: nothing). Called before components' @init."""

    def stop(self) -> None:
        """Close connections (default: nothing); idempotent."""


@dataclass(frozen=True)
class BindingKind:
    """A registered binding kind: its element's local name and its two sides."""

    name: str
    service: type[ServiceBinding] | None = None
    reference: type[ReferenceBinding] | None = None


BINDING_KINDS: dict[str, BindingKind] = {}


def register_binding(
    name: str, *, service: type[ServiceBinding] | None = None, reference: type[ReferenceBinding] | None = None
) -> None:
    """Register (or replace) the binding kind whose XML element is ``name`` (e.g. "binding.grpc")."""
    BINDING_KINDS[name] = BindingKind(name, service, reference)


def wrap_operation(
    call: Callable[..., Any],
    op: Operation,
    *,
    callback: object | None,
    by_value: bool,
    submit: Callable[..., None],
) -> Callable[..., Any]:
    """Compose the per-operation callable from ``call`` (the raw method).

    Adds, only where needed: deep copies of arguments and result (``by_value``, for
    remotable interfaces), routing of ``scart.callback()`` to ``callback`` (a contextvar
    set and reset around the call, also inside one-way workers), and queueing on the
    one-way pool (``op.oneway``: returns None at once). With none of these it returns
    ``call`` itself, so a plain local call costs what a direct method call costs.
    """
    inner = call
    if by_value and not op.oneway:  # a one-way call is copied once, at submit (below)
        def inner(*args: Any, _c: Callable[..., Any] = call, **kwargs: Any) -> Any:
            return by_value_copy(_c(*by_value_copy(args), **by_value_copy(kwargs)))
    if callback is not None:
        plain = inner
        var_set, var_reset = CURRENT_CALLBACK.set, CURRENT_CALLBACK.reset

        def inner(*args: Any, **kwargs: Any) -> Any:
            token = var_set(callback)
            try:
                return plain(*args, **kwargs)
            finally:
                var_reset(token)
    if op.oneway:
        work = inner
        if by_value:
            def oneway(*args: Any, **kwargs: Any) -> None:  # copy now: the caller may mutate after return
                submit(work, *by_value_copy(args), **by_value_copy(kwargs))
        else:
            def oneway(*args: Any, **kwargs: Any) -> None:
                submit(work, *args, **kwargs)
        return oneway
    return inner


_HOST_PORT = re.compile(r"^(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(?P<port>[0-9]{1,5})$")


def parse_host_port(text: str) -> tuple[str, int] | None:
    """``(host, port)`` of a "host:port" address (host a name, IPv4 or bracketed IPv6),
    or None when ``text`` is not of that shape. The port is not range-checked: see
    :func:`port_in_range`."""
    m = _HOST_PORT.match(text)
    return None if m is None else (m["host"], int(m["port"]))


def port_in_range(port: int, *, zero_ok: bool = False) -> bool:
    """Whether ``port`` is 1..65535 (0..65535 with ``zero_ok``: "any free port")."""
    return (0 if zero_ok else 1) <= port <= 65535


_ATOMIC = frozenset({int, float, str, bool, bytes, complex, type(None)})


def by_value_copy(value: Any) -> Any:
    """A deep copy of ``value`` for pass-by-value, skipping the copy when it holds only
    immutable atoms (ints, strings...), which cannot be mutated by the callee anyway."""
    kind = type(value)
    if kind in _ATOMIC:
        return value
    if kind is tuple and all(type(v) in _ATOMIC for v in value):
        return value
    if kind is dict and not value:
        return value
    return copy.deepcopy(value)
