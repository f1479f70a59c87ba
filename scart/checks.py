"""The static checks of :mod:`scart.assembly` that need no wiring state (a mixin of its
assembler): bindings and composite extensions, implementation types, multiplicity and
interface compatibility of a wired reference."""

from __future__ import annotations

from types import MappingProxyType

from scart import errors as E
from scart.api import ComponentType, InterfaceInfo, interface_info
from scart.errors import Problem
from scart.extensions import ExtensionError, ExtensionRegistry
from scart.graph import Assembly, Bound, Endpoint, Target
from scart.model import Binding, Component, Element, Location
from scart.spi import BindingProvider, CheckContext, Side

#: For each declared multiplicity, the ones a component may narrow it to (ASM50009).
NARROWINGS: MappingProxyType[str, tuple[str, ...]] = MappingProxyType({
    "0..n": ("0..n", "1..n", "0..1", "1..1"),
    "1..n": ("1..n", "1..1"),
    "0..1": ("0..1", "1..1"),
    "1..1": ("1..1",),
})


class Checks:
    """Mixin: needs ``self.problems`` (a list of ``Problem``), ``self.problem(code, message, loc)``,
    ``self.registry`` (the extension registry) and ``self.context`` (what checks may see)."""

    problems: list[Problem]
    registry: ExtensionRegistry
    context: CheckContext

    def problem(self, code: str, message: str, loc: Location) -> None:
        raise NotImplementedError

    def check_bindings(self, result: Assembly) -> None:
        """Every binding's kind is registered for its side; the kind's own ``check`` runs."""
        for node in result.nodes.values():
            for sname, models in node.service_bindings.items():
                for model in models:
                    self.check_binding(model, "service", node.ctype.services[sname])
            for ref, eps in node.references.items():
                ref_type = node.ctype.references[ref][1]
                for ep in eps:
                    if isinstance(ep, Bound):
                        self.check_binding(ep.binding, "reference", interface_info(ref_type) if ref_type else None)
        for name, models in result.service_bindings.items():
            t = result.services[name]
            for model in models:
                self.check_binding(model, "service", result.nodes[t.node].ctype.services[t.service])

    def check_binding(self, model: Binding, side: Side, iface: InterfaceInfo | None) -> None:
        try:
            provider = self.registry.binding(model.kind)
        except ExtensionError as exc:
            self.problem(E.SCART_UNKNOWN_KIND, str(exc), model.loc)
            return
        if provider is None or side not in provider.sides:
            self.problem(E.SCART_UNKNOWN_KIND, f"binding <{model.kind}> cannot be used on a {side}; "
                         f"known: {', '.join(self._usable(side))}", model.loc)
            return
        self.problems.extend(provider.check(model, iface, side, self.context))

    def _usable(self, side: Side) -> list[str]:
        usable = []
        for name in self.registry.known(BindingProvider):
            try:
                provider = self.registry.binding(name)
            except ExtensionError:
                continue
            if provider is not None and side in provider.sides:
                usable.append(name)
        return usable

    def check_extensions(self, result: Assembly) -> None:
        """Run each registered composite element's static check on its elements."""
        by_kind: dict[str, list[tuple[str, Element]]] = {}
        for prefix, el in result.elements:
            by_kind.setdefault(el.kind, []).append((prefix, el))
        for kind, elements in by_kind.items():
            try:
                provider = self.registry.element(kind)
            except ExtensionError as exc:
                self.problem(E.SCART_UNKNOWN_KIND, str(exc), elements[0][1].loc)
                continue
            if provider is None:
                self.problem(E.SCART_UNKNOWN_KIND, f"no handler for <scart:{kind}>", elements[0][1].loc)
                continue
            self.problems.extend(provider.check(elements, result, self.context))


    def check_type(self, ctype: ComponentType, loc: Location) -> None:
        cls_ops = {n for n in dir(ctype.cls) if not n.startswith("_")}
        for sname, iface in ctype.services.items():
            for op in iface.operations.values():
                if op.name not in cls_ops:
                    self.problem(E.SCART_MISSING_OPERATION, f"{ctype.cls.__name__} lacks operation {op.name!r} "
                                 f"of its declared service {sname!r}", loc)
            for checked in (iface, iface.callback):
                for op in (checked.operations.values() if checked else ()):
                    if op.oneway and op.returns_value:
                        self.problem(E.SCART_ONEWAY_RETURNS, f"one-way operation {checked.name}.{op.name} "
                                     "declares a return value", loc)


    def check_multiplicity(self, comp: Component, ref: str, mult: str, targets: list[Endpoint],
                           loc: Location, promoted: bool) -> None:
        n = len(targets)
        if n == 0 and promoted:
            return
        where = comp.loc if n == 0 else loc
        if mult == "1..1" and n != 1:
            self.problem(E.ASM_MULTIPLICITY_1_1, f"component {comp.name!r}: reference {ref!r} (1..1) has {n} targets", where)
        elif mult == "0..1" and n > 1:
            self.problem(E.ASM_MULTIPLICITY_0_1, f"component {comp.name!r}: reference {ref!r} (0..1) has {n} targets", where)
        elif mult == "1..n" and n == 0:
            self.problem(E.ASM_MULTIPLICITY_1_N, f"component {comp.name!r}: reference {ref!r} (1..n) has no target", where)

    def check_compatible(self, source: InterfaceInfo, target: InterfaceInfo, ref: str, t: Target, loc: Location) -> None:
        where = f"reference {ref!r} ({source.name}) is wired to {t.node}/{t.service} ({target.name})"
        missing = [op for op in source.operations if op not in target.operations]
        if missing:
            self.problem(E.ASM_INTERFACE_MISMATCH, f"{where}, which lacks operation(s) {', '.join(missing)}", loc)
        flipped = [f"{n} ({'one-way' if op.oneway else 'request-response'} here, "
                   f"{'one-way' if target.operations[n].oneway else 'request-response'} there)"
                   for n, op in source.operations.items() if n in target.operations and op.oneway != target.operations[n].oneway]
        if flipped:
            self.problem(E.ASM_INTERFACE_MISMATCH, f"{where}: one-way differs for {', '.join(flipped)}", loc)
        if source.callback is not None:
            if target.callback is None:
                self.problem(E.ASM_INTERFACE_MISMATCH, f"{where}: the reference expects callbacks "
                             f"({source.callback.name}) but the service has no callback interface", loc)
            else:
                extra = [n for n in target.callback.operations if n not in source.callback.operations]
                if extra:
                    self.problem(E.ASM_INTERFACE_MISMATCH, f"{where}: the service's callback interface "
                                 f"{target.callback.name} has operation(s) {', '.join(extra)} that the reference's "
                                 f"callback interface {source.callback.name} lacks", loc)
