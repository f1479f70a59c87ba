"""The SCDL loader: composite XML (SCA 1.1, SCA 1.0/OSOA, ``urn:scart:1.0``) to the model.

Parsing is safe: a size bound checked before reading, any DOCTYPE refused, lxml's parser
with ``resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False``.
Elements of ``urn:scart:1.0`` are validated against the XSD shipped in
``scart/schema/scart-1.0.xsd``.

The loader never raises on a bad composite: it appends :class:`~scart.errors.Problem` s
to ``Loader.problems`` and goes on, so every problem is reported together.
One small reader per element type; the table :data:`COMPOSITE_CHILDREN` dispatches the
children of ``<composite>``. Children of ``<composite>`` outside the SCA namespaces that
the runtime's extension registry knows by local name (``scart:connect``, or a
third-party ``foo:thing``) are read generically into ``Composite.extensions``, as are
``implementation.*`` and ``binding.*`` elements of any namespace (see ``scart.model``):
new kinds are added as extensions, not here. Only scart's own namespace is checked
against the shipped XSD; an extension checks its own elements.
"""

from __future__ import annotations

import functools
import os
import re
from collections.abc import Callable
from pathlib import Path
from types import MappingProxyType
from typing import Any

from lxml import etree

from scart import errors as E
from scart.errors import Problem
from scart.model import (
    SCA10_NS,
    SCA11_NS,
    SCART_NS,
    Binding,
    Component,
    ComponentReference,
    ComponentService,
    Composite,
    CompositeReference,
    CompositeService,
    Element,
    Implementation,
    Include,
    Interface,
    Location,
    PropertyValue,
    Wire,
)

MAX_BYTES = 8 * 1024 * 1024  #: size bound of any XML file read (composite or WSDL)
SCA_NAMESPACES = (SCA11_NS, SCA10_NS)
_IGNORED = frozenset({"documentation", "requires", "policySetAttachment", "extensions", "description"})
_SCHEMA_PATH = Path(__file__).with_name("schema") / "scart-1.0.xsd"
_PROLOG_LIMIT = 64 * 1024  #: how much of a file's head is scanned for a DOCTYPE before its root element


def _prolog_doctype_line(data: bytes) -> int | None:
    """The line of a ``<!DOCTYPE``/``<!ENTITY`` before the root element, else None.

    Only the prolog is scanned (XML declaration, processing instructions, comments,
    whitespace), so the same text inside a comment or in content is no false positive.
    UTF-16 files (BOM or not) are decoded first; other encodings are read as Latin-1,
    which keeps every ASCII markup character in place."""
    head = data[:_PROLOG_LIMIT]
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        text = head.decode("utf-16", errors="replace")
    elif head.startswith(b"<\x00"):
        text = head.decode("utf-16-le", errors="replace")
    elif head.startswith(b"\x00<"):
        text = head.decode("utf-16-be", errors="replace")
    else:
        text = head.decode("latin-1")
    i, n = 0, len(text)
    while i < n:  # bounded: i grows every round
        if text[i].isspace() or text[i] in "\ufeff\u00ef\u00bb\u00bf":  # (a UTF-8 BOM read as Latin-1)
            i += 1
        elif text.startswith("<?", i):
            end = text.find("?>", i + 2)
            if end < 0:
                return None
            i = end + 2
        elif text.startswith("<!--", i):
            end = text.find("-->", i + 4)
            if end < 0:
                return None
            i = end + 3
        elif text[i:i + 9].upper() == "<!DOCTYPE" or text[i:i + 8].upper() == "<!ENTITY":
            return text.count("\n", 0, i) + 1
        else:
            return None  # the root element (or malformed: the parser reports it)
    return None


def _parser() -> etree.XMLParser:
    return etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False,
        dtd_validation=False, remove_pis=True,
    )


def parse_xml(path: str, problems: list[Problem], max_bytes: int = MAX_BYTES) -> etree._Element | None:
    """Parse ``path`` safely; on any problem append it to ``problems`` and return None.

    Refuses files over ``max_bytes`` (checked before reading) and any DOCTYPE or entity
    declaration (checked before and after parsing), never touching the network.
    """
    try:
        size = os.path.getsize(path)
        if size > max_bytes:
            problems.append(Problem(E.SCART_UNSAFE_XML, f"file is {size} bytes, over the {max_bytes} bytes bound", path, 0))
            return None
        with open(path, "rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        problems.append(Problem(E.SCART_XML, f"cannot read: {exc.strerror or exc}", path, 0))
        return None
    line = _prolog_doctype_line(data)
    if line is not None:
        problems.append(Problem(E.SCART_UNSAFE_XML, "DOCTYPE/ENTITY declarations are refused", path, line))
        return None
    try:
        root = etree.fromstring(data, _parser())
    except etree.XMLSyntaxError as exc:
        problems.append(Problem(E.SCART_XML, f"malformed XML: {exc.msg}", path, exc.lineno or 0))
        return None
    if root.getroottree().docinfo.doctype or root.getroottree().docinfo.internalDTD is not None:
        problems.append(Problem(E.SCART_UNSAFE_XML, "DOCTYPE declarations are refused", path, 1))
        return None
    return root


@functools.cache
def _xsd() -> etree.XMLSchema:
    """The shipped XSD of ``urn:scart:1.0`` (parsed once)."""
    return etree.XMLSchema(etree.parse(str(_SCHEMA_PATH), _parser()))


def _bool(value: str | None, default: bool = False) -> bool:
    if value is None:
        return default
    return value.strip().lower() in ("true", "1")


def _local(el: etree._Element) -> tuple[str, str]:
    q = etree.QName(el)
    return q.namespace or "", q.localname


class Loader:
    """Reads one composite file into a :class:`~scart.model.Composite`; collects problems.

    ``resolve_composite`` is given by the contribution to find composites by QName
    (for ``implementation.composite`` and ``include``); it returns None when unknown.
    ``is_element(local_name)`` says whether a ``<scart:NAME>`` child of ``<composite>``
    is an extension element the runtime knows.
    """

    def __init__(self, path: str, resolve_composite: Callable[[str, Location], Composite | None],
                 is_element: Callable[[str], bool] = lambda name: False) -> None:
        self.path = path
        self.problems: list[Problem] = []
        self.resolve_composite = resolve_composite
        self.is_element = is_element
        self._tns = ""

    def loc(self, el: etree._Element) -> Location:
        """The location of ``el``."""
        return Location(path=self.path, line=el.sourceline or 0)

    def problem(self, code: str, message: str, el: etree._Element) -> None:
        """Record a problem at ``el``."""
        self.problems.append(Problem(code, message, self.path, el.sourceline or 0))

    def append_unique(self, items: list[Any], item: Any, code: str, what: str, el: etree._Element) -> None:
        """Append ``item`` unless one of ``items`` has its name: then report ``code`` at ``el``
        (the second occurrence) and keep the first."""
        if any(i.name == item.name for i in items):
            self.problem(code, f"{what} {item.name!r}", el)
        else:
            items.append(item)

    def load(self) -> Composite | None:
        """Parse the file and read its ``<composite>``; None if it cannot be parsed at all."""
        root = parse_xml(self.path, self.problems)
        if root is None:
            return None
        ns, name = _local(root)
        if ns not in SCA_NAMESPACES or name != "composite":
            self.problem(E.SCART_UNKNOWN_ELEMENT, f"root element must be an SCA <composite>, not <{name}> in {ns!r}", root)
            return None
        return self.read_composite(root)

    # --- composite and its children ----------------------------------------------------

    def read_composite(self, el: etree._Element) -> Composite:
        """``<composite name targetNamespace autowire>`` and its children, via the dispatch table."""
        self._tns = el.get("targetNamespace", "")
        comp = Composite(
            name=self.required(el, "name") or "", target_namespace=self._tns,
            autowire=_bool(el.get("autowire")), loc=self.loc(el),
        )
        for child in el.iterchildren(tag=etree.Element):
            ns, local = _local(child)
            if ns in SCA_NAMESPACES and local in COMPOSITE_CHILDREN:
                COMPOSITE_CHILDREN[local](self, child, comp)
            elif ns not in SCA_NAMESPACES and self.is_element(local):
                if ns != SCART_NS or self.validate_scart(child):  # scart's own: the shipped XSD too
                    comp.extensions.append(self.read_element(child))
            elif local not in _IGNORED:
                self.problem(E.SCART_UNKNOWN_ELEMENT, f"unknown element <{local}> in {ns!r} inside <composite>", child)
        return comp

    def required(self, el: etree._Element, attr: str) -> str | None:
        """The attribute's value, or None after recording a schema problem."""
        value = el.get(attr)
        if value is None or not value.strip():
            self.problem(E.ASM_SCHEMA, f"<{_local(el)[1]}> needs a {attr!r} attribute", el)
            return None
        return value.strip()

    def read_component(self, el: etree._Element, parent: Composite) -> None:
        """``<component>``: implementation, services, references, properties."""
        comp = Component(name=self.required(el, "name") or "", loc=self.loc(el))
        if el.get("autowire") is not None:
            comp.autowire = _bool(el.get("autowire"))
        for child in el.iterchildren(tag=etree.Element):
            ns, local = _local(child)
            if local.startswith("implementation."):
                if comp.implementation is not None:
                    self.problem(E.ASM_SCHEMA, f"component {comp.name!r} has more than one implementation", child)
                comp.implementation = self.read_implementation(child)
            elif ns in SCA_NAMESPACES and local == "service":
                self.append_unique(comp.services, self.read_component_service(child), E.ASM_DUPLICATE_SERVICE,
                                   f"component {comp.name!r}: duplicate service", child)
            elif ns in SCA_NAMESPACES and local == "reference":
                self.append_unique(comp.references, self.read_component_reference(child), E.ASM_DUPLICATE_REFERENCE,
                                   f"component {comp.name!r}: duplicate reference", child)
            elif ns in SCA_NAMESPACES and local == "property":
                comp.properties.append(self.read_property(child))
            elif local not in _IGNORED:
                self.problem(E.SCART_UNKNOWN_ELEMENT, f"unknown element <{local}> in {ns!r} inside <component>", child)
        if comp.implementation is None:
            self.problem(E.ASM_SCHEMA, f"component {comp.name!r} has no implementation", el)
        parent.components.append(comp)

    def read_implementation(self, el: etree._Element) -> Implementation:
        """Any ``implementation.*``; ``implementation.composite`` is resolved by QName."""
        ns, local = _local(el)
        impl = Implementation(kind=local, namespace=ns, attributes=dict(el.attrib), loc=self.loc(el))
        if ns == SCART_NS and not self.validate_scart(el):
            impl.invalid = True  # reported; nothing is imported for it
        if local == "implementation.composite":
            qname = self.qname(el, "name")
            if qname is not None:
                impl.attributes["name"] = qname
                impl.composite = self.resolve_composite(qname, impl.loc)
                if impl.composite is None:
                    self.problem(E.ASM_NO_SUCH_COMPOSITE, f"implementation.composite names no composite {qname} in the contribution", el)
        return impl

    def qname(self, el: etree._Element, attr: str) -> str | None:
        """Attribute ``attr`` as a Clark QName (prefix resolved; no prefix: targetNamespace)."""
        raw = self.required(el, attr)
        if raw is None:
            return None
        prefix, _, local = raw.rpartition(":")
        if not prefix:
            return f"{{{self._tns}}}{local}"
        ns = el.nsmap.get(prefix)
        if ns is None:
            self.problem(E.ASM_SCHEMA, f"unknown namespace prefix {prefix!r} in {raw!r}", el)
            return None
        return f"{{{ns}}}{local}"

    def read_interface(self, el: etree._Element) -> Interface:
        """``interface.python``/``interface.wsdl``/``interface.java``: target and callback."""
        ns, local = _local(el)
        invalid = ns == SCART_NS and not self.validate_scart(el)
        target = el.get("interface") or el.get("class") or ""
        if not target and not invalid:
            self.problem(E.ASM_SCHEMA, f"<{local}> needs an 'interface' attribute", el)
        remotable = el.get("remotable")
        return Interface(kind=local, target=target, callback=el.get("callbackInterface"),
                         remotable=_bool(remotable) if remotable is not None else None,
                         invalid=invalid or not target, loc=self.loc(el))

    def read_binding(self, el: etree._Element) -> Binding:
        """Any ``binding.*``: kind, attributes and children kept for the binding's factory."""
        ns, local = _local(el)
        if ns == SCART_NS:
            self.validate_scart(el)
        generic = self.read_element(el)
        return Binding(kind=local, namespace=ns, attributes=generic.attributes, text=generic.text,
                       children=generic.children, name=el.get("name"), loc=self.loc(el))

    def read_element(self, el: etree._Element) -> Element:
        """Any element, generically (attributes, text, children)."""
        ns, local = _local(el)
        return Element(
            kind=local, namespace=ns, attributes=dict(el.attrib), text=(el.text or "").strip(),
            children=[self.read_element(c) for c in el.iterchildren(tag=etree.Element)], loc=self.loc(el),
        )

    def _port_children(self, el: etree._Element, what: str) -> tuple[Interface | None, list[Binding], list[Binding]]:
        iface, bindings, cb_bindings = None, [], []
        for child in el.iterchildren(tag=etree.Element):
            ns, local = _local(child)
            if local.startswith("interface."):
                iface = self.read_interface(child)
            elif local.startswith("binding."):
                bindings.append(self.read_binding(child))
            elif ns in SCA_NAMESPACES and local == "callback":
                cb_bindings.extend(self.read_binding(c) for c in child.iterchildren(tag=etree.Element)
                                   if _local(c)[1].startswith("binding."))
            elif local not in _IGNORED:
                self.problem(E.SCART_UNKNOWN_ELEMENT, f"unknown element <{local}> in {ns!r} inside <{what}>", child)
        return iface, bindings, cb_bindings

    def read_component_service(self, el: etree._Element) -> ComponentService:
        """A component's ``<service name>``."""
        iface, b, cb = self._port_children(el, "service")
        return ComponentService(name=self.required(el, "name") or "", interface=iface, bindings=b,
                                callback_bindings=cb, loc=self.loc(el))

    def read_component_reference(self, el: etree._Element) -> ComponentReference:
        """A component's ``<reference name target multiplicity autowire>``."""
        iface, b, cb = self._port_children(el, "reference")
        ref = ComponentReference(
            name=self.required(el, "name") or "", targets=(el.get("target") or "").split(),
            multiplicity=el.get("multiplicity"), interface=iface, bindings=b, callback_bindings=cb,
            loc=self.loc(el),
        )
        if el.get("autowire") is not None:
            ref.autowire = _bool(el.get("autowire"))
        return ref

    def read_property(self, el: etree._Element) -> PropertyValue:
        """``<property>`` with ``@value``, ``<value>`` children, text, ``@file`` or ``@source``."""
        values: list[str] | None = None
        if el.get("value") is not None:
            values = [el.get("value") or ""]
        value_children = [c for c in el.iterchildren(tag=etree.Element) if _local(c)[1] == "value"]
        if value_children:
            if values is not None:
                self.problem(E.ASM_SCHEMA, "property has both @value and <value> (ASM50033)", el)
            values = [(c.text or "").strip() for c in value_children]
        elif values is None and el.text and el.text.strip():
            values = [el.text.strip()]
        return PropertyValue(
            name=self.required(el, "name") or "", values=values, file=el.get("file"),
            source=el.get("source"), type=el.get("type"), many=_bool(el.get("many")),
            must_supply=_bool(el.get("mustSupply")), loc=self.loc(el),
        )

    def read_composite_property(self, el: etree._Element, parent: Composite) -> None:
        """A composite-level ``<property>`` (flows to components through ``source="$name"``)."""
        prop = self.read_property(el)
        if any(p.name == prop.name for p in parent.properties):
            self.problem(E.ASM_DUPLICATE_COMPOSITE_PROPERTY, f"duplicate composite property {prop.name!r}", el)
        parent.properties.append(prop)

    def read_composite_service(self, el: etree._Element, parent: Composite) -> None:
        """A composite ``<service name promote>``."""
        iface, b, _ = self._port_children(el, "service")
        service = CompositeService(
            name=self.required(el, "name") or "", promote=self.required(el, "promote") or "",
            interface=iface, bindings=b, loc=self.loc(el))
        self.append_unique(parent.services, service, E.ASM_DUPLICATE_COMPOSITE_SERVICE,
                           "duplicate composite service", el)

    def read_composite_reference(self, el: etree._Element, parent: Composite) -> None:
        """A composite ``<reference name promote target multiplicity>``."""
        iface, b, _ = self._port_children(el, "reference")
        reference = CompositeReference(
            name=self.required(el, "name") or "", promote=(self.required(el, "promote") or "").split(),
            targets=(el.get("target") or "").split(), multiplicity=el.get("multiplicity"),
            interface=iface, bindings=b, loc=self.loc(el))
        self.append_unique(parent.references, reference, E.ASM_DUPLICATE_COMPOSITE_REFERENCE,
                           "duplicate composite reference", el)

    def read_wire(self, el: etree._Element, parent: Composite) -> None:
        """``<wire source target replace>``."""
        parent.wires.append(Wire(source=self.required(el, "source") or "", target=self.required(el, "target") or "",
                                 replace=_bool(el.get("replace")), loc=self.loc(el)))

    def read_include(self, el: etree._Element, parent: Composite) -> None:
        """``<include name="QName">``: the included composite's content is merged in place."""
        qname = self.qname(el, "name")
        if qname is None:
            return
        loc = self.loc(el)
        parent.includes.append(Include(name=qname, loc=loc))
        included = self.resolve_composite(qname, loc)
        if included is None:
            self.problem(E.ASM_INCLUDE_UNKNOWN, f"include names no composite {qname} in the contribution", el)
            return
        parent.components.extend(included.components)
        parent.services.extend(included.services)
        parent.references.extend(included.references)
        parent.properties.extend(included.properties)
        parent.wires.extend(included.wires)
        parent.extensions.extend(included.extensions)

    def validate_scart(self, el: etree._Element) -> bool:
        """Validate one ``urn:scart:1.0`` element against the shipped XSD; record problems."""
        schema = _xsd()
        if schema.validate(etree.ElementTree(_detached(el))):
            return True
        for entry in schema.error_log:
            msg = re.sub(r"\{urn:scart:1\.0\}", "scart:", entry.message)
            self.problem(E.SCART_SCHEMA, f"<{_local(el)[1]}>: {msg}", el)
        return False


def _detached(el: etree._Element) -> etree._Element:
    copy = etree.Element(el.tag, dict(el.attrib), nsmap={None: SCART_NS})
    for child in el.iterchildren(tag=etree.Element):
        copy.append(_detached(child))
    copy.text = el.text
    return copy


#: Readers of the SCA-namespace children of ``<composite>``, by local name.
COMPOSITE_CHILDREN: MappingProxyType[str, Callable[[Loader, etree._Element, Composite], None]] = MappingProxyType({
    "component": Loader.read_component,
    "service": Loader.read_composite_service,
    "reference": Loader.read_composite_reference,
    "property": Loader.read_composite_property,
    "wire": Loader.read_wire,
    "include": Loader.read_include,
})
