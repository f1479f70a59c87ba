"""Samples as JSON messages with a JSON Schema of their port's type: what MCAP files
(``scart record``) and the Foxglove app (``scart foxglove``) carry."""

from __future__ import annotations

from typing import Any

__all__ = ["message_of", "type_schema"]


def type_schema(type_name: str) -> dict[str, Any]:
    """The JSON Schema of a registry type (pydantic's; ``{"title": name}``, any JSON, when
    this process does not know the type or pydantic cannot describe it)."""
    import pydantic

    from dataflow import registry

    py_type = registry.python_type(type_name)
    if py_type is None:
        return {"title": type_name}
    try:
        return pydantic.TypeAdapter(py_type).json_schema()
    except Exception:  # noqa: BLE001 - a type pydantic cannot describe: any JSON
        return {"title": type_name}


def _schema_of(type_name: str) -> dict[str, Any]:
    """A message's JSON Schema: the type's, a non-object wrapped as ``{"value": ...}``
    (Foxglove wants objects); ``{"title": name}`` for a type unknown here."""
    from dataflow import registry

    schema = type_schema(type_name)
    if registry.python_type(type_name) is not None and schema.get("type") != "object":
        schema = {"title": type_name, "type": "object", "properties": {"value": schema}}
    return schema


def message_of(value: Any) -> dict[str, Any]:
    """A sample as a JSON message: its JSON form, a non-object wrapped as ``{"value": ...}``
    (the shape :func:`_schema_of` describes)."""
    from dataflow import registry

    data = registry.to_jsonable(value)
    return data if isinstance(data, dict) else {"value": data}
