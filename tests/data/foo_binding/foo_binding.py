"""``binding.foo``: a reference calls a service of the same runtime (``uri="Component/Service"``)
and writes one line per call to the file named by ``journal``. Written against
``scart.spi`` only, as any third-party binding would be."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from scart.spi import (
    Binding, BindingProvider, CheckContext, Host, InterfaceInfo, Invocation, Operation, Problem, ReferenceBinding,
    Side,
)


class FooReference(ReferenceBinding):
    """Each call goes through ``ServiceEndpoint.invoke`` and is journaled."""

    def invoker(self, operation: Operation, callback: object | None) -> Callable[..., Any]:
        assert self.model is not None
        target = self.host.endpoint(self.model.attributes["uri"])
        journal = Path(self.model.attributes["journal"])
        name = operation.name

        def call(*args: Any, **kwargs: Any) -> Any:
            result = target.invoke(Invocation(name, args, kwargs, callback))
            with journal.open("a", encoding="utf-8") as fh:
                fh.write(f"{name}{args} -> {result!r}\n")
            return result
        return call


class FooBinding(BindingProvider):
    """The provider scart finds through the ``scart.extensions`` entry point."""

    name = "binding.foo"
    sides = frozenset({"reference"})

    def check(self, model: Binding, interface: InterfaceInfo | None, side: Side,
              context: CheckContext) -> list[Problem]:
        return [Problem("FOO-001", f"binding.foo needs a {attr!r} attribute", model.loc.path, model.loc.line)
                for attr in ("uri", "journal") if attr not in model.attributes]

    def reference(self, model: Binding, interface: InterfaceInfo, host: Host) -> ReferenceBinding:
        return FooReference(model, interface, host)
