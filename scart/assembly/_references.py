"""The references and wires of the assembly (phase 2): each reference resolved to its
endpoints (``@target``, ``<wire>`` with ``replace``, bindings, autowire, then promotion
from the enclosing component), with its multiplicity and interface compatibility checked.
A mixin of the assembler, private to :mod:`scart.assembly`."""

from __future__ import annotations

from scart import errors as E
from scart.api import interface_info
from scart.assembly._state import Failed, Scope
from scart.assembly._targets import Targets
from scart.checks import NARROWINGS as _NARROWINGS
from scart.component_types import composite_reference_defaults
from scart.extensions import ExtensionError
from scart.graph import Bound, Endpoint, Node, Target
from scart.model import Binding, Component, ComponentReference, CompositeReference, Location
from scart.scdl import SCA_NAMESPACES as _SCA_NAMESPACES
from scart.scdl import did_you_mean


class References(Targets):
    """Wires every reference of a scope, and of the scopes nested in it."""

    def check_wire_sources(self, scope: Scope) -> None:
        """Each ``<wire>``'s @source names a reference of a component of this composite
        (``Component/reference``, or ``Component`` when it has one reference)."""
        for w in scope.composite.wires:
            comp_name, _, ref = w.source.partition("/")
            ref = ref.partition("/")[0]
            child = scope.children.get(comp_name)
            if isinstance(child, Failed):
                continue
            if child is None:
                self.problem(E.SCART_WIRE_SOURCE, f"wire @source {w.source!r}: no component {comp_name!r}"
                             f"{did_you_mean(comp_name, scope.children)}; known: "
                             f"{', '.join(list(scope.children)[:20]) or 'none'}", w.loc)
                continue
            refs = list(child.ctype.references) if child.ctype is not None else []
            if (ref and ref not in refs) or (not ref and len(refs) != 1):
                said = f"has no reference {ref!r}{did_you_mean(ref, refs)}" if ref else f"has {len(refs)} references"
                self.problem(E.SCART_WIRE_SOURCE, f"wire @source {w.source!r}: component {comp_name!r} {said}; "
                             f"its references: {', '.join(refs) or 'none'}", w.loc)

    def wire(self, scope: Scope, inherited: dict[str, list[Endpoint]]) -> None:
        self.check_wire_sources(scope)
        promoted: dict[str, list[Endpoint]] = {}
        for cr in scope.composite.references:
            for uri in cr.promote:
                comp_name, _, ref = uri.partition("/")
                child = scope.children.get(comp_name)
                if isinstance(child, Failed):
                    continue
                if child is None or child.ctype is None or ref not in child.ctype.references:
                    known = [f"{n}/{r}" for n, c in scope.children.items() if c.ctype is not None for r in c.ctype.references]
                    self.problem(E.ASM_PROMOTED_REFERENCE, f"composite reference {cr.name!r}: @promote {uri!r} names "
                                 f"no component reference; known: {', '.join(known[:20]) or 'none'}", cr.loc)
                    continue
                self.check_promoted_reference(scope, cr, comp_name, child, ref)
                outer = inherited.get(cr.name) or [Bound(b) for b in cr.bindings]
                if not outer and cr.targets and scope.component is None:
                    outer = [t for t in (self.resolve_service(scope, u, cr.loc, what=f"composite reference {cr.name!r}: "
                                                              "target ") for u in cr.targets) if t]
                promoted[uri] = outer
        for name, child in scope.children.items():
            if child.ctype is None:
                continue
            endpoints = {r: self.reference_endpoints(scope, name, child, r, promoted.get(f"{name}/{r}", []))
                         for r in child.ctype.references}
            if isinstance(child, Node):
                child.references = endpoints
            else:
                self.wire(child, endpoints)

    def check_promoted_reference(self, scope: Scope, cr: CompositeReference, comp_name: str, child: Node | Scope,
                                 ref: str) -> None:
        """A composite reference promoting ``comp_name/ref``: a 0..1/1..1 ``nonOverridable``
        reference is not promoted (ASM50042); the composite reference's
        multiplicity narrows, never widens, the promoted one's — or relaxes "at least one"
        when the component reference has its own targets (ASM60011); its interface is a
        compatible superset of the promoted one's (ASM60012), and references promoted
        together have one interface (ASM60008)."""
        comp = child.model if isinstance(child, Node) else child.component
        assert comp is not None and child.ctype is not None
        spec, ref_type = child.ctype.references[ref]
        xml = next((r for r in comp.references if r.name == ref), None)
        mult = (xml.multiplicity if xml is not None and xml.multiplicity else None) or spec.multiplicity
        wired = bool(xml is not None and (xml.targets or xml.bindings)) or any(
            w.source.partition("/")[0] == comp_name and w.source.partition("/")[2] in (ref, "")
            for w in scope.composite.wires)
        where = f"composite reference {cr.name!r} promotes {comp_name}/{ref}"
        if xml is not None and xml.non_overridable and not mult.endswith("n"):
            self.problem(E.ASM_NON_OVERRIDABLE, f"{where}, which is nonOverridable and {mult}: it cannot be "
                         "promoted (its target cannot be replaced)", cr.loc)
        if cr.multiplicity:
            allowed = list(_NARROWINGS.get(mult, ()))
            if wired and mult.startswith("1"):  # it has targets already: "at least one" may be relaxed
                allowed += [m for m in _NARROWINGS.get("0" + mult[1:], ()) if m not in allowed]
            if cr.multiplicity not in allowed:
                self.problem(E.ASM_COMPOSITE_MULTIPLICITY, f"{where} ({mult}): multiplicity {cr.multiplicity!r} "
                             f"would widen it (allowed: {', '.join(allowed)})", cr.loc)
        promoted = self.reference_interface(xml.interface if xml else None, ref_type, cr.loc)
        if promoted is None and isinstance(child, Scope):
            promoted = self.nested_reference_interface(child, ref, 0)
        if promoted is None:
            return
        if cr.interface is not None:
            declared = self.declared_interface(cr.interface)
            if declared is not None:
                self.check_subset(promoted, declared, E.ASM_COMPOSITE_REFERENCE_INTERFACE,
                                  f"{where} ({promoted.name}): its declared interface {declared.name}", cr.interface.loc)
        first = self._promoted_interfaces.setdefault(id(cr), (f"{comp_name}/{ref}", promoted))
        if first[1] is not promoted and cr.interface is None:  # without an interface of its own: one interface
            where = (f"composite reference {cr.name!r} promotes {first[0]} ({first[1].name}) and "
                     f"{comp_name}/{ref} ({promoted.name}) together, and declares no interface of its own")
            if self.check_subset(first[1], promoted, E.ASM_PROMOTED_INTERFACES, where, cr.loc):
                self.check_subset(promoted, first[1], E.ASM_PROMOTED_INTERFACES, where, cr.loc)

    def reference_endpoints(self, scope: Scope, comp_name: str, child: Node | Scope, ref: str,
                            from_outside: list[Endpoint]) -> list[Endpoint]:
        comp = child.model if isinstance(child, Node) else child.component
        assert comp is not None and child.ctype is not None
        spec, ref_type = child.ctype.references[ref]
        xml = next((r for r in comp.references if r.name == ref), None)
        loc = xml.loc if xml is not None else comp.loc
        uris = [(u, loc) for u in (xml.targets if xml else [])]
        bindings = self.reference_bindings(comp, ref, xml, uris)
        side = self.side_files.get(child.path) if isinstance(child, Node) else None
        if side is not None and not uris and not bindings and ref in side.targets:  # the componentType's default
            uris, bindings = list(side.targets[ref]), list(side.bindings.get(ref, []))
        elif isinstance(child, Scope) and not uris and not bindings:  # the composite reference's own bindings
            uris, bindings = composite_reference_defaults(child.composite, ref)
        replaced = False
        for w in scope.composite.wires:
            src_comp, _, src_ref = w.source.partition("/")
            if src_comp == comp_name and (src_ref == ref or (not src_ref and len(child.ctype.references) == 1)):
                if w.replace and not replaced:  # the @target URIs go once; every wire is kept
                    uris = [(u, l) for u, l in uris if l is not loc]
                    replaced = True
                uris.append((w.target, w.loc))
        what = f"component {comp.name!r} reference {ref!r}: target "
        targets: list[Endpoint] = [t for t in (self.resolve_service(scope, u, l, what=what) for u, l in uris) if t]
        unresolved = len(targets) < len(uris)
        iface = self.reference_interface(xml.interface if xml else None, ref_type, loc)
        if iface is not None and xml is not None and xml.interface is not None:
            # the declared interface may add to the implementation's, never take — nor declare a
            # callback it lacks (when it does, checking it against the targets would only repeat the problem)
            implemented = (interface_info(ref_type) if ref_type is not None else
                           self.nested_reference_interface(child, ref, 0) if isinstance(child, Scope) else None)
            if implemented is not None and implemented.callback is None and iface.callback is not None:
                self.problem(E.ASM_REFERENCE_INTERFACE, f"component {comp.name!r} reference {ref!r} declares callback "
                             f"interface {iface.callback.name}, but its componentType's reference ({implemented.name}) "
                             "has no callback interface", xml.interface.loc)
                iface = None
            elif implemented is not None and not self.check_subset(
                    implemented, iface, E.ASM_REFERENCE_INTERFACE,
                    f"reference {ref!r} of {comp.name!r}: the implementation's {implemented.name} "
                    f"and the declared interface {iface.name}", xml.interface.loc):
                iface = None
            if iface is not None and isinstance(child, Node):
                child.ref_interfaces[ref] = iface
        mult = spec.multiplicity
        if xml is not None and xml.multiplicity:
            if xml.multiplicity not in _NARROWINGS.get(spec.multiplicity, ()):
                self.problem(E.ASM_MULTIPLICITY_NARROWING, f"component {comp.name!r}: reference {ref!r} is declared "
                             f"{spec.multiplicity} by its implementation; multiplicity {xml.multiplicity!r} does not "
                             f"narrow it (allowed: {', '.join(_NARROWINGS.get(spec.multiplicity, ()))})", loc)
            else:
                mult = xml.multiplicity
        if not targets and bindings:
            targets = [Bound(b) for b in bindings]
        if from_outside:  # promoted, and the outside gives targets: they replace the component's own
            if xml is not None and xml.non_overridable:  # ... unless it is nonOverridable: then they add
                targets = targets + list(from_outside) if mult.endswith("n") else targets
            else:
                targets = list(from_outside)
        autowire = next((a for a in ((xml.autowire if xml else None), comp.autowire) if a is not None),
                        scope.composite.autowire)
        if not targets and not uris and autowire and iface is not None:
            targets = self.autowire(scope, comp_name, iface)
            if not mult.endswith("n"):
                targets = targets[:1]  # SCA: for a 0..1/1..1 reference the runtime picks one; the first
        if not unresolved:  # an unresolved target is reported already; its count would mislead
            self.check_multiplicity(comp, ref, mult, targets, loc,
                                    promoted=bool(from_outside) or self._is_promoted(scope, comp_name, ref))
        for t in targets:
            if not isinstance(t, Target):
                continue
            offered = self.offered(t)
            if iface is not None and not self.check_compatible(iface, offered, ref, t, loc):
                continue  # the caller's callback methods are not checked against a mismatched interface
            if offered.callback is not None and isinstance(child, Node):
                lacking = [op for op in offered.callback.operations if not callable(getattr(child.ctype.cls, op, None))]
                if lacking:
                    self.problem(E.SCART_CALLBACK_MISSING, f"component {comp.name!r} calls {t.node}/{t.service}, whose "
                                 f"callback interface {offered.callback.name} needs method(s) {', '.join(lacking)} "
                                 "on the caller", loc)
        return targets

    def reference_bindings(self, comp: Component, ref: str, xml: ComponentReference | None,
                           uris: list[tuple[str, Location]]) -> list[Binding]:
        """The bindings of a component reference that reach an endpoint of their own. A
        ``binding.sca`` with ``@uri`` is a target like ``@target`` (added to ``uris``); one
        without is the default binding (nothing to add). Beside a ``@target``, a binding
        that names its own endpoint is a conflict (ASM50026)."""
        if xml is None:
            return []
        out = []
        for b in xml.bindings:
            if b.kind == "binding.sca" and b.namespace in _SCA_NAMESPACES:
                if "uri" in b.attributes:
                    if xml.targets:
                        self.problem(E.ASM_TARGET_AND_BINDING, f"component {comp.name!r} reference {ref!r} has "
                                     f"@target {' '.join(xml.targets)!r} and a <binding.sca> with @uri "
                                     f"{b.attributes['uri']!r}: give one or the other", b.loc)
                    uris.append((b.attributes["uri"], b.loc))
                continue
            out.append(b)
            names = True
            try:
                provider = self.registry.binding(b.kind)
                names = provider.names_endpoint(b) if provider is not None else True
            except ExtensionError:
                pass  # reported by the binding check
            if xml.targets and names:
                self.problem(E.ASM_TARGET_AND_BINDING, f"component {comp.name!r} reference {ref!r} has @target "
                             f"{' '.join(xml.targets)!r} and a <{b.kind}> that names its own endpoint: "
                             "give one or the other", b.loc)
        return out

    def _is_promoted(self, scope: Scope, comp_name: str, ref: str) -> bool:
        return scope.component is not None and any(f"{comp_name}/{ref}" in cr.promote for cr in scope.composite.references)
