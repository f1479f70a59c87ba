"""XML Schema types and elements for property values (SCA Assembly 1.1 §4.4, §5.4).

A :class:`SchemaSet` holds the ``.xsd`` files of the contributions a composite sees, plus
the XML Schema built-in types and the SCA namespace's own schemas, shipped in the package
(``scart/schema/sca-core.xsd``, ``sca-policy.xsd``, ``sca-contribution.xsd``: ``sca:Callback``,
``sca:callback``, ``sca:Multiplicity``...). It answers what a ``@type`` or ``@element`` QName names
and checks a value against it with lxml's validator: a ``@type`` value is validated as
an element of that type, an ``@element`` value as an instance of that global element.

Loading is safe and closed: the files are parsed with :func:`scart.scdl.parse_xml` (size
bound, no DOCTYPE), and an ``xs:import``/``xs:include`` is served only from those files
(by name) — never from the network or elsewhere on disk.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Sequence
from pathlib import Path

from lxml import etree

from scart.errors import Problem
from scart.model import SCA11_NS

__all__ = ["XSD_NS", "SchemaSet", "builtin_simple"]

XSD_NS = "http://www.w3.org/2001/XMLSchema"
_CHECK_NS = "urn:scart:check"  # the namespace of the wrapper element a @type value is checked as
_SCHEMA_DIR = Path(__file__).with_name("schema")
#: The SCA 1.1 namespace's schemas shipped with scart (one namespace, included together).
SCA_SCHEMAS = ("sca-core.xsd", "sca-policy.xsd", "sca-contribution.xsd")

#: XML Schema built-in simple types (Part 2, §3): what ``xs:NAME`` may name besides anyType.
_BUILTINS = frozenset("""
    string normalizedString token language Name NCName ID IDREF IDREFS ENTITY ENTITIES NMTOKEN NMTOKENS QName
    NOTATION anyURI boolean float double decimal integer nonPositiveInteger negativeInteger long int short byte
    nonNegativeInteger unsignedLong unsignedInt unsignedShort unsignedByte positiveInteger duration dateTime time
    date gYearMonth gYear gMonthDay gDay gMonth hexBinary base64Binary anySimpleType
""".split())


def builtin_simple(qname: str) -> bool:
    """Is ``qname`` (Clark) an XML Schema built-in simple type?"""
    return qname.startswith(f"{{{XSD_NS}}}") and qname.partition("}")[2] in _BUILTINS


class _Resolver(etree.Resolver):
    """Serves schema documents from the set's own files only (by file name)."""

    def __init__(self, files: dict[str, bytes]) -> None:
        super().__init__()
        self.files = files

    def resolve(self, url: str, pubid: str, context: object) -> object:
        data = self.files.get(url.rpartition("/")[2].rpartition(":")[2])
        if data is None:
            raise OSError(f"schema {url!r} is not in the contribution (nothing is fetched from elsewhere)")
        return self.resolve_string(data, context, base_url=url)


class SchemaSet:
    """The schemas a composite's property values are checked against (see the module
    docstring). Problems reading a file go to ``problems``. Not thread-safe."""

    def __init__(self, files: Sequence[Path], problems: list[Problem]) -> None:
        from scart.scdl import parse_xml

        self._data: dict[str, bytes] = {name: (_SCHEMA_DIR / name).read_bytes() for name in SCA_SCHEMAS}
        self._by_ns: dict[str, list[str]] = {SCA11_NS: list(SCA_SCHEMAS)}
        self.types: dict[str, str] = {}  # Clark QName -> "simple" | "complex"
        self.elements: set[str] = set()
        roots = [(name, etree.fromstring(self._data[name])) for name in SCA_SCHEMAS]
        pending: list[tuple[str, str, str]] = []  # (namespace, stored name, file name)
        included: set[str] = set()  # file names another schema includes: loaded through it, not again
        seen: set[bytes] = set()
        for file in files:
            root = parse_xml(str(file), problems)
            if root is None:
                continue
            if etree.QName(root).text != f"{{{XSD_NS}}}schema":
                continue
            data = file.read_bytes() if file.stat().st_size <= (8 << 20) else b""
            if data in seen:  # the same schema in two contributions: declared once
                continue
            seen.add(data)
            name = f"f{len(self._data)}-{file.name}"
            self._data[name] = data
            self._data.setdefault(file.name, self._data[name])  # what another schema's schemaLocation names
            pending.append((root.get("targetNamespace", ""), name, file.name))
            included |= {str(el.get("schemaLocation", "")).rpartition("/")[2]
                         for el in root.iterchildren(f"{{{XSD_NS}}}include", f"{{{XSD_NS}}}redefine")}
            roots.append((name, root))
        for ns, name, file_name in pending:
            if file_name not in included:
                self._by_ns.setdefault(ns, []).append(name)
        self.element_types: dict[str, str] = {}  # global element -> its named type (anonymous ones absent)
        self.bases: dict[str, str] = {}  # complex type -> the type it extends or restricts
        for _, root in roots:
            self._index(root)

    def _index(self, root: etree._Element) -> None:
        """Record the global types and elements a schema document declares."""
        tns = root.get("targetNamespace", "")
        for child in root.iterchildren(tag=etree.Element):
            local, name = etree.QName(child).localname, child.get("name")
            if name is None:
                continue
            qname = f"{{{tns}}}{name}"
            if local == "simpleType":
                self.types[qname] = "simple"
            elif local == "complexType":
                self.types[qname] = "complex"
                derived = child.find(f"{{{XSD_NS}}}complexContent/*[@base]")
                if derived is not None:
                    self.bases[qname] = _resolve(derived, derived.get("base", ""))
            elif local == "element":
                self.elements.add(qname)
                if child.get("type"):
                    self.element_types[qname] = _resolve(child, child.get("type", ""))

    def derives(self, qname: str, base: str) -> bool:
        """Is the complex type ``qname`` ``base`` or derived from it (by extension or restriction)?"""
        for _ in range(32):  # bounded: a chain of bases (a cycle is the schema's own error)
            if qname == base:
                return True
            if qname not in self.bases:
                return False
            qname = self.bases[qname]
        return False

    def kind(self, qname: str) -> str | None:
        """"simple", "complex" or None (no such type) for a type's Clark QName."""
        if builtin_simple(qname):
            return "simple"
        if qname == f"{{{XSD_NS}}}anyType":
            return "complex"
        return self.types.get(qname)

    def check_type(self, value: etree._Element, qname: str) -> str | None:
        """Why ``value`` (a ``<value>`` element: its text and children) is not a valid
        ``qname``, or None when it is."""
        # the value's namespace declarations stay in scope: an xs:QName's prefix resolves
        wrapper = etree.Element(f"{{{_CHECK_NS}}}value",
                                nsmap={**{k: v for k, v in value.nsmap.items() if k}, None: _CHECK_NS})
        wrapper.text = value.text
        for name, attribute in value.attrib.items():  # a complex type's attributes (requires="..." on sca:Callback)
            wrapper.set(name, attribute)
        for child in value:
            wrapper.append(_copy(child))
        return self._validate(self._schema(("type", qname)), wrapper)

    def check_element(self, value: etree._Element) -> str | None:
        """Why ``value`` is not a valid instance of its global element, or None."""
        return self._validate(self._schema(("element", etree.QName(value).namespace or "")), _copy(value))

    @functools.cache  # noqa: B019 - one per set, and the set lives as long as its load
    def _schema(self, key: tuple[str, str]) -> etree.XMLSchema | str:
        """A schema importing every namespace of the set; for a type, it also declares the
        wrapper element of that type. The error text when it cannot be built."""
        prefixes = {ns: f"n{i}" for i, ns in enumerate(self._by_ns)}
        imports = "".join('<xs:import' + (f' namespace="{ns}"' if ns else "") +
                          f' schemaLocation="scart-ns:{prefixes[ns]}"/>' for ns in self._by_ns)
        declare = ""
        if key[0] == "type":
            ns, _, local = key[1][1:].partition("}")
            prefix = "xs:" if ns == XSD_NS else (f"{prefixes.get(ns, 'missing')}:" if ns else "")
            declare = f'<xs:element name="value" type="{prefix}{local}"/>'
        xmlns = "".join(f' xmlns:{p}="{ns}"' for ns, p in prefixes.items() if ns)
        text = (f'<xs:schema xmlns:xs="{XSD_NS}"{xmlns} targetNamespace="{_CHECK_NS}" '
                f'elementFormDefault="qualified">{imports}{declare}</xs:schema>')
        files = dict(self._data)
        for ns, prefix in prefixes.items():  # one document per namespace including its files
            includes = "".join(f'<xs:include schemaLocation="scart-file:{name}"/>' for name in self._by_ns[ns])
            files[prefix] = (f'<xs:schema xmlns:xs="{XSD_NS}" targetNamespace="{ns}">{includes}</xs:schema>'
                             if ns else f'<xs:schema xmlns:xs="{XSD_NS}">{includes}</xs:schema>').encode()
        parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
        parser.resolvers.add(_Resolver(files))
        try:
            return etree.XMLSchema(etree.fromstring(text.encode(), parser))
        except (etree.XMLSchemaParseError, etree.XMLSyntaxError) as exc:
            error = exc.error_log.last_error if exc.error_log else None
            file = re.sub(r"^scart-(?:file|ns):(?:f\d+-)?", "", error.filename or "") if error is not None else ""
            where = f"{file}:{error.line}: " if file and not file.startswith("n") and error is not None else ""
            return f"the contribution's XML Schemas cannot be used: {where}{_tidy(str(exc))}"

    @staticmethod
    def _validate(schema: etree.XMLSchema | str, doc: etree._Element) -> str | None:
        if isinstance(schema, str):
            return schema
        if schema.validate(doc):
            return None
        return _tidy(schema.error_log[0].message) if schema.error_log else "not valid"


def _resolve(el: etree._Element, qname: str) -> str:
    """A QName attribute value of ``el`` as a Clark QName (its prefix in ``el``'s scope)."""
    prefix, _, local = qname.strip().rpartition(":")
    return f"{{{el.nsmap.get(prefix or None, '') or ''}}}{local}"


def _copy(el: etree._Element) -> etree._Element:
    """A detached deep copy (keeps the namespaces the element uses)."""
    return etree.fromstring(etree.tostring(el))


def _tidy(message: str) -> str:
    """A validator message without namespace noise: ``{urn:x}name`` becomes ``name``."""
    return re.sub(r"\{[^}'\"\s,]*[:/][^}'\"\s,]*\}", "", message).strip()  # a namespace URI, not '{...}' text
