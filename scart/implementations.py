"""``implementation.python``: a plain Python class as a component (built into the core).

:class:`PythonImplementation` is the provider (see :mod:`scart.spi`): at load time it
imports the class from the contribution and reads its declarations
(:func:`scart.api.component_type`); at start it gives each component a manager by scope:
:class:`CompositeScopeManager` (one instance for the component's life) or
:class:`StatelessManager` (one instance per call). ``implementation.composite`` is
handled by the assembler itself (nesting).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from scart import errors as E
from scart.api import ComponentType, component_type
from scart.errors import RuntimeStateError, ScartError
from scart.model import Implementation
from scart.spi import CheckContext, ComponentManager, Host, ImplementationProblem, ImplementationProvider, Invoker

if TYPE_CHECKING:
    from scart.graph import Node

__all__ = ["CompositeScopeManager", "PythonImplementation", "StatelessManager"]


def _call_all(instance: object, names: tuple[str, ...], manager: ComponentManager | None = None,
              label: str = "") -> None:
    for name in names:
        if manager is not None:
            manager.stage = f"{label} {name}"
        getattr(instance, name)()


class CompositeScopeManager(ComponentManager):
    """One instance for the component's life: created at start (or first use when
    ``eager_init=False``); thread-safe creation; @destroy once on stop."""

    def __init__(self, node: Node, host: Host) -> None:
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
                    self.stage = "creating the instance"
                    fresh = ctype.cls()
                    self.host.configure(self.node, fresh)
                    _call_all(fresh, ctype.init, self, "@init")
                    self.stage = "started"
                    self._instance = fresh
                finally:
                    self._creating = False
            return self._instance

    def method(self, operation: str) -> Invoker:
        """The bound method when the instance exists; else a function creating it first."""
        inst = self._instance
        if inst is not None:
            return getattr(inst, operation)

        def lazy(*args: object, **kwargs: object) -> object:
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

    def method(self, operation: str) -> Invoker:
        """A function creating an instance per call."""
        ctype = self.node.ctype
        cls, host, node = ctype.cls, self.host, self.node

        def per_call(*args: object, **kwargs: object) -> object:
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


class PythonImplementation(ImplementationProvider):
    """``<scart:implementation.python class="pkg.mod:Class"/>``."""

    name = "implementation.python"

    def component_type(self, impl: Implementation, context: CheckContext) -> ComponentType:
        """Import the class (contribution folder first on ``sys.path``) and read its declarations."""
        ref = impl.attributes.get("class", "")
        try:
            cls = context.import_object(ref)
        except Exception as exc:  # any import-time failure is a composite problem
            raise ImplementationProblem(E.SCART_IMPORT, f"cannot import {ref!r}: {type(exc).__name__}: {exc}") from exc
        if not isinstance(cls, type):
            raise ImplementationProblem(E.SCART_NOT_A_COMPONENT, f"{ref!r} is not a class")
        return component_type(cls)

    def manager(self, node: Node, host: Host) -> ComponentManager:
        """Composite- or stateless-scoped manager, per the class's scope."""
        if node.ctype.scope == "stateless":
            return StatelessManager(node, host)
        return CompositeScopeManager(node, host)
