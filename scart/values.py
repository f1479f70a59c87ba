"""Property values: raw XML text to typed Python values.

``parse_value(["3"], int) == 3``; ``bool`` takes true/false/1/0; ``list[T]`` parses each
value as ``T`` (one value starting with "[" is read as a JSON array); any other type
(dicts, pydantic models...) is read as JSON and validated by pydantic.
"""

from __future__ import annotations

import functools
import json
import typing
from types import MappingProxyType
from typing import Any

from pydantic import TypeAdapter

#: XSD simple types of composite-level ``<property type="xsd:...">`` and their Python types.
XSD_TYPES: MappingProxyType[str, type] = MappingProxyType({
    "string": str, "anyURI": str, "QName": str, "int": int, "integer": int, "long": int, "short": int,
    "double": float, "float": float, "decimal": float, "boolean": bool,
})


def is_many(py_type: Any) -> bool:
    """True for many-valued property types (``list[T]``, ``tuple[...]``, ``set[T]``)."""
    return typing.get_origin(py_type) in (list, tuple, set)


@functools.lru_cache(maxsize=512)
def _adapter(py_type: Any) -> TypeAdapter[Any]:
    return TypeAdapter(py_type)


def parse_value(raw: list[str], py_type: Any) -> Any:
    """Parse raw text values as ``py_type``: ``bool`` takes true/false/1/0, ``list[T]`` parses
    each value as T (one value starting with "[" is read as JSON), other non-primitive types
    are read as JSON and validated by pydantic. Raises ``ValueError`` with a clear message."""
    if is_many(py_type):
        args = typing.get_args(py_type)
        item = args[0] if args else str
        if len(raw) == 1 and raw[0].lstrip().startswith("["):
            return _adapt(py_type, json.loads(raw[0]))
        return typing.get_origin(py_type)(parse_value([v], item) for v in raw)
    text = raw[0] if raw else ""
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


def _adapt(py_type: Any, data: Any) -> Any:
    adapter = _adapter(py_type)
    try:
        return adapter.validate_python(data)
    except Exception as exc:
        raise ValueError(f"{data!r} is not a valid {getattr(py_type, '__name__', py_type)}: {exc}") from None
