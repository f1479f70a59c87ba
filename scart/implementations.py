"""Implementation kinds: how a component's implementation is introspected and run.

A kind is registered under its XML element's local name with
:func:`register_implementation`. It answers two questions:

* ``component_type(impl, contribution)`` — at load time, what the implementation
  declares (services, references, properties) for the static checks; raises
  :class:`ImplementationProblem` (code + message) when it cannot be used;
* ``manager(node, host)`` — at start, a :class:`ComponentManager` that creates, configures
  and destroys instances and gives the raw callable of each service operation.

``implementation.python`` is built in; ``implementation.composite`` is handled by the
assembler itself (nesting). Issue 5 adds ``implementation.task`` the same way.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from scart import errors as E
from scart.api import ComponentType, component_type
from scart.errors import RuntimeStateError, ScartError
from scart.model import Implementation

if TYPE_CHECKING:
    from scart.assembly import Node
    from scart.contribution import Contribution


class ImplementationProblem(Exception):
    """Raised by ``component_type`` : the implementation cannot be used (``code``, message)."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


class ManagerHost(Protocol):
    """What the runtime offers component managers."""

    def configure(self, node: Node, instance: object) -> None:
        """Inject properties, references, and context into a fresh ``instance``."""


class ComponentManager(ABC):
    """Owns the instances of one component. ``start``/``stop`` are called once each."""

    def __init__(self, node: Node, host: ManagerHost) -> None:
        self.node = node
        self.host = host

    @abstractmethod
    def method(self, operation: str) -> Callable[..., Any]:
        """The raw callable running ``operation`` on the right instance."""

    @abstractmethod
    def start(self) -> None:
        """Create eager instances and run their @init."""

    @abstractmethod
    def stop(self) -> None:
        """Run @destroy of live instances; idempotent."""

    def instance(self) -> object | None:
        """The current instance (composite scope), or None."""
        return None


class ImplementationKind(Protocol):
    """A registered implementation kind."""

    def component_type(self, impl: Implementation, contribution: Contribution) -> ComponentType:
        """What the implementation declares; raises :class:`ImplementationProblem`."""

    def manager(self, node: Node, host: ManagerHost) -> ComponentManager:
        """A manager for the component ``node``."""


IMPLEMENTATION_KINDS: dict[str, ImplementationKind] = {}


def register_implementation(name: str, kind: ImplementationKind) -> None:
    """Register (or replace) the implementation kind whose XML element is ``name``."""
    IMPLEMENTATION_KINDS[name] = kind


def _call_all(instance: object, names: tuple[str, ...]) -> None:
    for name in names:
        getattr(instance, name)()


class CompositeScopeManager(ComponentManager):
    """One instance for the component's life: created at start (or first use when
    ``eager_init=False``); thread-safe creation; @destroy once on stop."""

    def __init__(self, node: Node, host: ManagerHost) -> None:
        super().__init__(node, host)
        self._instance: object | None = None
        self._lock = threading.RLock()  # re-entrant: a cycle is reported, not deadlocked
        self._creating = False
        self._stopped = False

    def instance(self) -> object | None:
        """The instance if created."""
        return self._instance

    def get(self) -> object:
        """The instance, created (and initialised) on first use."""
        inst = self._instance
        if inst is not None:
            return inst
        with self._lock:
            if self._stopped:
                raise RuntimeStateError(f"component {self.node.path} is stopped")
            if self._instance is None:
                if self._creating:
                    raise ScartError(f"component {self.node.path} is used by its own @init (through a cycle "
                                     "of references); break the cycle or make one side eager")
                self._creating = True
                try:
                    ctype = self.node.ctype
                    fresh = ctype.cls()
                    self.host.configure(self.node, fresh)
                    _call_all(fresh, ctype.init)
                    self._instance = fresh
                finally:
                    self._creating = False
            return self._instance

    def method(self, operation: str) -> Callable[..., Any]:
        """The bound method when the instance exists; else a function creating it first."""
        inst = self._instance
        if inst is not None:
            return getattr(inst, operation)

        def lazy(*args: Any, **kwargs: Any) -> Any:
            return getattr(self.get(), operation)(*args, **kwargs)
        return lazy

    def start(self) -> None:
        """Create the instance now unless ``eager_init=False``."""
        if self.node.ctype.eager_init:
            self.get()

    def stop(self) -> None:
        """Run @destroy if the instance exists; idempotent."""
        with self._lock:
            inst, self._instance = self._instance, None
            if self._stopped or inst is None:
                self._stopped = True
                return
            self._stopped = True
        _call_all(inst, self.node.ctype.destroy)


class StatelessManager(ComponentManager):
    """A fresh instance per call: configured, @init, the call, @destroy."""

    def method(self, operation: str) -> Callable[..., Any]:
        """A function creating an instance per call."""
        ctype = self.node.ctype
        cls, host, node = ctype.cls, self.host, self.node

        def per_call(*args: Any, **kwargs: Any) -> Any:
            inst = cls()
            host.configure(node, inst)
            _call_all(inst, ctype.init)
            try:
                return getattr(inst, operation)(*args, **kwargs)
            finally:
                _call_all(inst, ctype.destroy)
        return per_call

    def start(self) -> None:
        """Nothing to create."""

    def stop(self) -> None:
        """Nothing to destroy."""


class PythonImplementation:
    """``<scart:implementation.python class="pkg.mod:Class"/>``."""

    def component_type(self, impl: Implementation, contribution: Contribution) -> ComponentType:
        """Import the class (contribution folder first on ``sys.path``) and read its declarations."""
        from scart.contribution import import_object

        ref = impl.attributes.get("class", "")
        try:
            cls = import_object(ref, contribution.folder)
        except Exception as exc:  # any import-time failure is a composite problem
            raise ImplementationProblem(E.SCART_IMPORT, f"cannot import {ref!r}: {type(exc).__name__}: {exc}") from exc
        if not isinstance(cls, type):
            raise ImplementationProblem(E.SCART_NOT_A_COMPONENT, f"{ref!r} is not a class")
        return component_type(cls)

    def manager(self, node: Node, host: ManagerHost) -> ComponentManager:
        """Composite- or stateless-scoped manager, per the class's scope."""
        if node.ctype.scope == "stateless":
            return StatelessManager(node, host)
        return CompositeScopeManager(node, host)


register_implementation("implementation.python", PythonImplementation())
