"""In-process calls: the local binding (``binding.sca``, the default when a wire names no
binding) and the per-operation callables every binding ends up calling.

:func:`wrap_operation` composes what a call needs beyond the raw method (pass-by-value
copies, callback routing, one-way queueing) and nothing more: for a composite-scoped
target with no callback, no one-way and no remotable interface, the local reference's
invoker is the target instance's bound method itself (no overhead at all).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any, TypeVar

from scart.api import CURRENT_CALLBACK, InterfaceInfo, Operation
from scart.model import Binding
from scart.spi import BindingProvider, Host, Invoker, ReferenceBinding, ServiceBinding, ServiceEndpoint

__all__ = ["LocalBinding", "LocalReferenceBinding", "LocalServiceBinding", "by_value_copy", "wrap_operation"]


class LocalServiceBinding(ServiceBinding):
    """Nothing to export in-process: local references reach the endpoint directly."""

    def start(self) -> None:
        """No-op."""

    def stop(self) -> None:
        """No-op (idempotent)."""

    @property
    def address(self) -> str | None:
        """"Component/Service" — the name local callers use."""
        return f"{self.endpoint.component}/{self.endpoint.service}"


class LocalReferenceBinding(ReferenceBinding):
    """Calls ``target`` in-process (``target`` given by the runtime, or ``uri`` "Comp/Service")."""

    def __init__(
        self, model: Binding | None, interface: InterfaceInfo, host: Host,
        target: ServiceEndpoint | None = None,
    ) -> None:
        super().__init__(model, interface, host)
        if target is None:
            uri = (model.attributes.get("uri") if model is not None else None) or ""
            target = host.endpoint(uri)
        self.target = target

    def invoker(self, operation: Operation, callback: object | None) -> Invoker:
        """The target endpoint's callable for ``operation`` (see ``ServiceEndpoint.operation``)."""
        return self.target.operation(operation.name, callback)


class LocalBinding(BindingProvider):
    """The ``binding.sca`` provider: in-process service and reference sides."""

    name = "binding.sca"

    def service(self, model: Binding, endpoint: ServiceEndpoint, host: Host) -> ServiceBinding:
        """A :class:`LocalServiceBinding`."""
        return LocalServiceBinding(model, endpoint, host)

    def reference(self, model: Binding, interface: InterfaceInfo, host: Host) -> ReferenceBinding:
        """A :class:`LocalReferenceBinding` to the service named by ``@uri``."""
        return LocalReferenceBinding(model, interface, host)


def wrap_operation(
    call: Invoker,
    op: Operation,
    *,
    callback: object | None,
    by_value: bool,
    submit: Callable[..., None],
) -> Invoker:
    """Compose the per-operation callable from ``call`` (the raw method).

    Adds, only where needed: deep copies of arguments and result (``by_value``, for
    remotable interfaces), routing of ``scart.callback()`` to ``callback`` (a contextvar
    set and reset around the call, also inside one-way workers), and queueing on the
    one-way pool (``op.oneway``: returns None at once). With none of these it returns
    ``call`` itself, so a plain local call costs what a direct method call costs.
    """
    inner = call
    if by_value and not op.oneway:  # a one-way call is copied once, at submit (below)
        def inner(*args: object, _c: Invoker = call, **kwargs: object) -> object:
            return by_value_copy(_c(*by_value_copy(args), **by_value_copy(kwargs)))
    if callback is not None:
        plain = inner
        var_set, var_reset = CURRENT_CALLBACK.set, CURRENT_CALLBACK.reset

        def inner(*args: object, **kwargs: object) -> object:
            token = var_set(callback)
            try:
                return plain(*args, **kwargs)
            finally:
                var_reset(token)
    if op.oneway:
        work = inner
        if by_value:
            def oneway(*args: object, **kwargs: object) -> None:  # copy now: the caller may mutate after return
                submit(work, *by_value_copy(args), **by_value_copy(kwargs))
        else:
            def oneway(*args: object, **kwargs: object) -> None:
                submit(work, *args, **kwargs)
        return oneway
    return inner


T = TypeVar("T")
_ATOMIC = frozenset({int, float, str, bool, bytes, complex, type(None)})


def by_value_copy(value: T) -> T:
    """A deep copy of ``value`` for pass-by-value, skipping the copy when it holds only
    immutable atoms (ints, strings...), which cannot be mutated by the callee anyway."""
    kind = type(value)
    if kind in _ATOMIC:
        return value
    if kind is tuple and all(type(v) in _ATOMIC for v in value):  # type: ignore[attr-defined]  # kind is tuple
        return value
    if kind is dict and not value:
        return value
    return copy.deepcopy(value)
