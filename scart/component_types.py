"""What an implementation's componentType gives its components beyond the implementation
itself (private helper of :mod:`scart.assembly`): a ``Class.componentType`` side file next
to a Python class's module (:class:`SideFile`), and the bindings of a composite's own
references when the composite is used as an implementation
(:func:`composite_reference_defaults`)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from scart import errors as E
from scart.api import ComponentType, PropSpec, RefSpec
from scart.checks import NARROWINGS as _NARROWINGS
from scart.model import Binding, Component, ComponentTypeFile, Composite, Location
from scart.properties import TypeRef, compatible, python_family
from scart.scdl import SCA_NAMESPACES as _SCA_NAMESPACES

if TYPE_CHECKING:
    from scart.assembly._components import Components

__all__ = ["SideFile", "composite_reference_defaults"]


class SideFile:
    """A componentType side file checked against its implementation class: it may type
    properties, give them defaults or make them mustSupply, narrow reference
    multiplicities and give references default targets (``binding.sca`` ``@uri``) or
    bindings. Names the class does not declare are problems (SCART-C007)."""

    def __init__(self, model: ComponentTypeFile, ctype: ComponentType, assembler: Components) -> None:
        self.types: dict[str, TypeRef] = {}
        self.defaults: dict[str, list[str] | None] = {}
        self.required: set[str] = set()
        self.multiplicity: dict[str, str] = {}
        self.targets: dict[str, list[tuple[str, Location]]] = {}
        self.bindings: dict[str, list[Binding]] = {}
        what = f"componentType of {ctype.cls.__name__}"
        for s in model.services:
            if s.name not in ctype.services:
                assembler.problem(E.SCART_SIDE_FILE, f"{what}: service {s.name!r} is not one the class offers "
                                  f"({', '.join(ctype.services) or 'none'})", s.loc)
            elif s.interface is not None:
                declared = assembler.declared_interface(s.interface)
                if declared is not None:
                    assembler.check_subset(declared, ctype.services[s.name], E.SCART_SIDE_FILE,
                                           f"{what}: service {s.name!r} declared as {declared.name}", s.interface.loc)
        for r in model.references:
            if r.name not in ctype.references:
                assembler.problem(E.SCART_SIDE_FILE, f"{what}: reference {r.name!r} is not one the class declares "
                                  f"({', '.join(ctype.references) or 'none'})", r.loc)
                continue
            declared_mult = ctype.references[r.name][0].multiplicity
            if r.multiplicity and r.multiplicity not in _NARROWINGS.get(declared_mult, ()):
                assembler.problem(E.SCART_SIDE_FILE, f"{what}: reference {r.name!r} is {declared_mult} in the class; "
                                  f"{r.multiplicity} does not narrow it", r.loc)
            elif r.multiplicity:
                self.multiplicity[r.name] = r.multiplicity
            uris: list[tuple[str, Location]] = []
            self.bindings[r.name] = assembler.reference_bindings(Component(name=what, loc=r.loc), r.name, r, uris)
            self.targets[r.name] = uris
        for p in model.properties:
            if p.name not in ctype.properties:
                assembler.problem(E.SCART_SIDE_FILE, f"{what}: property {p.name!r} is not one the class declares "
                                  f"({', '.join(ctype.properties) or 'none'})", p.loc)
                continue
            ref = assembler.reader.declared(p)
            if ref is not None:
                family, own = python_family(ctype.properties[p.name][1]), assembler.reader.family(ref)
                if not compatible(own, family):
                    assembler.problem(E.SCART_SIDE_FILE, f"{what}: property {p.name!r} is {family} in the class, "
                                      f"{assembler.reader.shown(ref, p.namespaces)} here", p.loc)
                self.types[p.name] = ref
            if p.values is not None or p.xml is not None or p.file is not None:
                self.defaults[p.name] = assembler.declaration_values(p)
            if p.must_supply:
                self.required.add(p.name)

    def merge(self, ctype: ComponentType) -> ComponentType:
        """``ctype`` with this file's mustSupply properties and narrowed multiplicities."""
        if not self.required and not self.multiplicity:
            return ctype
        props = dict(ctype.properties)
        for name in self.required:
            spec, py_type = props[name]
            required = PropSpec(spec.default, True)
            required.name = name
            props[name] = (required, py_type)
        refs = dict(ctype.references)
        for name, mult in self.multiplicity.items():
            _, ref_type = refs[name]
            narrowed = RefSpec(mult.startswith("1"), mult.endswith("n"))
            narrowed.name = name
            refs[name] = (narrowed, ref_type)
        return dataclasses.replace(ctype, properties=props, references=refs)


def composite_reference_defaults(composite: Composite, ref: str) -> tuple[list[tuple[str, Location]], list[Binding]]:
    """What a composite used as an implementation gives its reference ``ref`` when the
    component wires it no other way (its componentType's default): a ``binding.sca``
    ``@uri`` is a target resolved beside the component; other bindings reach their own
    endpoints."""
    cr = next((r for r in composite.references if r.name == ref), None)
    uris: list[tuple[str, Location]] = []
    bindings: list[Binding] = []
    for b in cr.bindings if cr is not None else []:
        if b.kind == "binding.sca" and b.namespace in _SCA_NAMESPACES:
            if "uri" in b.attributes:
                uris.append((b.attributes["uri"], b.loc))
        else:
            bindings.append(b)
    return uris, bindings
