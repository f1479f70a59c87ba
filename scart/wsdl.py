"""WSDL 1.1 documents as ``interface.wsdl`` uses them (private helper of
:mod:`scart.contribution`): their portTypes — operations, one-way ones, the callback an
``sca:callback`` attribute names — and the XML Schema components their messages need.

A message part names a global element (``element=``) or a type (``type=``). It is
declared by a schema inside the WSDL's ``<types>``, or by an ``.xsd`` file of the
contributions: the one its ``xsi:schemaLocation`` or an ``xs:import``'s
``@schemaLocation`` names is looked up there by file name, never fetched. A part whose
element or type no schema declares is a problem naming the WSDL (its file and line),
the part and the schema the WSDL points at.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field

from lxml import etree

from scart import errors as E
from scart.api import InterfaceInfo, Operation
from scart.errors import Problem
from scart.model import SCA10_NS, SCA11_NS

__all__ = ["WSDL_NS", "Need", "WsdlTypes", "missing_schemas", "parse_wsdl_target", "port_type_needs",
           "read_port_types", "wsdl_types"]

WSDL_NS = "http://schemas.xmlsoap.org/wsdl/"
XSD_NS = "http://www.w3.org/2001/XMLSchema"
XSI_NS = "http://www.w3.org/2001/XMLSchema-instance"

#: What an ``interface.wsdl`` @interface (or @callbackInterface) may say.
_WSDL_TARGET = re.compile(r"(?P<ns>[^#\s]*)#wsdl\.(?:porttype|interface)\((?P<name>[^()\s]+)\)")


@dataclass(frozen=True)
class Need:
    """An element or type a portType's message part names (Clark QName), and where."""

    qname: str
    what: str  # "element" | "type"
    part: str  # "operation 'op' input message 'm' part 'p'"
    line: int


@dataclass
class WsdlTypes:
    """What a WSDL says of its schemas: the global elements and types its ``<types>``
    declare (Clark QNames), and the schema locations it names, by namespace."""

    declared: set[str] = field(default_factory=set)
    locations: dict[str, list[str]] = field(default_factory=dict)


def parse_wsdl_target(target: str) -> tuple[str, str] | None:
    """``(namespace, name)`` of ``ns#wsdl.porttype(Name)`` or ``ns#wsdl.interface(Name)``; None otherwise."""
    m = _WSDL_TARGET.fullmatch(target.strip())
    return (m["ns"], m["name"]) if m else None


def _qname(el: etree._Element, raw: str, default_ns: str) -> str:
    prefix, _, local = raw.strip().rpartition(":")
    ns = el.nsmap.get(prefix) if prefix else default_ns
    return f"{{{ns or ''}}}{local}"


def read_port_types(root: etree._Element, path: str = "<memory>"
                    ) -> tuple[dict[str, InterfaceInfo], dict[str, tuple[str, Problem]]]:
    """WSDL 1.1 ``portType`` s of a parsed ``definitions`` element, by Clark QName, and the
    callback portType each names with an ``sca:callback`` attribute (Clark QName, and the
    problem to report if it names nothing).

    An operation with an ``input`` and no ``output`` is one-way.
    """
    tns = root.get("targetNamespace", "")
    out: dict[str, InterfaceInfo] = {}
    callbacks: dict[str, tuple[str, Problem]] = {}
    for pt in root.iterchildren(f"{{{WSDL_NS}}}portType"):
        ops: dict[str, Operation] = {}
        for op in pt.iterchildren(f"{{{WSDL_NS}}}operation"):
            has_out = op.find(f"{{{WSDL_NS}}}output") is not None
            ops[op.get("name", "")] = Operation(op.get("name", ""), oneway=not has_out, returns_value=has_out)
        qname = f"{{{tns}}}{pt.get('name', '')}"
        out[qname] = InterfaceInfo(pt.get("name", ""), ops, remotable=True)
        for sca in (SCA11_NS, SCA10_NS):
            raw = pt.get(f"{{{sca}}}callback")
            if raw is None:
                continue
            callbacks[qname] = (_qname(pt, raw, tns), Problem(
                E.SCART_WSDL, f"portType {pt.get('name', '')!r}: sca:callback {raw!r} names no portType in the "
                "contribution", path, pt.sourceline or 0))
    return out, callbacks


def port_type_needs(root: etree._Element) -> dict[str, list[Need]]:
    """For each portType (Clark QName), the elements and types its operations' messages
    name. A message the WSDL does not declare is left to the WSDL's own validity."""
    tns = root.get("targetNamespace", "")
    messages = {f"{{{tns}}}{m.get('name', '')}": m for m in root.iterchildren(f"{{{WSDL_NS}}}message")}
    out: dict[str, list[Need]] = {}
    for pt in root.iterchildren(f"{{{WSDL_NS}}}portType"):
        needs: list[Need] = []
        for op in pt.iterchildren(f"{{{WSDL_NS}}}operation"):
            for io in op.iterchildren(f"{{{WSDL_NS}}}input", f"{{{WSDL_NS}}}output", f"{{{WSDL_NS}}}fault"):
                message = messages.get(_qname(io, io.get("message", ""), tns))
                if message is None:
                    continue
                for part in message.iterchildren(f"{{{WSDL_NS}}}part"):
                    for what in ("element", "type"):
                        if part.get(what):
                            needs.append(Need(_qname(part, part.get(what, ""), ""), what,
                                              f"operation {op.get('name', '')!r} {etree.QName(io).localname} message "
                                              f"{message.get('name', '')!r} part {part.get('name', '')!r}",
                                              part.sourceline or 0))
        out[f"{{{tns}}}{pt.get('name', '')}"] = needs
    return out


def wsdl_types(root: etree._Element) -> WsdlTypes:
    """The schemas a WSDL declares in its ``<types>`` and the locations it names
    (``xsi:schemaLocation`` pairs on any element, ``xs:import``/``xs:include`` ``@schemaLocation``)."""
    found = WsdlTypes()
    for schema in root.iterfind(f"{{{WSDL_NS}}}types/{{{XSD_NS}}}schema"):
        tns = schema.get("targetNamespace", "")
        for child in schema.iterchildren(f"{{{XSD_NS}}}element", f"{{{XSD_NS}}}complexType",
                                         f"{{{XSD_NS}}}simpleType"):
            if child.get("name"):
                found.declared.add(f"{{{tns}}}{child.get('name')}")
        for ref in schema.iterchildren(f"{{{XSD_NS}}}import", f"{{{XSD_NS}}}include"):
            if ref.get("schemaLocation"):
                ns = ref.get("namespace", tns)
                found.locations.setdefault(ns, []).append(ref.get("schemaLocation", ""))
    for el in root.iter(tag=etree.Element):
        pairs = (el.get(f"{{{XSI_NS}}}schemaLocation") or "").split()
        for ns, location in zip(pairs[::2], pairs[1::2]):
            found.locations.setdefault(ns, []).append(location)
    return found


def missing_schemas(needs: list[Need], types: WsdlTypes, known: Callable[[str, str], bool],
                    has_file: Callable[[str], bool], path: str, port_type: str) -> list[Problem]:
    """A problem (at the part's line of the WSDL ``path``) for each need no schema
    declares: not in the WSDL's ``<types>``, and ``known(what, qname)`` (the
    contributions' schemas) says no; ``has_file(name)`` says whether the contributions
    hold a schema file of that name (what a location the WSDL names is looked up as)."""
    problems: list[Problem] = []
    for need in needs:
        ns, _, local = need.qname[1:].partition("}")
        if ns == XSD_NS or need.qname in types.declared or known(need.what, need.qname):
            continue
        named = types.locations.get(ns, [])
        absent = [n for n in named if not has_file(n.rstrip("/").rpartition("/")[2])]
        if absent:
            where = (f"the schema it names for that namespace ({', '.join(repr(n) for n in absent)}) is not in "
                     "the contributions (schemas are looked up by file name among their .xsd files, never fetched)")
        elif named:
            where = f"the schema it names for that namespace ({', '.join(repr(n) for n in named)}) does not declare it"
        else:
            where = "no schema of the contributions, nor the WSDL's <types>, declares it"
        problems.append(Problem(E.ASM_UNRESOLVED, f"WSDL portType {port_type!r}: {need.part} names {need.what} "
                                f"{local!r} of namespace {ns!r}, and {where}", path, need.line))
    return problems
