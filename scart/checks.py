"""The static checks of :mod:`scart.assembly` that need no wiring state (a mixin of its
assembler): bindings and composite extensions, implementation types, multiplicity and
interface compatibility of a wired reference."""

from __future__ import annotations

from types import MappingProxyType

from scart import errors as E
from scart.api import ComponentType, InterfaceInfo, interface_info
from scart.errors import Problem
from scart.extensions import ExtensionError, ExtensionRegistry
from scart.assembled import Assembly
from scart.graph import Bound, Endpoint, Node, Target
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

    def check_implementations(self, result: Assembly) -> None:
        """Run each implementation kind's static check on its assembled components."""
        by_kind: dict[str, list[Node]] = {}
        for node in result.nodes.values():
            by_kind.setdefault(node.kind, []).append(node)
        for kind, nodes in by_kind.items():
            try:
                provider = self.registry.implementation(kind)
            except ExtensionError:
                continue  # reported where the component was built
            if provider is not None:
                self.problems.extend(provider.check(nodes, result, self.context))

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
                if checked is None:
                    continue
                for op in checked.operations.values():
                    if op.oneway and op.returns_value:
                        self.problem(E.SCART_ONEWAY_RETURNS, f"one-way operation {checked.name}.{op.name} "
                                     "declares a return value", loc)


    def check_multiplicity(self, comp: Component, ref: str, mult: str, targets: list[Endpoint],
                           loc: Location, promoted: bool) -> None:
        n = len(targets)
        if n == 0 and (promoted or comp.misread):  # misread: the missing target is likely what was misread
            return
        where = comp.loc if n == 0 else loc
        if mult == "1..1" and n != 1:
            self.problem(E.ASM_MULTIPLICITY_1_1, f"component {comp.name!r}: reference {ref!r} (1..1) has {n} targets", where)
        elif mult == "0..1" and n > 1:
            self.problem(E.ASM_MULTIPLICITY_0_1, f"component {comp.name!r}: reference {ref!r} (0..1) has {n} targets", where)
        elif mult == "1..n" and n == 0:
            self.problem(E.ASM_MULTIPLICITY_1_N, f"component {comp.name!r}: reference {ref!r} (1..n) has no target", where)

    def check_compatible(self, source: InterfaceInfo, target: InterfaceInfo, ref: str, t: Target, loc: Location) -> bool:
        """A wire (or @target) from reference ``ref`` to service ``t``: the target's interface
        is a compatible superset of the reference's (ASM60043); True when it is."""
        return self.check_subset(source, target, E.ASM_INTERFACE_MISMATCH,
                          f"reference {ref!r} ({source.name}) is wired to {t.node}/{t.service} ({target.name})", loc)

    def check_subset(self, sub: InterfaceInfo, sup: InterfaceInfo, code: str, where: str, loc: Location) -> bool:
        """Report (``code``, at ``loc``) each way ``sup`` is not a compatible superset of
        ``sub``; True when it is. See :func:`mismatches`."""
        reasons = mismatches(sub, sup)
        for reason in reasons:
            self.problem(code, f"{where}: {reason}", loc)
        return not reasons


def mismatches(sub: InterfaceInfo, sup: InterfaceInfo) -> list[str]:
    """How ``sup`` fails to be a compatible superset of ``sub`` (SCA compatibility by
    operations): an operation of ``sub`` it lacks, an operation one-way on one side only,
    or callbacks that do not match — both or neither declare one, and ``sub``'s callback
    interface offers every operation ``sup``'s may call back (the callback direction is
    reversed). Empty when compatible."""
    reasons = []
    missing = [op for op in sub.operations if op not in sup.operations]
    if missing:
        reasons.append(f"{sup.name} lacks operation(s) {', '.join(missing)}")
    flipped = [f"{n} ({'one-way' if op.oneway else 'request-response'} in {sub.name}, "
               f"{'one-way' if sup.operations[n].oneway else 'request-response'} in {sup.name})"
               for n, op in sub.operations.items() if n in sup.operations and op.oneway != sup.operations[n].oneway]
    if flipped:
        reasons.append(f"one-way differs for {', '.join(flipped)}")
    if sub.callback is not None and sup.callback is None:
        reasons.append(f"{sub.name} declares callback interface {sub.callback.name}, and {sup.name} has no callback interface")
    elif sup.callback is not None and sub.callback is None:
        reasons.append(f"{sup.name} declares callback interface {sup.callback.name}, and {sub.name} has no callback interface")
    elif sub.callback is not None and sup.callback is not None:
        extra = [n for n in sup.callback.operations if n not in sub.callback.operations]
        if extra:
            reasons.append(f"callback interface {sup.callback.name} has operation(s) {', '.join(extra)} that "
                           f"{sub.callback.name} lacks")
    return reasons
