"""The static checks of :mod:`scart.assembly` that need no wiring state (a mixin of its
assembler): bindings and composite extensions, implementation types, multiplicity and
interface compatibility of a wired reference."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from scart import errors as E
from scart.api import ComponentType, InterfaceInfo, interface_info
from scart.bindings.base import BINDING_KINDS
from scart.errors import Problem
from scart.extensions import COMPOSITE_EXTENSIONS
from scart.model import Binding, Component, Location

if TYPE_CHECKING:
    from scart.assembly import Assembly, Endpoint, Target

#: For each declared multiplicity, the ones a component may narrow it to (ASM50009).
NARROWINGS: dict[str, tuple[str, ...]] = {
    "0..n": ("0..n", "1..n", "0..1", "1..1"),
    "1..n": ("1..n", "1..1"),
    "0..1": ("0..1", "1..1"),
    "1..1": ("1..1",),
}


class Checks:
    """Mixin: needs ``self.problems`` (a list of ``Problem``), ``self.problem(code, message, loc)``
    and ``self.contribution``."""

    problems: list[Problem]
    contribution: Any

    def problem(self, code: str, message: str, loc: Location) -> None:
        raise NotImplementedError

    def check_bindings(self, result: Assembly) -> None:
        """Every binding's kind is registered for its side; the kind's own ``check`` runs."""
        from scart.assembly import Bound  # (a cycle at import time otherwise)

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

    def check_binding(self, model: Binding, side: str, iface: InterfaceInfo | None) -> None:
        kind = BINDING_KINDS.get(model.kind)
        impl = getattr(kind, side, None) if kind is not None else None
        if impl is None:
            usable = sorted(k for k, v in BINDING_KINDS.items() if getattr(v, side) is not None)
            self.problem(E.SCART_UNKNOWN_KIND, f"binding <{model.kind}> cannot be used on a {side}; "
                         f"known: {', '.join(usable)}", model.loc)
            return
        self.problems.extend(impl.check(model, iface, self.contribution))

    def check_extensions(self, result: Assembly) -> None:
        """Run each registered composite extension's static check on its elements."""
        by_kind: dict[str, list[tuple[str, Element]]] = {}
        for prefix, el in result.extensions:
            by_kind.setdefault(el.kind, []).append((prefix, el))
        for kind, elements in by_kind.items():
            ext = COMPOSITE_EXTENSIONS.get(kind)
            if ext is None:
                self.problem(E.SCART_UNKNOWN_KIND, f"no handler for <scart:{kind}>", elements[0][1].loc)
                continue
            self.problems.extend(ext.check(elements, result))


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
