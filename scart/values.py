"""Property values: raw XML text to typed Python values.

``parse_value(["3"], int) == 3``; ``bool`` takes true/false/1/0; ``list[T]`` parses each
value as ``T`` (one value starting with "[" is read as a JSON array); any other type
(dicts, pydantic models...) is read as JSON and validated by pydantic. A complex XML value
(an :class:`XmlValue`: a ``<value>`` with child elements, or a global element) becomes
data first — each child element a key, repeated ones a list, attributes keys too, a leaf
its text — and is then validated the same way (a ``str`` property gets the XML itself).
"""

from __future__ import annotations

import functools
import json
import typing
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, TypeAlias

from lxml import etree
from pydantic import TypeAdapter, ValidationError

if TYPE_CHECKING:
    from typing_extensions import TypeForm

#: XSD simple types of composite-level ``<property type="xsd:...">`` and their Python types.
XSD_TYPES: MappingProxyType[str, type] = MappingProxyType({
    "string": str, "anyURI": str, "QName": str, "int": int, "integer": int, "long": int, "short": int,
    "double": float, "float": float, "decimal": float, "boolean": bool,
})


#: An XML element as plain data: its stripped text, or its attributes and child elements
#: by local name (a repeated child: a list).
XmlData: TypeAlias = "str | dict[str, XmlData | list[XmlData]]"


class XmlValue(str):
    """A complex property value: the XML of its ``<value>`` (or global element) element."""

    def element(self) -> etree._Element:
        """The value parsed (it was serialized from an already-parsed, safe document)."""
        parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
        return etree.fromstring(self.encode(), parser)

    def data(self) -> XmlData:
        """The value as plain data (see the module docstring); for a ``<value>`` wrapper,
        its content."""
        return xml_data(self.element())


def xml_data(el: etree._Element) -> XmlData:
    """Plain data of an element: a dict of its attributes and child elements (by local name;
    repeated children: a list), or its stripped text when it has neither."""
    children = [c for c in el if isinstance(c.tag, str)]
    attrs = {etree.QName(k).localname: v for k, v in el.attrib.items() if not k.startswith("{")}
    if not children and not attrs:
        return (el.text or "").strip()
    grouped: dict[str, list[XmlData]] = {}
    for child in children:
        grouped.setdefault(etree.QName(child).localname, []).append(xml_data(child))
    return {**attrs, **{k: v[0] if len(v) == 1 else v for k, v in grouped.items()}}


def is_many(py_type: object) -> bool:
    """True for many-valued property types (``list[T]``, ``tuple[...]``, ``set[T]``)."""
    return typing.get_origin(py_type) in (list, tuple, set)


@functools.lru_cache(maxsize=512)
def _adapter(py_type: TypeForm[object]) -> TypeAdapter[object]:
    return TypeAdapter(py_type)


def parse_value(raw: list[str], py_type: Any) -> object:  # Any: a type form, called when int or float
    """Parse raw text values as ``py_type``: ``bool`` takes true/false/1/0, ``list[T]`` parses
    each value as T (one value starting with "[" is read as JSON), other non-primitive types
    are read as JSON and validated by pydantic. Raises ``ValueError`` with a clear message."""
    if is_many(py_type):
        args = typing.get_args(py_type)
        item = args[0] if args else str
        if len(raw) == 1 and not isinstance(raw[0], XmlValue) and raw[0].lstrip().startswith("["):
            return _adapt(py_type, json.loads(raw[0]))
        return typing.get_origin(py_type)(parse_value([v], item) for v in raw)
    text = raw[0] if raw else ""
    if isinstance(text, XmlValue):
        return str(text) if py_type is str or py_type is Any else _adapt(py_type, text.data())
    if py_type is bool:
        low = text.strip().lower()
        if low in ("true", "1"):
            return True
        if low in ("false", "0"):
            return False
        raise ValueError(f"{text!r} is not a boolean (true/false/1/0)")
    if py_type is str or py_type is Any:
        return text
    if py_type in (int, float):
        try:
            return py_type(text.strip())
        except ValueError:
            raise ValueError(f"{text!r} is not a valid {py_type.__name__}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        data = text
    return _adapt(py_type, data)


def _adapt(py_type: object, data: object) -> object:
    adapter = _adapter(py_type)
    try:
        return adapter.validate_python(data)
    except ValidationError as exc:  # one line: the first problem, where it is, and how many more
        errors = exc.errors()
        first = errors[0] if errors else {"loc": (), "msg": str(exc)}
        where = ".".join(str(part) for part in first["loc"])
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        why = f"{where + ': ' if where else ''}{first['msg']}{more}"
    except Exception as exc:  # noqa: BLE001 - a validator of the user's model may raise anything
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    shown = repr(data)
    shown = shown if len(shown) <= 80 else shown[:77] + "..."
    raise ValueError(f"{shown} is not a valid {getattr(py_type, '__name__', py_type)}: {why}")
