"""The services of the assembly: what a target URI names (through promotions and
bindings), the services a composite promotes, and autowiring. A mixin of the assembler,
private to :mod:`scart.assembly`."""

from __future__ import annotations

from scart import errors as E
from scart.api import InterfaceInfo
from scart.assembly._interfaces import Interfaces
from scart.assembly._state import Failed, Scope
from scart.checks import mismatches
from scart.graph import Endpoint, Node, Target
from scart.model import Binding, CompositeService, Location
from scart.scdl import did_you_mean


class Targets(Interfaces):
    """Resolves services: wire targets, promoted services and their bindings, autowire."""

    def resolve_service(self, scope: Scope, uri: str, loc: Location, code: str = E.ASM_NO_SUCH_TARGET,
                        what: str = "") -> Target | None:
        """The leaf service ``uri`` ("Component[/Service]") names in ``scope`` (through
        promotions), or None after reporting why (``what`` says whose URI it is)."""
        comp_name, _, service = uri.partition("/")
        service, _, binding = service.partition("/")
        child = scope.children.get(comp_name)
        if child is None:
            known = ", ".join(list(scope.children)[:20]) or "none"
            self.problem(code, f"{what}{uri!r}: no component {comp_name!r}{did_you_mean(comp_name, scope.children)}; "
                         f"known: {known}", loc)
            return None
        if isinstance(child, Failed):
            return None  # its own problem is reported already
        offered = child.ctype.services if child.ctype is not None else {}
        if not service:
            if len(offered) != 1:
                self.problem(E.ASM_AMBIGUOUS_TARGET, f"{what}{uri!r}: component {comp_name!r} offers "
                             f"{len(offered)} services ({', '.join(offered)}); name one as 'Component/Service'", loc)
                return None
            service = next(iter(offered))
        if service not in offered:
            self.problem(code, f"{what}{uri!r}: component {comp_name!r} has no service {service!r}"
                         f"{did_you_mean(service, offered)}; it offers: {', '.join(offered) or 'none'}", loc)
            return None
        if isinstance(child, Node):
            if binding and not self.has_binding(child, service, binding):
                xml = next((s for s in child.model.services if s.name == service), None)
                names = sorted({b.name or service for b in xml.bindings} if xml and xml.bindings else {service})
                self.problem(E.ASM_NO_SUCH_BINDING, f"{what}{uri!r}: service {comp_name}/{service} has no binding "
                             f"named {binding!r}{did_you_mean(binding, names)}; its bindings: {', '.join(names)}", loc)
                return None
            return Target(child.path, service)
        promoted = next(cs for cs in child.composite.services if cs.name == service)
        if binding:  # the bindings it has: the component's <service>'s, else the composite service's
            xml = next((s for s in child.component.services if s.name == service), None) if child.component else None
            names = sorted({b.name or service for b in (xml.bindings if xml and xml.bindings else promoted.bindings)}
                           or {service})
            if binding not in names:
                self.problem(E.ASM_NO_SUCH_BINDING, f"{what}{uri!r}: service {comp_name}/{service} has no binding "
                             f"named {binding!r}{did_you_mean(binding, names)}; its bindings: {', '.join(names)}", loc)
                return None
        return self.resolve_service(child, promoted.promote, promoted.loc, E.ASM_PROMOTED_SERVICE)

    @staticmethod
    def has_binding(node: Node, service: str, name: str) -> bool:
        """Does the component's service have a binding named ``name``? An unnamed binding
        is named after its service, and a service without bindings has its binding.sca."""
        xml = next((s for s in node.model.services if s.name == service), None)
        if xml is None or not xml.bindings:
            return name == service
        return any((b.name or service) == name for b in xml.bindings)

    def promoted_service(self, cs: CompositeService, target: Target) -> InterfaceInfo:
        """The interface of the service ``cs`` promotes; a declared one must be a compatible
        subset of it, callbacks included (ASM60005)."""
        offered = self.offered(target)
        if cs.interface is not None:
            declared = self.declared_interface(cs.interface)
            if declared is not None:
                self.check_subset(declared, offered, E.ASM_COMPOSITE_SERVICE_INTERFACE,
                                  f"composite service {cs.name!r}: its declared interface {declared.name} and the "
                                  f"promoted {target.node}/{target.service} ({offered.name})", cs.interface.loc)
        return offered

    def bind_promoted(self, target: Target, alias: str, bindings: list[Binding]) -> None:
        """Record ``bindings`` of a service promoted out of a nested composite on its leaf
        target (as a root-level promoted service's bindings are), named also ``alias``."""
        if not bindings:
            return
        node = self.nodes[target.node]
        node.service_bindings.setdefault(target.service, []).extend(bindings)
        aliases = node.service_aliases.setdefault(target.service, [])
        if alias not in aliases:
            aliases.append(alias)

    def autowire(self, scope: Scope, comp_name: str, iface: InterfaceInfo) -> list[Endpoint]:
        found: list[Endpoint] = []
        for name, child in scope.children.items():
            if name == comp_name or child.ctype is None:
                continue
            for sname in child.ctype.services:
                target = self.resolve_service(scope, f"{name}/{sname}", scope.composite.loc)
                if target is not None and not mismatches(iface, self.offered(target)):  # compatible (ASM60022)
                    found.append(target)
        return found
