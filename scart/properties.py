"""Property values as a composite gives them (SCA Assembly 1.1, §4.4, §5.4, §6.5), read and
checked before anything starts (private helper of :mod:`scart.assembly`).

* A value is text (``@value``, a ``<value>``, the element's text), complex XML (a
  ``<value>`` with child elements, or instances of the global element ``@element``
  names), a file (``@file``: an ``sca:values`` document, or — scart's extension — plain
  UTF-8 text), or comes from a composite property through ``@source``: ``$name``, or an
  XPath 1.0 expression over it (``$p/ns:child``, ``$p[2]/text()``) evaluated by lxml
  with the property element's namespace declarations, ``$p`` being the sequence of the
  composite property's values (its ``<value>`` elements, or its global elements).
* Declared types are checked: ``@type`` names an XML Schema type — built in, in the SCA
  namespace, or in an ``.xsd`` file of the contributions (ASM40007) — and every value is
  valid for it (ASM50027, ASM50028); ``@element`` names a global element (ASM40008) and
  the values are valid instances of it (ASM50029); not both (ASM40010/50035/60040, at
  reading).
* Types match: a component property's declared type is compatible with its
  componentType's (ASM50036), and a composite property it takes through ``@source``
  with its own (ASM50038). A Python annotation counts as a type (``str``: a string,
  ``int``: an integer, ``float``: a number, ``bool``: a boolean, a model or dict:
  complex); two complex XML types must be one type, or one derived from the other.

A problem never shows a file's content.
"""

from __future__ import annotations

import os
import re
import stat
import typing
from collections.abc import Callable
from pathlib import Path

from lxml import etree

from scart import errors as E
from scart.contribution import Contribution
from scart.model import SCA10_NS, SCA11_NS, Location, PropertyValue
from scart.schemas import XSD_NS, builtin_simple
from scart.scdl import _parser, _prolog_doctype_line
from scart.values import XmlValue

__all__ = ["MAX_PROPERTY_FILE_BYTES", "FileValues", "PropertyReader", "Refused", "TypeRef", "python_family",
           "xml_family"]

#: Largest file a property's ``@file`` may name (bytes).
MAX_PROPERTY_FILE_BYTES = 1 << 20

#: A declared property type: ``("type", "{ns}local")`` or ``("element", "{ns}local")``.
TypeRef = tuple[str, str]

_SOURCE = re.compile(r"\s*\$(?P<name>[A-Za-z_][\w.-]*)(?P<path>.*)", re.S)
_VARIABLE = re.compile(r"\$([A-Za-z_][\w.-]*)")
_VALUE_TAGS = (f"{{{SCA11_NS}}}value", f"{{{SCA10_NS}}}value")
_VALUES_TAGS = (f"{{{SCA11_NS}}}values", f"{{{SCA10_NS}}}values")

_STRINGS = frozenset("string normalizedString token language Name NCName ID IDREF NMTOKEN QName anyURI".split())
_INTEGERS = frozenset("""integer int long short byte nonNegativeInteger nonPositiveInteger negativeInteger
    positiveInteger unsignedLong unsignedInt unsignedShort unsignedByte""".split())
_NUMBERS = frozenset("double float decimal".split())
_ANY_TYPE = f"{{{XSD_NS}}}anyType"


class Refused(list):
    """No value: the property's values were refused (reported already, so nothing more is said)."""


class FileValues(list):
    """Raw values read from a property's ``@file`` (so that errors do not echo them)."""

    def __init__(self, values: list[str], file: str) -> None:
        super().__init__(values)
        self.file = file


def xml_family(ref: TypeRef | None, kinds: Callable[[str], str | None]) -> str | None:
    """The family of a declared XML type, for compatibility: "string", "integer",
    "number", "boolean", "complex", or None (another simple type, or unknown: compatible
    with anything)."""
    if ref is None:
        return None
    what, qname = ref
    if what == "element":
        return "complex"
    local = qname.partition("}")[2]
    if builtin_simple(qname):
        if local in _STRINGS:
            return "string"
        if local in _INTEGERS:
            return "integer"
        if local in _NUMBERS:
            return "number"
        return "boolean" if local == "boolean" else None  # dates, binary...: whatever a string may hold
    return "complex" if kinds(qname) == "complex" else None  # a simple type of its own: its base is not known


def python_family(py_type: object) -> str | None:
    """The family of a Python annotation (see :func:`xml_family`); a list's is its items'."""
    origin = typing.get_origin(py_type)
    if origin in (list, tuple, set):
        args = [a for a in typing.get_args(py_type) if a is not Ellipsis]
        return python_family(args[0]) if len(set(args)) == 1 else None
    if origin is typing.Union or type(py_type).__name__ == "UnionType":
        args = [a for a in typing.get_args(py_type) if a is not type(None)]
        return python_family(args[0]) if len(args) == 1 else None
    if py_type is bool:
        return "boolean"
    if py_type is int:
        return "integer"
    if py_type is float:
        return "number"
    if py_type is str:
        return "string"
    if py_type is dict or origin is dict or (isinstance(py_type, type) and hasattr(py_type, "model_fields")):
        return "complex"
    return None


def compatible(a: str | None, b: str | None) -> bool:
    """Can values of family ``a`` stand where ``b`` is declared (and back)? Unknown is compatible."""
    if a is None or b is None or a == b:
        return True
    return {a, b} == {"integer", "number"}


class PropertyReader:
    """Reads raw property values and checks them (see the module docstring); problems go
    through ``problem(code, message, loc)``."""

    def __init__(self, contribution: Contribution, problem: Callable[[str, str, Location], None]) -> None:
        self.contribution = contribution
        self.problems_seen: list[str] = []

        def report(code: str, message: str, loc: Location) -> None:
            self.problems_seen.append(code)
            problem(code, message, loc)
        self.problem = report

    # --- types --------------------------------------------------------------------------

    @staticmethod
    def declared(p: PropertyValue) -> TypeRef | None:
        """The property's own ``@type`` or ``@element`` (``@element`` first: it is the stricter)."""
        if p.element is not None:
            return ("element", p.element)
        return ("type", p.type) if p.type is not None else None

    def family(self, ref: TypeRef | None) -> str | None:
        """:func:`xml_family` of ``ref`` in the contributions' schemas."""
        if ref is None or (ref[0] == "type" and builtin_simple(ref[1])):
            return xml_family(ref, lambda q: None)
        return xml_family(ref, self.contribution.schemas.kind)

    def complex_type(self, ref: TypeRef | None) -> str | None:
        """The complex type a declaration stands for: a complex ``@type`` itself, an
        ``@element``'s named type (the element itself when its type is anonymous); None
        for a simple or unknown type."""
        if ref is None:
            return None
        what, qname = ref
        schemas = self.contribution.schemas
        if what == "element":
            return schemas.element_types.get(qname, qname)
        return qname if schemas.kind(qname) == "complex" else None

    def agree(self, a: TypeRef | None, b: TypeRef | None) -> bool:
        """Can values declared ``a`` stand where ``b`` is declared? Their families are
        compatible, and two complex XML types are one type, or one derives from the other
        (``xs:anyType`` takes anything)."""
        if not compatible(self.family(a), self.family(b)):
            return False
        ta, tb = self.complex_type(a), self.complex_type(b)
        if ta is None or tb is None or _ANY_TYPE in (ta, tb):
            return True
        schemas = self.contribution.schemas
        return schemas.derives(ta, tb) or schemas.derives(tb, ta)

    @staticmethod
    def shown(ref: TypeRef | None, namespaces: dict[str, str] | None = None) -> str:
        """``xs:int``, ``geo:Point`` (a prefix of ``namespaces``, as the user wrote it),
        ``{urn:x}Point`` when no prefix is known... for messages."""
        if ref is None:
            return "untyped"
        ns, _, local = ref[1][1:].partition("}")
        prefix = next((k for k, v in (namespaces or {}).items() if v == ns and k), None)
        text = (f"xs:{local}" if ns == XSD_NS else f"sca:{local}" if ns == SCA11_NS
                else f"{prefix}:{local}" if prefix else ref[1])
        return text if ref[0] == "type" else f"element {text}"

    # --- raw values -------------------------------------------------------------------

    def raw(self, p: PropertyValue, ctx: dict[str, list[str] | None]) -> list[str] | None:
        """The raw values of ``p`` (complex ones as :class:`~scart.values.XmlValue`), taking
        ``@source`` from the composite's properties ``ctx``; checked against ``p``'s own
        declared type. None when it gives none (or it is wrong: reported)."""
        if p.source is not None:
            return self.source(p, ctx)
        if p.file is not None:
            values = self.file(p)
        elif p.xml is not None:
            values = [XmlValue(x) for x in p.xml]
        else:
            values = p.values
        if values is not None and not isinstance(values, Refused) and not self.check(p, values):
            return Refused()
        return values

    def check(self, p: PropertyValue, values: list[str]) -> bool:
        """Each value of ``p`` against its declared ``@type`` or ``@element``; False when one
        is not valid (reported)."""
        before = len(self.problems_seen)
        self._check(p, values)
        return len(self.problems_seen) == before

    def _check(self, p: PropertyValue, values: list[str]) -> None:
        ref = self.declared(p)
        if ref is None:
            return
        schemas = self.contribution.schemas
        where = f"property {p.name!r} ({self.shown(ref, p.namespaces)})"
        if ref[0] == "type":
            kind = schemas.kind(ref[1])
            if kind is None:
                self.problem(E.ASM_PROPERTY_TYPE, f"{where}: @type names no XML Schema type (built in, sca:, or in "
                             "an .xsd file of the contributions)", p.loc)
                return
            if kind == "complex" and p.values is not None and p.xml is None and p.file is None and values:
                self.problem(E.ASM_PROPERTY_VALUE, f"{where}: a complex type takes <value> elements, not text "
                             "or @value", p.loc)
                return
            for value in values:
                element = value.element() if isinstance(value, XmlValue) else _text_value(value, p.namespaces)
                why = schemas.check_type(element, ref[1])
                if why is not None:
                    self.problem(E.ASM_PROPERTY_VALUE, f"{where}: {_shown_value(value, values, why)}", p.loc)
            return
        if ref[1] not in schemas.elements:
            self.problem(E.ASM_PROPERTY_ELEMENT, f"{where}: @element names no global element of an .xsd file of "
                         "the contributions", p.loc)
            return
        for value in values:
            element = value.element() if isinstance(value, XmlValue) else None
            if element is None or etree.QName(element).text != ref[1]:
                self.problem(E.ASM_ELEMENT_VALUE, f"{where}: each value must be an <{etree.QName(ref[1]).localname}> "
                             "element", p.loc)
                continue
            why = schemas.check_element(element)
            if why is not None:
                self.problem(E.ASM_ELEMENT_VALUE, f"{where}: {_shown_value(value, values, why)}", p.loc)

    # --- @source ------------------------------------------------------------------------

    def source(self, p: PropertyValue, ctx: dict[str, list[str] | None]) -> list[str] | None:
        """``$name`` (the composite property's values) or an XPath over the composite's
        properties (see the module docstring)."""
        m = _SOURCE.fullmatch(p.source or "")
        names = set(_VARIABLE.findall(p.source or ""))
        unknown = sorted(names - set(ctx))
        if not names or unknown:
            self.problem(E.SCART_BAD_SOURCE, f"property {p.name!r}: @source {p.source!r} names no composite "
                         f"property{f' {unknown[0]!r}' if unknown else ''}; known: "
                         f"{', '.join('$' + k for k in ctx) or 'none'}", p.loc)
            return None
        if m is not None and not m["path"].strip():
            return ctx[m["name"]]
        if any(isinstance(ctx[k], Refused) for k in names):
            return Refused()  # what it is taken from was refused (reported): nothing more to say
        files = [vs.file for k in sorted(names) if isinstance(vs := ctx[k], FileValues)]
        try:
            xpath = etree.XPath(p.source or "", namespaces=p.namespaces)
            variables = {k: [_node(v) for v in (vs or [])] for k, vs in ctx.items() if _SOURCE.fullmatch(f"${k}")}
            result = xpath(etree.Element("context"), **variables)
        except (etree.XPathSyntaxError, etree.XPathEvalError) as exc:
            self.problem(E.SCART_BAD_SOURCE, f"property {p.name!r}: @source {p.source!r} is not a valid XPath "
                         f"over the composite's properties: {exc}", p.loc)
            return None
        values: list[str] = []
        if isinstance(result, bool):
            result = ["true" if result else "false"]
        elif isinstance(result, float):
            result = [str(int(result)) if result.is_integer() else repr(result)]
        elif isinstance(result, str):
            result = [str(result)]
        for item in result:
            if isinstance(item, etree._Element):
                values.append(XmlValue(etree.tostring(item, encoding="unicode", with_tail=False)) if len(item)
                              else (item.text or "").strip())
            else:
                values.append(str(item).strip())
        if files and values:  # taken from a file: its content is never shown either
            return FileValues(values, files[0])
        return values or None

    # --- @file --------------------------------------------------------------------------

    def file(self, p: PropertyValue) -> list[str] | None:
        """The values in ``@file``: a regular file inside the contribution folder with no
        other hard link, at most :data:`MAX_PROPERTY_FILE_BYTES`; an ``sca:values`` document (ASM50046), or plain
        UTF-8 text (one value). Problems never show its content."""
        folder = self.contribution.folder_of(p.loc.path).path
        where = f"property {p.name!r}: file {p.file!r}"
        try:
            path = (Path(p.loc.path).parent / (p.file or "")).resolve()
            if not path.is_relative_to(folder):
                self.problem(E.ASM_PROPERTY_FILE, f"{where} is outside the contribution folder {folder}", p.loc)
                return None
            # opened without following a link and without blocking (a FIFO swapped in after the
            # check above must not hang), then checked on the open file itself
            fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
            with os.fdopen(fd, "rb") as fh:
                info = os.fstat(fd)
                if not stat.S_ISREG(info.st_mode):
                    self.problem(E.ASM_PROPERTY_FILE, f"{where} is not a regular file", p.loc)
                    return None
                if info.st_nlink > 1:  # another name of it may be any file outside the folder
                    self.problem(E.ASM_PROPERTY_FILE, f"{where} has {info.st_nlink} hard links: a hard link can "
                                 "make a file outside the contribution look inside it; use a plain copy", p.loc)
                    return None
                if info.st_size > MAX_PROPERTY_FILE_BYTES:
                    self.problem(E.ASM_PROPERTY_FILE, f"{where} is {info.st_size} bytes, over the "
                                 f"{MAX_PROPERTY_FILE_BYTES} bytes bound", p.loc)
                    return None
                data = fh.read(MAX_PROPERTY_FILE_BYTES + 1)[:MAX_PROPERTY_FILE_BYTES]
        except OSError as exc:
            self.problem(E.ASM_PROPERTY_FILE, f"{where}: cannot read: {exc.strerror or exc}", p.loc)
            return None
        if data.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"<"):
            return self._values_document(p, data, where)
        try:
            return FileValues([data.decode("utf-8").strip()], p.file or "")
        except UnicodeDecodeError:
            self.problem(E.ASM_PROPERTY_FILE, f"{where} is not UTF-8 text", p.loc)
            return None

    def _values_document(self, p: PropertyValue, data: bytes, where: str) -> list[str] | None:
        if _prolog_doctype_line(data) is not None:
            self.problem(E.SCART_UNSAFE_XML, f"{where}: DOCTYPE/ENTITY declarations are refused", p.loc)
            return None
        try:
            root = etree.fromstring(data, _parser())
        except etree.XMLSyntaxError as exc:
            self.problem(E.ASM_PROPERTY_FILE_FORMAT, f"{where} is not well-formed XML (line {exc.lineno})", p.loc)
            return None
        if root.tag not in _VALUES_TAGS:
            self.problem(E.ASM_PROPERTY_FILE_FORMAT, f"{where}: the document must be an <sca:values> of <value> "
                         f"elements (or global elements), not <{etree.QName(root).localname}>", p.loc)
            return None
        children = [c for c in root if isinstance(c.tag, str)]
        if any(c.tag in _VALUE_TAGS for c in children) and any(c.tag not in _VALUE_TAGS for c in children):
            self.problem(E.ASM_PROPERTY_FILE_FORMAT, f"{where}: <sca:values> holds either <value> elements or "
                         "global elements, not both", p.loc)
            return None
        if not children:
            self.problem(E.ASM_PROPERTY_FILE_FORMAT, f"{where}: <sca:values> holds no value", p.loc)
            return None
        # a global element is a value of the property's @type (its content checked) or an instance of its @element
        values = [XmlValue(etree.tostring(c, encoding="unicode", with_tail=False)) if len(c) or p.element
                  else (c.text or "").strip() for c in children]
        return FileValues(values, p.file or "")


def _text_value(text: str, nsmap: dict[str, str] | None = None) -> etree._Element:
    """A ``<value>`` holding ``text``, in scope of the namespace declarations ``nsmap``
    (an ``xs:QName`` value's prefix resolves as in the composite)."""
    value = etree.Element(f"{{{SCA11_NS}}}value", nsmap={k: v for k, v in (nsmap or {}).items() if k})
    value.text = text
    return value


def _node(value: str) -> etree._Element:
    """A value as an XPath node: its element, or a ``<value>`` holding its text."""
    return value.element() if isinstance(value, XmlValue) else _text_value(value)


def _shown_value(value: str, values: list[str], why: str) -> str:
    """Why a value is not valid: the validator's words, naming the value — except for a
    file's, whose content is never shown (the validator's words may quote it)."""
    if isinstance(values, FileValues):
        return f"a value in file {values.file!r} is not valid for this type (content not shown)"
    if isinstance(value, XmlValue):
        return f"value <{etree.QName(value.element()).localname}> is not valid: {why}"
    return f"value {value[:60]!r} is not valid: {why}"
