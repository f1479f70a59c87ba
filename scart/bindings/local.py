"""The local binding: in-process calls, the default when a wire names no binding.

Registered as ``binding.sca`` (the SCA default binding). The reference side asks the
target :class:`~scart.bindings.base.ServiceEndpoint` for one callable per operation;
for a composite-scoped target with no callback, no one-way and no remotable interface,
that callable is the target instance's bound method itself (no overhead at all).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from scart.api import InterfaceInfo, Operation
from scart.bindings.base import BindingHost, ReferenceBinding, ServiceBinding, ServiceEndpoint, register_binding
from scart.model import Binding


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
        self, model: Binding | None, interface: InterfaceInfo, host: BindingHost,
        target: ServiceEndpoint | None = None,
    ) -> None:
        super().__init__(model, interface, host)
        if target is None:
            uri = (model.attributes.get("uri") if model is not None else None) or ""
            target = host.endpoint(uri)
        self.target = target

    def invoker(self, operation: Operation, callback: object | None) -> Callable[..., Any]:
        """The target endpoint's callable for ``operation`` (see ``ServiceEndpoint.operation``)."""
        return self.target.operation(operation.name, callback)


register_binding("binding.sca", service=LocalServiceBinding, reference=LocalReferenceBinding)
