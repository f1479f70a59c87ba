"""Assembly: the static checks, and the flat, resolved component graph the runtime runs.

:func:`assemble` loads a composite and its contribution, introspects every
implementation, checks every SCA assembly rule (and each extension's own checks), and
returns an :class:`~scart.assembled.Assembly` — or raises one
:class:`~scart.errors.ScdlError` listing every problem. Nothing is started, and
nothing touches the network unless the settings say ``online``.

Two phases. *Build* walks composites top-down (nesting through
``implementation.composite``), introspects implementations and resolves property values
(composite properties flow in through ``source="$name"``). *Wire* resolves every
reference to endpoints (``@target``, ``<wire>`` with ``replace``, autowire, then
promotion from the enclosing component), and checks multiplicity and interface
compatibility. Leaf components are named by their path ("Outer/Inner").
"""

from __future__ import annotations

import dataclasses
import os
import re
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

from scart import errors as E
from scart.api import ComponentType, InterfaceInfo, PropSpec, RefSpec, interface_info
from scart.archive import ArchiveError, is_archive, unpack
from scart.checks import NARROWINGS as _NARROWINGS
from scart.checks import Checks, mismatches
from scart.component_types import SideFile, composite_reference_defaults
from scart.contribution import METADATA, Contribution, deployable_of, import_object
from scart.errors import Problem, ScdlError
from scart.extensions import ExtensionError, ExtensionRegistry
from scart.assembled import Assembly
from scart.graph import DEFAULT, Bound, Endpoint, Node, Target
from scart.model import (
    Binding, Component, ComponentReference, Composite, CompositeReference, CompositeService, Element,
    Interface, Location, PropertyValue,
)
from scart.scdl import SCA_NAMESPACES as _SCA_NAMESPACES
from scart.scdl import did_you_mean
from scart.settings import Settings
from scart.spi import CheckContext, ImplementationProblem, ImplementationProvider
from scart.properties import FileValues, PropertyReader, Refused, TypeRef, compatible, python_family
from scart.values import is_many, parse_value



@dataclass
class Failed:
    """Placeholder of a component whose implementation could not be read (already reported):
    names resolve to it silently, so one broken component causes no cascade of errors."""

    model: Component
    ctype: None = None


@dataclass
class Scope:
    """One composite instance while assembling: its children (leaf Node or nested Scope)."""

    composite: Composite
    prefix: str
    props: dict[str, list[str] | None]
    types: dict[str, TypeRef | None] = field(default_factory=dict)  # of the composite's own properties
    children: dict[str, Node | Scope | Failed] = field(default_factory=dict)
    component: Component | None = None  # the component this composite implements
    ctype: ComponentType | None = None


def assemble(path: str, overrides: dict[str, str] | None = None, *, strict_overrides: bool = True,
             extensions: ExtensionRegistry | None = None, settings: Settings | None = None,
             contributions: Sequence[str | os.PathLike[str]] = ()) -> Assembly:
    """Load, check and resolve the composite at ``path`` (a ``.composite`` file, or a
    contribution folder with one deployable composite); ``overrides`` maps
    "Component.prop" (or "Outer/Inner.prop") to a raw value. Raises ``ScdlError``.

    ``contributions`` are more contribution folders the composite is resolved in (see
    :mod:`scart.contribution`).

    ``extensions`` is the registry of kinds to check against (default: the entry points);
    ``settings`` are given to the extensions' checks (offline unless ``settings.online``).
    With ``strict_overrides=False`` an override naming no component property is no
    problem; the keys not used are then in ``unused_overrides`` of the result (or of the
    ``ScdlError``), for callers checking several files (``scart validate --set``)."""
    registry = extensions if extensions is not None else ExtensionRegistry()
    path, root_archive = _root_file(path, overrides)
    contribution = Contribution(path, is_element=lambda name: _is_element(registry, name),
                                contributions=[str(c) for c in contributions], root_archive=root_archive)
    root = contribution.load_root()
    context = CheckContext(contribution.folder, contribution.root_file, settings or Settings(), contribution.import_object)
    assembler = _Assembler(contribution, registry, context, dict(overrides or {}), strict_overrides)
    if root is None:
        _refuse([contribution.display_problem(p) for p in contribution.problems], set(overrides or {}))
    result = assembler.run(root)
    # a composite used by several components is checked once per use: report each problem once
    # causes first, their knock-ons after: the contributions' metadata, then what was read
    # wrong, then the rest; within each, the root file first, by line
    reading = set(contribution.problems)
    problems = list(dict.fromkeys(contribution.problems + assembler.problems))
    root_path = str(path)
    problems.sort(key=lambda p: (not p.path.endswith(METADATA.name), p not in reading, p.path != root_path,
                                 p.path, p.line))
    problems = [contribution.display_problem(p) for p in problems]
    errors = [p for p in problems if p.severity == "error"]
    warnings = [p for p in problems if p.severity != "error"]
    unused = set(assembler.overrides) - assembler.used_overrides
    if errors:
        _refuse(errors, unused, warnings)
    result.unused_overrides = unused
    result.warnings = warnings
    return result


def _refuse(errors: list[Problem], unused: set[str], warnings: list[Problem] | None = None) -> NoReturn:
    """Raise the ``ScdlError`` of ``errors`` (with the overrides not used, and the warnings)."""
    err = ScdlError(errors)
    err.unused_overrides = unused
    err.warnings = list(warnings or [])
    raise err


def _root_file(path: str, overrides: dict[str, str] | None
               ) -> tuple[str, tuple[Path, tempfile.TemporaryDirectory[str]] | None]:
    """The composite file to load for ``path`` — a ``.composite`` file, or the one
    deployable of a contribution folder or ZIP archive (unpacked: see
    :mod:`scart.archive`) — and the unpacked archive; raises ``ScdlError`` when there is
    none."""
    given = Path(path)
    unpacked = None
    if is_archive(given):
        try:
            unpacked = unpack(given)
        except ArchiveError as exc:
            _refuse([Problem(E.SCART_ARCHIVE, str(exc), path, 0)], set(overrides or {}))
        folder = Path(unpacked.name).resolve()
    elif given.is_dir():
        folder = given
    else:
        return path, None
    found, why = deployable_of(folder)
    if found is None:
        shown = [p if unpacked is None else dataclasses.replace(
            p, path=p.path.replace(str(folder), f"{path}!"), message=p.message.replace(str(folder), f"{path}!"))
                 for p in why]
        _refuse(shown, set(overrides or {}))
    return found, (given, unpacked) if unpacked is not None else None


_REFUSED = re.compile(r"refused by its check: (.*?)(?: \[type=|$)", re.S)

def _is_element(registry: ExtensionRegistry, name: str) -> bool:
    try:
        return registry.element(name) is not None
    except ExtensionError:
        return True  # known but broken: read it, and let the check report why it cannot be used


class _Assembler(Checks):
    def __init__(self, contribution: Contribution, registry: ExtensionRegistry, context: CheckContext,
                 overrides: dict[str, str], strict_overrides: bool = True) -> None:
        self.contribution = contribution
        self.registry = registry
        self.context = context
        self.overrides = overrides
        self.strict_overrides = strict_overrides
        self.used_overrides: set[str] = set()
        self.problems: list[Problem] = []
        self.nodes: dict[str, Node] = {}
        self.extensions: list[tuple[str, Element]] = []
        self.reader = PropertyReader(contribution, self.problem)
        self.side_files: dict[str, SideFile] = {}  # by component path
        self._promoted_interfaces: dict[int, tuple[str, InterfaceInfo]] = {}  # composite reference -> first promoted
        #: (component path, service) -> the interface its <service> declares: what wires see of it
        self.declared_services: dict[tuple[str, str], InterfaceInfo] = {}

    def problem(self, code: str, message: str, loc: Location) -> None:
        self.problems.append(Problem(code, message, loc.path, loc.line))

    def run(self, root: Composite) -> Assembly:
        props = {p.name: self.declaration_values(p) for p in root.properties}
        scope = self.build(root, "", props, {p.name: self.reader.declared(p) for p in root.properties})
        self.wire(scope, {})
        for key in sorted(set(self.overrides) - self.used_overrides) if self.strict_overrides else ():
            self.problems.append(Problem(E.SCART_OVERRIDE, f"--set {key}: {self.no_such_property(key)}",
                                         "<command line>", 0))
        services: dict[str, Target] = {}
        bindings: dict[str, list[Binding]] = {}
        for cs in root.services:
            target = self.resolve_service(scope, cs.promote, cs.loc, E.ASM_PROMOTED_SERVICE,
                                          what=f"composite service {cs.name!r}: @promote ")
            if target is not None:
                self.promoted_service(cs, target)
                services[cs.name] = target
                bindings[cs.name] = cs.bindings
        aliases: dict[str, Target] = {}
        for name, child in scope.children.items():
            offered = list(child.ctype.services) if child.ctype is not None else []
            for sname in offered:
                t = self.resolve_service(scope, f"{name}/{sname}", root.loc)
                if t is not None:
                    aliases[f"{name}/{sname}"] = t
                    if len(offered) == 1:
                        aliases[name] = t
        result = Assembly(root, self.contribution, self.registry, self.nodes, self.init_order(), services, bindings,
                          aliases, self.extensions)
        self.check_bindings(result)
        self.check_implementations(result)
        self.check_extensions(result)
        return result

    def no_such_property(self, key: str) -> str:
        """Why an override ``Component.prop`` names nothing, with what it could name."""
        path, _, name = key.rpartition(".")
        node = self.nodes.get(path)
        if node is None:
            known = list(self.nodes)
            return (f"no component {path!r}{did_you_mean(path, known)}; components: "
                    f"{', '.join(known[:20]) or 'none'}")
        props = list(node.ctype.properties)
        return (f"component {path!r} has no property {name!r}{did_you_mean(name, props)}; its properties: "
                f"{', '.join(props) or 'none'}")

    # --- phase 1: build ---------------------------------------------------------------

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

    def offered(self, target: Target) -> InterfaceInfo:
        """The interface a service offers to wires: the one its ``<service>`` declares, else its implementation's."""
        declared = self.declared_services.get((target.node, target.service))
        return declared if declared is not None else self.nodes[target.node].ctype.services[target.service]

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

    # --- properties ---------------------------------------------------------------------

    def component_raw_props(self, comp: Component, ctype: ComponentType, scope: Scope, path: str,
                            families: dict[str, str | None],
                            declared: dict[str, TypeRef | None] | None = None) -> dict[str, list[str] | None]:
        """The raw values a component gives its properties (``@source`` from ``scope``,
        then ``--set``), their types checked against the componentType's ``families`` (and
        the XML types it ``declared``)."""
        raw: dict[str, list[str] | None] = {}
        for p in comp.properties:
            if p.name in ctype.properties:
                if self.check_property_types(comp, p, scope, families.get(p.name), (declared or {}).get(p.name)):
                    raw[p.name] = self.raw_value(p, scope.props)
                else:
                    raw[p.name] = Refused()
        for name in ctype.properties:
            key = f"{path}.{name}"
            if key in self.overrides:
                raw[name] = [self.overrides[key]]
                self.used_overrides.add(key)
        return raw

    def check_property_types(self, comp: Component, p: PropertyValue, scope: Scope, family: str | None,
                             theirs: TypeRef | None = None) -> bool:
        """A component property's declared type matches its componentType's (``family``,
        and ``theirs`` when the componentType declares an XML type) (ASM50036); a composite
        property it takes whole through ``@source`` matches too (ASM50038). False when one
        does not (reported, naming both types)."""
        reader = self.reader
        own = reader.declared(p)
        if own is not None and not (compatible(reader.family(own), family) and reader.agree(own, theirs)):
            their_type = reader.shown(theirs, p.namespaces) if theirs is not None else family
            self.problem(E.ASM_PROPERTY_TYPE_MISMATCH, f"component {comp.name!r} property {p.name!r}: declared "
                         f"{reader.shown(own, p.namespaces)}, but its componentType's is {their_type}", p.loc)
            return False
        m = re.fullmatch(r"\s*\$([A-Za-z_][\w.-]*)\s*", p.source or "")
        if m is None or m[1] not in scope.types:
            return True
        source = scope.types[m[1]]
        wanted_ref = own if own is not None else theirs
        wanted = reader.family(own) if own is not None else family
        if source is not None and not (compatible(reader.family(source), wanted) and reader.agree(source, wanted_ref)):
            shown = reader.shown(wanted_ref, p.namespaces) if wanted_ref is not None else wanted
            self.problem(E.ASM_SOURCE_TYPE, f"component {comp.name!r} property {p.name!r} ({shown}): @source "
                         f"${m[1]} is {reader.shown(source, p.namespaces)}", p.loc)
            return False
        return True

    def check_against(self, comp: Component, decl: PropertyValue, values: list[str], from_cli: bool) -> list[str] | None:
        """The values a component gives a property of the composite it implements, checked
        at the component (its line) against what the composite declares: its type or
        element, and one value unless ``many`` (ASM50032). Refused when wrong (reported)."""
        own = None if from_cli else next((p for p in comp.properties if p.name == decl.name), None)
        typed = own is not None and self.reader.declared(own) is not None  # checked already, against its own type
        if own is None:  # from --set
            own = decl.model_copy(update={"loc": Location(path="<command line>", line=0), "values": list(values),
                                          "xml": None, "file": None, "source": None})
        if len(values) > 1 and not decl.many:
            self.problem(E.ASM_SINGLE_VALUED, f"component {comp.name!r} property {decl.name!r} "
                         f"({self.reader.shown(self.reader.declared(decl), decl.namespaces)}) is single-valued but has {len(values)} "
                         "values", own.loc)
            return Refused()
        if not typed and not self.reader.check(
                own.model_copy(update={"type": decl.type, "element": decl.element}), values):
            return Refused()
        return values

    def declaration_values(self, decl: PropertyValue) -> list[str] | None:
        """The values a composite or componentType property declaration gives itself: one
        unless it is ``many`` (ASM50032)."""
        values = self.raw_value(decl, {})
        if values is not None and len(values) > 1 and not decl.many and not isinstance(values, Refused):
            self.problem(E.ASM_SINGLE_VALUED, f"property {decl.name!r} ({self.reader.shown(self.reader.declared(decl), decl.namespaces)})"
                         f" is single-valued but has {len(values)} values", decl.loc)
            return Refused()
        return values

    def raw_value(self, p: PropertyValue, ctx: dict[str, list[str] | None]) -> list[str] | None:
        """The raw values of ``p`` (see :class:`scart.properties.PropertyReader`)."""
        return self.reader.raw(p, ctx)

    def property_value(self, comp: Component, name: str, spec: PropSpec, py_type: Any, raw: list[str] | None,
                       override: str | None = None) -> Any:
        where = next((p.loc for p in comp.properties if p.name == name), comp.loc)
        if override is not None:  # the value came from --set: that is where the problem is
            where = Location(path="<command line>", line=0)
            name = f"{name} (--set {override})"
        if isinstance(raw, Refused):
            return DEFAULT  # its problem is reported
        if raw is None:
            if spec.required:
                self.problem(E.ASM_MUST_SUPPLY, f"component {comp.name!r}: required property {name!r} "
                             "not supplied", comp.loc)
            return DEFAULT
        if len(raw) > 1 and not is_many(py_type):
            type_name = getattr(py_type, "__name__", None) or str(py_type)
            self.problem(E.ASM_SINGLE_VALUED, f"property {name!r} ({type_name}) is single-valued but has "
                         f"{len(raw)} values", where)
            return DEFAULT
        try:
            return parse_value(raw, py_type)
        except ValueError as exc:
            if isinstance(raw, FileValues):  # never echo a file's content (it may be anything)
                type_name = getattr(py_type, "__name__", str(py_type))
                self.problem(E.ASM_PROPERTY_VALUE, f"property {name!r}: the content of file {raw.file!r} is not a "
                             f"valid {type_name} (content not shown)", where)
                return DEFAULT
            msg = str(exc)
            refused = _REFUSED.search(msg)  # a task Property's own check: say so, without pydantic's noise
            if refused is not None:
                msg = f"{' '.join(raw)!r} refused by its check: {refused.group(1).strip()}"
            self.problem(E.ASM_PROPERTY_VALUE, f"property {name!r}: {msg}", where)
            return DEFAULT

    # --- phase 2: wire ------------------------------------------------------------------

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

    def reference_interface(self, declared: Interface | None, ref_type: type | None, loc: Location) -> InterfaceInfo | None:
        """The interface a reference uses: the declared one (``<interface.*>``), else its
        annotation's; None when neither (or the declared one is broken: reported)."""
        if declared is not None:
            return self.declared_interface(declared)
        return interface_info(ref_type) if ref_type is not None else None

    def nested_reference_interface(self, child: Scope, ref: str, depth: int) -> InterfaceInfo | None:
        """The interface of reference ``ref`` of a composite used as an implementation:
        the one its composite reference declares, else the one of the reference it
        promotes (through nested composites); None when unknown."""
        cr = next((r for r in child.composite.references if r.name == ref), None)
        if cr is None or depth > 32:  # bounded (cycles are refused at load)
            return None
        if cr.interface is not None:
            return self.declared_interface(cr.interface)
        comp_name, _, inner_ref = (cr.promote[0] if cr.promote else "").partition("/")
        inner = child.children.get(comp_name)
        if inner is None or isinstance(inner, Failed) or inner.ctype is None or inner_ref not in inner.ctype.references:
            return None
        comp = inner.model if isinstance(inner, Node) else inner.component
        xml = next((r for r in comp.references if r.name == inner_ref), None) if comp is not None else None
        if xml is not None and xml.interface is not None:
            return self.declared_interface(xml.interface)
        ref_type = inner.ctype.references[inner_ref][1]
        if ref_type is not None:
            return interface_info(ref_type)
        return self.nested_reference_interface(inner, inner_ref, depth + 1) if isinstance(inner, Scope) else None

    def declared_interface(self, declared: Interface) -> InterfaceInfo | None:
        """An ``<interface.wsdl>``, ``<interface.java>`` or ``<scart:interface.python>``
        with its callback interface: the one ``@callbackInterface`` names must agree with
        the one the interface itself declares (ASM80011); a WSDL interface is remotable
        (ASM80017). None (reported) when it cannot be resolved."""
        if declared.invalid:
            return None  # reported by the schema check
        if declared.kind == "interface.wsdl":
            if declared.remotable is False:
                self.problem(E.ASM_WSDL_REMOTABLE, f"interface.wsdl {declared.target!r}: remotable=\"false\" is not "
                             "allowed (a WSDL interface is always remotable)", declared.loc)
            info = self.contribution.wsdl_interface(declared.target, declared.loc)
            cb = (self.contribution.wsdl_interface(declared.callback, declared.loc, "callbackInterface")
                  if declared.callback else None)
        else:
            java = declared.kind == "interface.java"
            info = self.python_interface(_class_name(declared.target, java), declared.loc)
            cb = self.python_interface(_class_name(declared.callback, java), declared.loc) if declared.callback else None
            if info is not None and declared.remotable is not None:
                info = dataclasses.replace(info, remotable=declared.remotable)
        if info is None or (declared.callback and cb is None):
            return None  # reported; an interface missing its callback would only cause knock-on problems
        if cb is not None:
            own = info.callback
            if own is not None and set(own.operations) != set(cb.operations):
                self.problem(E.ASM_CALLBACK_AGREES, f"interface {info.name}: callbackInterface {cb.name} disagrees "
                             f"with the callback interface {own.name} that {info.name} itself declares", declared.loc)
                return None  # what else is said of it would be a knock-on
            info = dataclasses.replace(info, callback=cb)
        return info

    def python_interface(self, target: str, loc: Location) -> InterfaceInfo | None:
        try:
            obj = import_object(target, self.contribution.folder)
        except Exception as exc:
            self.problem(E.SCART_IMPORT, f"cannot import interface {target!r}: {exc}", loc)
            return None
        if not isinstance(obj, type):
            self.problem(E.SCART_IMPORT, f"interface {target!r} is not a class", loc)
            return None
        return interface_info(obj)

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

    def init_order(self) -> list[str]:
        """Leaf paths, targets before sources; definition order otherwise; cycles broken."""
        order: list[str] = []
        state: dict[str, int] = {}
        for start in self.nodes:
            stack: list[tuple[str, int]] = [(start, 0)]
            while stack:
                path, i = stack.pop()
                if i == 0:
                    if state.get(path):
                        continue
                    state[path] = 1
                deps = [t.node for ts in self.nodes[path].references.values() for t in ts if isinstance(t, Target)]
                if i < len(deps):
                    stack.append((path, i + 1))
                    if not state.get(deps[i]):
                        stack.append((deps[i], 0))
                else:
                    state[path] = 2
                    order.append(path)
        return order


def _class_name(target: str, java: bool) -> str:
    """``module:Class``; an ``interface.java`` may name it ``a.b.C`` (the class C of module a.b)."""
    return ":".join(target.rsplit(".", 1)) if java and ":" not in target else target


def _required(mult: str | None) -> bool:
    return (mult or "1..1").startswith("1")


def _multiple(mult: str | None) -> bool:
    return (mult or "1..1").endswith("n")


__all__ = ["assemble"]
