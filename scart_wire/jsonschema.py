"""Samples as JSON messages with a JSON Schema of their port's type: what MCAP files
(``scart record``) and the Foxglove app (``scart foxglove``) carry. Part of the wire layer:
it knows the type registry and arrays, nothing of either world."""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

if TYPE_CHECKING:
    import numpy as np
    from pydantic import JsonValue
    from typing_extensions import TypeForm

__all__ = ["message_of", "message_schema", "schema_name", "type_schema"]


def type_schema(type_name: str) -> dict[str, JsonValue]:
    """The JSON Schema of a registry type (pydantic's; ``{"title": name}``, any JSON, when
    this process does not know the type or pydantic cannot describe it)."""
    import pydantic

    from scart_wire.types import registry

    py_type = registry.python_type(type_name)
    if py_type is None:
        return {"title": type_name}
    try:
        return pydantic.TypeAdapter(cast("TypeForm[object]", py_type)).json_schema()
    except Exception:  # noqa: BLE001 - a type pydantic cannot describe: any JSON
        return {"title": type_name}


def schema_name(type_name: str) -> str:
    """The name of a type's schema in MCAP files and the Foxglove app: an image array's is
    ``foxglove.RawImage`` (the image panel shows it), any other type's its own name."""
    from scart_wire.arrays import RAW_IMAGE, array_spec

    spec = array_spec(type_name)
    return RAW_IMAGE if spec is not None and spec.image else type_name


def message_schema(type_name: str) -> dict[str, JsonValue]:
    """A message's JSON Schema: the type's, a non-object wrapped as ``{"value": ...}``
    (Foxglove wants objects); ``{"title": name}`` for a type unknown here; an array's,
    what :func:`message_of` makes of it."""
    from scart_wire.types import registry
    from scart_wire.arrays import array_spec

    spec = array_spec(type_name)
    if spec is not None:
        return _ARRAY_SCHEMA(type_name, image=spec.image is not None)
    schema = type_schema(type_name)
    if registry.python_type(type_name) is not None and schema.get("type") != "object":
        schema = {"title": type_name, "type": "object", "properties": {"value": schema}}
    return schema


def message_of(value: object) -> dict[str, object]:
    """A sample as a JSON message: its JSON form, a non-object wrapped as ``{"value": ...}``
    (the shape :func:`message_schema` describes)."""
    from scart_wire.types import registry

    kind = type(value)
    if kind.__name__ == "ndarray" and kind.__module__ == "numpy":  # an image or a cloud: base64, not a list
        from scart_wire.arrays import to_message

        return to_message(cast("np.ndarray", value))
    data = registry.to_jsonable(value)
    return data if isinstance(data, dict) else {"value": data}


def _ARRAY_SCHEMA(type_name: str, image: bool) -> dict[str, JsonValue]:  # noqa: N802 - a schema maker
    """The JSON Schema of an array's message (:func:`~scart_wire.arrays.to_message`)."""
    data: JsonValue = {"type": "string", "contentEncoding": "base64"}
    if image:
        stamp: JsonValue = {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}}
        return {"title": "foxglove.RawImage", "description": type_name, "type": "object",
                "properties": {"timestamp": stamp, "frame_id": {"type": "string"}, "width": {"type": "integer"},
                               "height": {"type": "integer"}, "encoding": {"type": "string"},
                               "step": {"type": "integer"}, "data": data}}
    return {"title": type_name, "type": "object", "properties": {
        "shape": {"type": "array", "items": {"type": "integer"}}, "dtype": {"type": "string"}, "data": data}}
