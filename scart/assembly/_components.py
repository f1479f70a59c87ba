"""The components of the assembly (phase 1): each composite walked top-down, each
implementation introspected (through its kind's provider, with its componentType side
file), nested composites built as scopes, and each component's services, references and
properties checked against its type. A mixin of the assembler, private to
:mod:`scart.assembly`."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from scart import errors as E
from scart.api import ComponentType, InterfaceInfo, PropSpec, RefSpec
from scart.assembly._properties import Properties
from scart.assembly._references import References
from scart.assembly._state import Failed, Scope
from scart.component_types import SideFile
from scart.extensions import ExtensionError
from scart.graph import Node, Target
from scart.model import Component, Composite, Location
from scart.properties import Refused, TypeRef, python_family
from scart.scdl import did_you_mean
from scart.spi import ImplementationProblem, ImplementationProvider


class Components(References, Properties):
    """Builds the scopes and leaf nodes of a composite and the composites nested in it."""

    def build(self, composite: Composite, prefix: str, props: dict[str, list[str] | None],
              types: dict[str, TypeRef | None]) -> Scope:
        scope = Scope(composite, prefix, props, types)
        self.extensions.extend((prefix, el) for el in composite.extensions)
        for comp in composite.components:
            if comp.name in scope.children:
                self.problem(E.ASM_DUPLICATE_COMPONENT, f"duplicate component name {comp.name!r}", comp.loc)
                continue
            scope.children[comp.name] = self.build_component(comp, scope)
        return scope

    def build_component(self, comp: Component, scope: Scope) -> Node | Scope | Failed:
        impl = comp.implementation
        if impl is None or impl.invalid:
            return Failed(comp)
        path = scope.prefix + comp.name
        if impl.kind == "implementation.composite":
            if impl.composite is None:
                return Failed(comp)
            return self.build_nested(comp, impl.composite, scope, path)
        try:
            kind = self.registry.implementation(impl.kind)
        except ExtensionError as exc:
            self.problem(E.SCART_UNKNOWN_KIND, str(exc), impl.loc)
            return Failed(comp)
        if kind is None:
            known = [*self.registry.known(ImplementationProvider), "implementation.composite"]
            self.problem(E.SCART_UNKNOWN_KIND, f"unknown implementation kind <{impl.kind}>"
                         f"{did_you_mean(impl.kind, known)}; known: {', '.join(sorted(known))}", impl.loc)
            return Failed(comp)
        try:
            ctype = kind.component_type(impl, self.context)
        except ImplementationProblem as exc:
            self.problem(exc.code, str(exc), impl.loc)
            if exc.partial is None:  # else enough of a type to check the rest of the component
                return Failed(comp)
            ctype = exc.partial
        self.check_type(ctype, impl.loc)
        side = self.side_file(ctype)
        if side is not None:
            ctype = side.merge(ctype)
            self.side_files[path] = side
        ctype = self.check_component_names(comp, ctype, path=path)
        node = Node(path, comp, impl.kind, ctype)
        families = {n: python_family(t) for n, (_, t) in ctype.properties.items()}
        if side is not None:
            families.update({n: self.reader.family(t) for n, t in side.types.items()})
        raw = self.component_raw_props(comp, ctype, scope, path, families, dict(side.types) if side else None)
        for name, (spec, py_type) in ctype.properties.items():
            given = raw.get(name)
            if given is None and side is not None:
                given = side.defaults.get(name)
            override = f"{path}.{name}" if f"{path}.{name}" in self.overrides else None
            node.properties[name] = self.property_value(comp, name, spec, py_type, given, override=override)
            node.property_locations[name] = (Location(path="<command line>", line=0) if override else
                                             next((p.loc for p in comp.properties if p.name == name), comp.loc))
        node.service_bindings = {s.name: s.bindings for s in comp.services if s.bindings and s.name in ctype.services}
        self.nodes[path] = node
        return node

    def side_file(self, ctype: ComponentType) -> SideFile | None:
        """The componentType side file of an implementation class — ``Class.componentType``
        next to its module — read and checked against the class; None without one."""
        module = sys.modules.get(getattr(ctype.cls, "__module__", ""), None)
        origin = getattr(module, "__file__", None)
        if not origin or ctype.cls is object:
            return None
        path = Path(origin).with_name(f"{ctype.cls.__name__}.componentType")
        model = self.contribution.component_type(path)
        return SideFile(model, ctype, self) if model is not None else None

    def build_nested(self, comp: Component, inner: Composite, scope: Scope, path: str) -> Scope:
        declared = {p.name: p for p in inner.properties}
        fake = ComponentType(object, {}, {}, {n: (PropSpec(None, p.must_supply), str) for n, p in declared.items()},
                             (), (), (), (), "composite", True)
        self.check_component_names(comp, fake, check_services=False)
        types = {n: self.reader.declared(p) for n, p in declared.items()}
        families = {n: self.reader.family(t) for n, t in types.items()}
        raw = self.component_raw_props(comp, fake, scope, path, families, types)
        props: dict[str, list[str] | None] = {}
        for name, decl in declared.items():
            given = raw.get(name)
            if given is not None and not isinstance(given, Refused):
                given = self.check_against(comp, decl, given, from_cli=f"{path}.{name}" in self.overrides)
            value = given if given is not None else self.declaration_values(decl)
            if value is None and decl.must_supply:
                self.problem(E.ASM_MUST_SUPPLY, f"component {comp.name!r}: required property {name!r} not supplied", comp.loc)
            props[name] = value
        child = self.build(inner, path + "/", props, {n: self.reader.declared(p) for n, p in declared.items()})
        child.component = comp
        services: dict[str, InterfaceInfo] = {}
        targets: dict[str, Target] = {}
        for cs in inner.services:
            target = self.resolve_service(child, cs.promote, cs.loc, E.ASM_PROMOTED_SERVICE,
                                          what=f"composite service {cs.name!r}: @promote ")
            if target is not None:
                services[cs.name] = self.promoted_service(cs, target)
                targets[cs.name] = target
                self.bind_promoted(target, f"{path}/{cs.name}", cs.bindings)
        for s in comp.services:  # the outer component's bindings on a promoted service
            if s.name in targets:
                self.bind_promoted(targets[s.name], f"{path}/{s.name}", s.bindings)
        refs: dict[str, tuple[RefSpec, type | None]] = {
            cr.name: (RefSpec(_required(cr.multiplicity), _multiple(cr.multiplicity)), None) for cr in inner.references}
        child.ctype = ComponentType(object, services, refs, fake.properties, (), (), (), (), "composite", True)
        self.check_component_names(comp, child.ctype, check_properties=False)
        return child

    def check_component_names(self, comp: Component, ctype: ComponentType, *, check_services: bool = True,
                              check_properties: bool = True, path: str | None = None) -> ComponentType:
        """Check the component's services, references and properties against ``ctype``; returns
        ``ctype`` with services made remotable where the composite's interface says so. A
        service's declared interface is, for the wires to it, the service's interface
        (recorded for the leaf component at ``path``)."""
        services = dict(ctype.services)
        if check_services:
            for s in comp.services:
                if s.name not in ctype.services:
                    self.problem(E.ASM_NO_SUCH_SERVICE, f"component {comp.name!r} has no service {s.name!r}; "
                                 f"it offers: {', '.join(ctype.services) or 'none'}", s.loc)
                elif s.interface is not None:
                    declared = self.reference_interface(s.interface, None, s.loc)
                    if declared is None:
                        continue
                    offered = ctype.services[s.name]
                    extra = [op for op in declared.operations if op not in offered.operations]
                    if extra:
                        self.problem(E.ASM_SERVICE_INTERFACE, f"service {s.name!r} of {comp.name!r}: declared interface "
                                     f"{declared.name} has operation(s) {', '.join(extra)} the implementation "
                                     "does not offer", s.interface.loc)
                    elif self.check_subset(declared, offered, E.ASM_SERVICE_INTERFACE,  # one-way flags, callbacks
                                           f"service {s.name!r} of {comp.name!r}: declared interface {declared.name} "
                                           f"and the implementation's {offered.name}", s.interface.loc) and path:
                        self.declared_services[(path, s.name)] = declared
                    if declared.remotable and not services[s.name].remotable:
                        services[s.name] = dataclasses.replace(services[s.name], remotable=True)
            for r in comp.references:
                if r.name not in ctype.references:
                    self.problem(E.ASM_NO_SUCH_REFERENCE, f"component {comp.name!r} has no reference {r.name!r}; "
                                 f"it declares: {', '.join(ctype.references) or 'none'}", r.loc)
        if check_properties:
            seen: set[str] = set()
            for p in comp.properties:
                if p.name in seen:
                    self.problem(E.ASM_DUPLICATE_PROPERTY, f"duplicate property {p.name!r}", p.loc)
                seen.add(p.name)
                if p.name not in ctype.properties:
                    self.problem(E.ASM_NO_SUCH_PROPERTY, f"component {comp.name!r} has no property {p.name!r}; "
                                 f"it declares: {', '.join(ctype.properties) or 'none'}", p.loc)
        return ctype if services == ctype.services else dataclasses.replace(ctype, services=services)


def _required(mult: str | None) -> bool:
    return (mult or "1..1").startswith("1")


def _multiple(mult: str | None) -> bool:
    return (mult or "1..1").endswith("n")
