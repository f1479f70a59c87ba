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

import copy
import difflib
import functools
import os
import re
import stat
from collections.abc import Callable, Iterable
from pathlib import Path
from types import MappingProxyType
from typing import Protocol, TypeVar

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
    ComponentTypeFile,
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

class _Named(Protocol):
    """An element kept once per name (a service, a reference, a property...)."""

    @property
    def name(self) -> str: ...


N = TypeVar("N", bound=_Named)

MAX_BYTES = 8 * 1024 * 1024  #: size bound of any XML file read (composite or WSDL)
SCA_NAMESPACES = (SCA11_NS, SCA10_NS)
_IGNORED = frozenset({"documentation", "requires", "policySetAttachment", "extensions", "description"})
_SCHEMA_PATH = Path(__file__).with_name("schema") / "scart-1.0.xsd"
_PROLOG_LIMIT = 64 * 1024  #: how much of a file's head is scanned for a DOCTYPE before its root element
XSD_NS = "http://www.w3.org/2001/XMLSchema"

_POLICY = ("requires", "policySets")
_PROPERTY = ("name", "type", "element", "many", "mustSupply", "value", "file", "source", *_POLICY)
#: The attributes (without namespace) each SCA element may carry, by where it stands
#: (SCA Assembly 1.1 schema, sca-core; 1.0's ``constrainingType`` is tolerated). An
#: attribute in another namespace is always allowed (extensions).
ATTRIBUTES: MappingProxyType[str, frozenset[str]] = MappingProxyType({k: frozenset(v) for k, v in {
    "composite": ("name", "targetNamespace", "local", "autowire", "constrainingType", *_POLICY),
    "component": ("name", "autowire", "constrainingType", *_POLICY),
    "component service": ("name", *_POLICY),
    "component reference": ("name", "autowire", "target", "wiredByImpl", "multiplicity", "nonOverridable", *_POLICY),
    "property": _PROPERTY,
    "composite service": ("name", "promote", *_POLICY),
    "composite reference": ("name", "autowire", "promote", "target", "wiredByImpl", "multiplicity", *_POLICY),
    "wire": ("source", "target", "replace", *_POLICY),
    "include": ("name",),
    "implementation.composite": ("name", *_POLICY),
    "interface.java": ("interface", "callbackInterface", "remotable", *_POLICY),
    "interface.wsdl": ("interface", "callbackInterface", "remotable", *_POLICY),
    "binding.sca": ("name", "uri", *_POLICY),
    "callback": _POLICY,
    "componentType": ("constrainingType", *_POLICY),
    "componentType service": ("name", *_POLICY),
    "componentType reference": ("name", "autowire", "wiredByImpl", "multiplicity", *_POLICY),
}.items()})

MULTIPLICITIES = ("0..1", "1..1", "0..n", "1..n")

#: The code of "a property with both @type and @element", by where the property stands.
TYPE_AND_ELEMENT: MappingProxyType[str, str] = MappingProxyType({
    "componentType": E.ASM_CT_TYPE_AND_ELEMENT, "component": E.ASM_COMPONENT_TYPE_AND_ELEMENT,
    "composite": E.ASM_COMPOSITE_TYPE_AND_ELEMENT,
})

#: What a URI in ``@promote`` (or ``@target``) may not contain (RFC 3986: no spaces,
#: controls, or the characters URIs exclude).
_NOT_IN_URI = re.compile(r'[\s<>"{}|\\^`]|[\x00-\x1f\x7f]')


def did_you_mean(word: str, known: Iterable[str]) -> str:
    """" (did you mean 'x'?)" when ``word`` looks like a misspelling of one of ``known``, else ""."""
    close = difflib.get_close_matches(word, list(known), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


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
        # opened without blocking (a FIFO would wait for a writer forever), checked on the open file
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(fd, "rb") as fh:
            info = os.fstat(fd)
            if not stat.S_ISREG(info.st_mode):
                problems.append(Problem(E.SCART_XML, "not a regular file (a composite is read from a file)", path, 0))
                return None
            if info.st_size > max_bytes:
                problems.append(Problem(E.SCART_UNSAFE_XML, f"file is {info.st_size} bytes, over the {max_bytes} "
                                        "bytes bound", path, 0))
                return None
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        problems.append(Problem(E.SCART_XML, f"cannot read {path}: {exc.strerror or exc}", path, 0))
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


def _text(el: etree._Element) -> str:
    """The text of a simple ``<value>`` (stripped); "" for one with child elements."""
    return "" if len(el) else (el.text or "").strip()


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

    def append_unique(self, items: list[N], item: N, code: str, what: str, el: etree._Element) -> None:
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

    def load_component_type(self) -> ComponentTypeFile | None:
        """Parse the file as a componentType side file; None if it cannot be read at all."""
        root = parse_xml(self.path, self.problems)
        if root is None:
            return None
        ns, name = _local(root)
        if ns not in SCA_NAMESPACES or name != "componentType":
            self.problem(E.SCART_UNKNOWN_ELEMENT, f"root element must be an SCA <componentType>, not <{name}>", root)
            return None
        self.check_attributes(root, "componentType")
        ct = ComponentTypeFile(loc=self.loc(root))
        for child in root.iterchildren(tag=etree.Element):
            ns, local = _local(child)
            if ns in SCA_NAMESPACES and local == "service":
                self.check_attributes(child, "componentType service")
                iface, b, cb = self._port_children(child, "service")
                self.no_service_uri(b, f"service {child.get('name', '')!r}")
                self.append_unique(ct.services, ComponentService(
                    name=self.required(child, "name") or "", interface=iface, bindings=b, callback_bindings=cb,
                    loc=self.loc(child)), E.ASM_CT_DUPLICATE_SERVICE, "componentType: duplicate service", child)
            elif ns in SCA_NAMESPACES and local == "reference":
                self.check_attributes(child, "componentType reference")
                iface, b, cb = self._port_children(child, "reference")
                ref = ComponentReference(name=self.required(child, "name") or "", multiplicity=self.multiplicity(child),
                                         interface=iface, bindings=b, callback_bindings=cb, loc=self.loc(child))
                if child.get("autowire") is not None:
                    ref.autowire = self.boolean(child, "autowire")
                self.append_unique(ct.references, ref, E.ASM_CT_DUPLICATE_REFERENCE,
                                   "componentType: duplicate reference", child)
            elif ns in SCA_NAMESPACES and local == "property":
                self.append_unique(ct.properties, self.read_property(child, "componentType"),
                                   E.ASM_CT_DUPLICATE_PROPERTY, "componentType: duplicate property", child)
            elif local not in _IGNORED and not local.startswith("implementation."):
                self.unknown(child, "componentType", ("service", "reference", "property"))
        return ct

    # --- composite and its children ----------------------------------------------------

    def read_composite(self, el: etree._Element) -> Composite:
        """``<composite name targetNamespace autowire>`` and its children, via the dispatch table."""
        self._tns = el.get("targetNamespace", "")
        self.check_attributes(el, "composite")
        comp = Composite(
            name=self.required(el, "name") or "", target_namespace=self._tns,
            autowire=self.boolean(el, "autowire"), local=self.boolean(el, "local"), loc=self.loc(el),
        )
        for child in el.iterchildren(tag=etree.Element):
            ns, local = _local(child)
            if ns in SCA_NAMESPACES and local in COMPOSITE_CHILDREN:
                COMPOSITE_CHILDREN[local](self, child, comp)
            elif ns not in SCA_NAMESPACES and self.is_element(local):
                if ns != SCART_NS or self.validate_scart(child):  # scart's own: the shipped XSD too
                    comp.extensions.append(self.read_element(child))
            elif local not in _IGNORED:
                self.unknown(child, "composite", COMPOSITE_CHILDREN if ns in SCA_NAMESPACES else
                             _scart_composite_children() if ns == SCART_NS else ())
        return comp

    def unknown(self, el: etree._Element, parent: str, known: Iterable[str]) -> None:
        """Report an element that may not stand inside ``parent`` (a near miss of ``known`` named)."""
        ns, local = _local(el)
        if local == "operation" and ns in SCA_NAMESPACES:
            self.problem(E.ASM_SCHEMA, f"<operation> inside <{parent}> is SCA 1.0; SCA 1.1 has no such element "
                         "(declare operations in the interface)", el)
            return
        sca = ns in SCA_NAMESPACES  # then the SCA schema forbids it; elsewhere, no extension reads it
        self.problem(E.ASM_SCHEMA if sca else E.SCART_UNKNOWN_ELEMENT, f"unknown element <{local}> "
                     f"{'' if sca else f'in {ns!r} '}inside <{parent}>{did_you_mean(local, known)}", el)

    def check_attributes(self, el: etree._Element, what: str) -> None:
        """Report each attribute without a namespace that ``ATTRIBUTES[what]`` does not allow."""
        allowed = ATTRIBUTES[what]
        for attr in el.attrib:
            if not attr.startswith("{") and attr not in allowed:
                self.problem(E.ASM_SCHEMA, f"<{_local(el)[1]}> has no attribute {attr!r}"
                             f"{did_you_mean(attr, allowed)}", el)

    def boolean(self, el: etree._Element, attr: str, default: bool = False) -> bool:
        """An xs:boolean attribute (true/false/1/0); anything else is reported and read as ``default``."""
        value = el.get(attr)
        if value is None:
            return default
        if value.strip() not in ("true", "false", "1", "0"):
            self.problem(E.ASM_SCHEMA, f"<{_local(el)[1]}> @{attr} must be true or false, not {value!r}", el)
            return default
        return value.strip() in ("true", "1")

    def promote(self, el: etree._Element, many: bool) -> list[str]:
        """``@promote``: one anyURI (a composite service) or a space-separated list of them
        (a composite reference), each "Component[/name]"; problems say ``promote``."""
        raw = self.required(el, "promote")
        if raw is None:
            return [""]
        uris = raw.split()
        what = f"<{_local(el)[1]} name={el.get('name', '')!r}>"
        if not many and len(uris) > 1:
            self.problem(E.ASM_PROMOTED_SERVICE, f"{what}: @promote {raw!r} must be one URI "
                         "'Component/Service', not a list", el)
        for uri in uris:
            bad = _NOT_IN_URI.search(uri)
            if bad or uri.startswith("/") or uri.count("/") > 2:
                code = E.ASM_PROMOTED_REFERENCE if many else E.ASM_PROMOTED_SERVICE
                self.problem(code, f"{what}: @promote {uri!r} is not a valid URI 'Component/"
                             f"{'reference' if many else 'Service'}'", el)
        return uris if many else uris[:1]

    def multiplicity(self, el: etree._Element) -> str | None:
        """@multiplicity, one of 0..1, 1..1, 0..n, 1..n (anything else reported, read as absent)."""
        value = el.get("multiplicity")
        if value is not None and value not in MULTIPLICITIES:
            self.problem(E.ASM_SCHEMA, f"<{_local(el)[1]}> @multiplicity {value!r} is not one of "
                         f"{', '.join(MULTIPLICITIES)}", el)
            return None
        return value

    def required(self, el: etree._Element, attr: str) -> str | None:
        """The attribute's value, or None after recording a schema problem."""
        value = el.get(attr)
        if value is None or not value.strip():
            self.problem(E.ASM_SCHEMA, f"<{_local(el)[1]}> needs a {attr!r} attribute", el)
            return None
        return value.strip()

    def read_component(self, el: etree._Element, parent: Composite) -> None:
        """``<component>``: implementation, services, references, properties."""
        before = len(self.problems)
        self.check_attributes(el, "component")
        comp = Component(name=self.required(el, "name") or "", loc=self.loc(el))
        if el.get("autowire") is not None:
            comp.autowire = self.boolean(el, "autowire")
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
                comp.properties.append(self.read_property(child, "component"))
            elif local not in _IGNORED:
                self.unknown(child, "component", ("service", "reference", "property", "implementation.composite"))
        if comp.implementation is None:
            self.problem(E.ASM_SCHEMA, f"component {comp.name!r} has no implementation", el)
        comp.misread = any(p.code in (E.SCART_UNKNOWN_ELEMENT, E.ASM_SCHEMA) for p in self.problems[before:])
        parent.components.append(comp)

    def read_implementation(self, el: etree._Element) -> Implementation:
        """Any ``implementation.*``; ``implementation.composite`` is resolved by QName."""
        ns, local = _local(el)
        impl = Implementation(kind=local, namespace=ns, attributes=dict(el.attrib), loc=self.loc(el))
        if ns == SCART_NS and not self.validate_scart(el):
            impl.invalid = True  # reported; nothing is imported for it
        if local == "implementation.composite":
            self.check_attributes(el, "implementation.composite")
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
        if ns in SCA_NAMESPACES and local in ATTRIBUTES:
            self.check_attributes(el, local)
        target = el.get("interface") or el.get("class") or ""
        if not target and not invalid:
            self.problem(E.ASM_SCHEMA, f"<{local}> needs an 'interface' attribute", el)
        remotable = el.get("remotable")
        return Interface(kind=local, target=target, callback=el.get("callbackInterface"),
                         remotable=self.boolean(el, "remotable") if remotable is not None else None,
                         invalid=invalid or not target, loc=self.loc(el))

    def read_binding(self, el: etree._Element) -> Binding:
        """Any ``binding.*``: kind, attributes and children kept for the binding's factory."""
        ns, local = _local(el)
        if ns == SCART_NS:
            self.validate_scart(el)
        elif ns in SCA_NAMESPACES and local in ATTRIBUTES:
            self.check_attributes(el, local)
            for child in el.iterchildren(tag=etree.Element):  # other namespaces: open content (1.1 Binding)
                child_ns, child_local = _local(child)
                if (child_ns in SCA_NAMESPACES and child_local not in _IGNORED
                        and not child_local.startswith(("wireFormat", "operationSelector"))):
                    self.unknown(child, local, ())
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
        iface: Interface | None = None
        bindings: list[Binding] = []
        cb_bindings: list[Binding] = []
        for child in el.iterchildren(tag=etree.Element):
            ns, local = _local(child)
            if local.startswith("interface."):
                iface = self.read_interface(child)
            elif local.startswith("binding."):
                bindings.append(self.read_binding(child))
            elif ns in SCA_NAMESPACES and local == "callback":
                self.check_attributes(child, "callback")
                cb_bindings.extend(self.read_binding(c) for c in child.iterchildren(tag=etree.Element)
                                   if _local(c)[1].startswith("binding."))
            elif local not in _IGNORED:
                self.unknown(child, what, ("interface.wsdl", "interface.java", "binding.sca", "callback"))
        for group in (bindings, cb_bindings):
            seen: set[str] = set()
            for b in group:
                name = b.name or b.kind  # a binding without @name is named after its kind
                if name in seen:
                    self.problems.append(Problem(E.ASM_DUPLICATE_BINDING, f"<{what} name={el.get('name', '')!r}>: two "
                                                 f"bindings named {name!r} (give each a distinct @name)",
                                                 b.loc.path, b.loc.line))
                seen.add(name)
        return iface, bindings, cb_bindings

    def no_service_uri(self, bindings: list[Binding], what: str) -> None:
        """A ``binding.sca`` of a service names no @uri (a service's URI is its component's)."""
        for b in bindings:
            if b.kind == "binding.sca" and b.namespace in SCA_NAMESPACES and "uri" in b.attributes:
                self.problems.append(Problem(E.ASM_SCA_BINDING_SERVICE_URI, f"{what}: <binding.sca> on a service "
                                             f"must not have @uri ({b.attributes['uri']!r}); a service's URI is "
                                             "given by its component", b.loc.path, b.loc.line))

    def read_component_service(self, el: etree._Element) -> ComponentService:
        """A component's ``<service name>``."""
        self.check_attributes(el, "component service")
        iface, b, cb = self._port_children(el, "service")
        service = ComponentService(name=self.required(el, "name") or "", interface=iface, bindings=b,
                                   callback_bindings=cb, loc=self.loc(el))
        self.no_service_uri(b, f"service {service.name!r}")
        return service

    def read_component_reference(self, el: etree._Element) -> ComponentReference:
        """A component's ``<reference name target multiplicity autowire>``."""
        self.check_attributes(el, "component reference")
        iface, b, cb = self._port_children(el, "reference")
        ref = ComponentReference(
            name=self.required(el, "name") or "", targets=(el.get("target") or "").split(),
            multiplicity=self.multiplicity(el), non_overridable=self.boolean(el, "nonOverridable"),
            interface=iface, bindings=b, callback_bindings=cb, loc=self.loc(el),
        )
        if el.get("autowire") is not None:
            ref.autowire = self.boolean(el, "autowire")
        return ref

    def read_property(self, el: etree._Element, where: str) -> PropertyValue:
        """``<property>`` (of a ``where``: "component", "composite" or "componentType") with
        ``@value``, ``<value>`` children (simple text or complex content), global elements
        (``@element``), text, ``@file`` or ``@source``."""
        self.check_attributes(el, "property")
        name = self.required(el, "name") or ""
        declared_type, element = self.type_qname(el, "type"), self.type_qname(el, "element")
        if declared_type is not None and element is not None:
            self.problem(TYPE_AND_ELEMENT[where], f"property {name!r} has both @type and @element: declare one", el)
        shown = f"property {name!r} ({el.get('type') or el.get('element') or 'untyped'})"
        values: list[str] | None = None
        xml: list[str] | None = None
        if el.get("value") is not None:
            values = [el.get("value") or ""]
        children = [c for c in el.iterchildren(tag=etree.Element) if _local(c)[1] not in _IGNORED]
        if element is not None:  # the values are instances of the global element
            given = []
            for c in children:
                if etree.QName(c).text == element:
                    given.append(c)
                elif _local(c) == (SCA11_NS, "value"):  # <value> standing for one: its content and attributes
                    given.append(_renamed(c, element))
                else:
                    self.problem(E.ASM_PROPERTY_VALUE, f"{shown}: <{_local(c)[1]}> is not its element "
                                 f"<{etree.QName(element).localname}>", c)
        elif _local(el)[0] == SCA10_NS and children and all(_local(c)[0] not in SCA_NAMESPACES for c in children):
            # SCA 1.0: a complex value is the property's own content, without a <value> wrapper
            wrapper = etree.Element(f"{{{SCA10_NS}}}value", nsmap={k: v for k, v in el.nsmap.items() if k})
            for c in children:
                wrapper.append(copy.deepcopy(c))
            given = [wrapper]
        else:
            given = [c for c in children if _local(c) in ((SCA11_NS, "value"), (SCA10_NS, "value"))]
            for c in children:
                if c not in given:
                    self.unknown(c, "property", ("value",))
        if given:
            if values is not None:
                self.problem(E.ASM_VALUE_AND_CHILD, f"{shown} has both @value and a <value> child: give one", el)
            values = [_text(c) for c in given]
            if element is not None or any(len(c) for c in given):
                xml = [etree.tostring(c, encoding="unicode", with_tail=False) for c in given]
        elif values is None and el.text and el.text.strip():
            values = [el.text.strip()]
        return PropertyValue(
            name=name, values=values, xml=xml, file=el.get("file"), source=el.get("source"),
            namespaces={k: v for k, v in el.nsmap.items() if k}, type=declared_type, element=element,
            many=self.boolean(el, "many"), must_supply=self.boolean(el, "mustSupply"), loc=self.loc(el),
        )

    def type_qname(self, el: etree._Element, attr: str) -> str | None:
        """An optional QName attribute (``@type``, ``@element``) as a Clark QName; a prefix
        not in scope is reported (None then)."""
        raw = el.get(attr)
        if raw is None:
            return None
        prefix, _, local = raw.strip().rpartition(":")
        ns = el.nsmap.get(prefix or None)
        if prefix and ns is None:
            if prefix not in ("xs", "xsd"):  # the customary XML Schema prefixes are understood undeclared
                self.problem(E.ASM_SCHEMA, f"@{attr} {raw!r}: unknown namespace prefix {prefix!r}", el)
                return None
            ns = XSD_NS
        return f"{{{ns or ''}}}{local}"

    def read_composite_property(self, el: etree._Element, parent: Composite) -> None:
        """A composite-level ``<property>`` (flows to components through ``source="$name"``)."""
        prop = self.read_property(el, "composite")
        if any(p.name == prop.name for p in parent.properties):
            self.problem(E.ASM_DUPLICATE_COMPOSITE_PROPERTY, f"duplicate composite property {prop.name!r}", el)
        parent.properties.append(prop)

    def read_composite_service(self, el: etree._Element, parent: Composite) -> None:
        """A composite ``<service name promote>``."""
        self.check_attributes(el, "composite service")
        iface, b, _ = self._port_children(el, "service")
        service = CompositeService(
            name=self.required(el, "name") or "", promote=self.promote(el, many=False)[0],
            interface=iface, bindings=b, loc=self.loc(el))
        self.no_service_uri(b, f"composite service {service.name!r}")
        self.append_unique(parent.services, service, E.ASM_DUPLICATE_COMPOSITE_SERVICE,
                           "duplicate composite service", el)

    def read_composite_reference(self, el: etree._Element, parent: Composite) -> None:
        """A composite ``<reference name promote target multiplicity>``."""
        self.check_attributes(el, "composite reference")
        iface, b, _ = self._port_children(el, "reference")
        reference = CompositeReference(
            name=self.required(el, "name") or "", promote=self.promote(el, many=True),
            targets=(el.get("target") or "").split(), multiplicity=self.multiplicity(el),
            interface=iface, bindings=b, loc=self.loc(el))
        self.append_unique(parent.references, reference, E.ASM_DUPLICATE_COMPOSITE_REFERENCE,
                           "duplicate composite reference", el)

    def read_wire(self, el: etree._Element, parent: Composite) -> None:
        """``<wire source target replace>``."""
        self.check_attributes(el, "wire")
        parent.wires.append(Wire(source=self.required(el, "source") or "", target=self.required(el, "target") or "",
                                 replace=self.boolean(el, "replace"), loc=self.loc(el)))

    def read_include(self, el: etree._Element, parent: Composite) -> None:
        """``<include name="QName">``: the included composite's content is merged in place
        (a ``local="true"`` composite only into another local one)."""
        self.check_attributes(el, "include")
        qname = self.qname(el, "name")
        if qname is None:
            return
        loc = self.loc(el)
        parent.includes.append(Include(name=qname, loc=loc))
        included = self.resolve_composite(qname, loc)
        if included is None:
            self.problem(E.ASM_INCLUDE_UNKNOWN, f"include names no composite {qname} in the contribution", el)
            return
        if included.local and not parent.local:
            self.problem(E.ASM_INCLUDE_LOCAL, f"include of {qname}: it is local=\"true\", so it can only be "
                         f"included into a local composite; {parent.name!r} is not", el)
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
        local = _local(el)[1]
        said: set[str] = set()
        for entry in schema.error_log:  # the first word on each attribute (a list type says it twice)
            attribute = re.search(r"attribute '([^']+)'", entry.message)
            key = attribute[1] if attribute else entry.message
            if key not in said:
                said.add(key)
                self.problem(E.SCART_SCHEMA, f"<scart:{local}>: {_schema_message(entry.message, local)}", el)
        return False


@functools.cache
def _scart_elements() -> tuple[str, ...]:
    """The global elements the shipped XSD declares."""
    root = etree.parse(str(_SCHEMA_PATH), _parser()).getroot()
    return tuple(e.get("name", "") for e in root.iterchildren(f"{{{XSD_NS}}}element"))


def _scart_composite_children() -> tuple[str, ...]:
    """The elements of scart's namespace that stand inside ``<composite>`` (what a typo of
    one is compared with: ``<scart:conect>`` is near ``connect``, never ``component``)."""
    return tuple(e for e in _scart_elements() if not e.startswith(("implementation.", "interface.", "binding.")))


@functools.cache
def _scart_attributes(local: str) -> tuple[str, ...]:
    """The attributes the shipped XSD declares for its element ``local``."""
    root = etree.parse(str(_SCHEMA_PATH), _parser()).getroot()
    for e in root.iterchildren(f"{{{XSD_NS}}}element"):
        if e.get("name") == local:
            return tuple(a.get("name", "") for a in e.iter(f"{{{XSD_NS}}}attribute"))
    return ()


_SCHEMA_MESSAGES: tuple[tuple[re.Pattern[str], Callable[[re.Match[str], str], str]], ...] = (
    (re.compile(r"No matching global declaration available for the validation root"),
     lambda m, local: f"scart has no element <scart:{local}>{did_you_mean(local, _scart_elements())}"),
    (re.compile(r"The attribute '([^']*)' is not allowed"),
     lambda m, local: f"no attribute {m[1]!r}{did_you_mean(m[1], _scart_attributes(local))}"),
    (re.compile(r"Element '[^']*': The attribute '([^']*)' is required but missing"),
     lambda m, local: f"needs the attribute {m[1]!r}"),
    (re.compile(r"Element '[^']*', attribute '([^']*)': \[facet 'pattern'\] The value '([^']*)' is not accepted"),
     lambda m, local: f"@{m[1]} {m[2]!r} is not of the expected form"
                      + (" 'package.module:Class'" if m[1] in ("class", "interface", "callbackInterface") else "")),
    (re.compile(r"Element '[^']*', attribute '([^']*)': '([^']*)' is not a valid value of the atomic type '([^']*)'"),
     lambda m, local: f"@{m[1]} {m[2]!r} is not a valid {m[3].replace('xs:', '')}"),
)


def _schema_message(message: str, local: str) -> str:
    """A schema validator's message in the user's terms (what they wrote, what is expected)."""
    message = re.sub(r"\{urn:scart:1\.0\}", "scart:", message)
    for pattern, say in _SCHEMA_MESSAGES:
        m = pattern.search(message)
        if m is not None:
            return say(m, local)
    return message.rstrip(".")


def _renamed(el: etree._Element, tag: str) -> etree._Element:
    """A copy of ``el`` named ``tag`` (Clark), its attributes, content and every namespace
    in its scope kept (a QName in an attribute value still resolves)."""
    renamed = etree.Element(tag, dict(el.attrib), nsmap=el.nsmap)
    renamed.text = el.text
    for child in el:
        renamed.append(copy.deepcopy(child))
    return renamed


def _detached(el: etree._Element) -> etree._Element:
    """A copy of ``el`` to validate alone, its prefixes still in scope (QName attributes such
    as ``@requires`` resolve)."""
    copy = etree.Element(el.tag, dict(el.attrib), nsmap={**{k: v for k, v in el.nsmap.items() if k}, None: SCART_NS})
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
