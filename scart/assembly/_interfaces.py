"""The interfaces of the assembly: declared ones (``<interface.*>``, with their callback
interfaces), a reference's, a nested composite reference's, and what a service offers to
wires. A mixin of the assembler, private to :mod:`scart.assembly`."""

from __future__ import annotations

import dataclasses

from scart import errors as E
from scart.api import InterfaceInfo, interface_info
from scart.assembly._state import AssemblerState, Failed, Scope
from scart.contribution import import_object
from scart.graph import Node, Target
from scart.model import Interface, Location


class Interfaces(AssemblerState):
    """Resolves and checks interfaces (ASM80011, ASM80017)."""

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

    def offered(self, target: Target) -> InterfaceInfo:
        """The interface a service offers to wires: the one its ``<service>`` declares, else its implementation's."""
        declared = self.declared_services.get((target.node, target.service))
        return declared if declared is not None else self.nodes[target.node].ctype.services[target.service]


def _class_name(target: str, java: bool) -> str:
    """``module:Class``; an ``interface.java`` may name it ``a.b.C`` (the class C of module a.b)."""
    return ":".join(target.rsplit(".", 1)) if java and ":" not in target else target
