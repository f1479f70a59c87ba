"""Typed, documented, validated task properties (RTT ``Property<T>``).

Declared on a TaskContext class: ``gain = Property(float, 1.0, doc="...")``; then
``task.gain`` reads the task's value and ``task.gain = x`` validates ``x`` with pydantic
(lax mode: ``"2"`` → ``2.0`` for a float) and stores it, or raises
:class:`~dataflow.errors.PortTypeError` (wrong type) /
:class:`~dataflow.errors.PropertyValueError` (rejected by ``check``), naming
``task.property``. Reads and writes are single reference operations: thread-safe.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Generic, TypeVar

import pydantic

from .errors import PortTypeError, PropertyValueError
from .types import registry

__all__ = ["Property", "BoundProperty"]

T = TypeVar("T")
_TYPE_ERRORS = ("_type", "_parsing", "model_attributes_type", "is_instance_of")


class Property(Generic[T]):
    """A task property: type, default value, doc, optional ``check(value)`` raising ValueError."""

    def __init__(
        self,
        type: Any,
        default: T,
        doc: str = "",
        check: Callable[[T], None] | None = None,
    ) -> None:
        self.type = type
        self.doc = doc
        self.check = check
        self.name = ""
        self._adapter: pydantic.TypeAdapter[T] = registry._adapter(type)  # one per type, cached
        self.default = self._adapter.validate_python(default)

    @property
    def type_name(self) -> str:
        """Registry name of the property's type."""
        return registry.type_name(self.type)

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        return obj._prop_values[self.name]

    def __set__(self, obj: Any, value: Any) -> None:
        obj._prop_values[self.name] = self.validate(value, getattr(obj, "name", "?"))

    def validate(self, value: Any, task_name: str = "?") -> T:
        """Coerce ``value`` to the property's type and run ``check``; raises as the module says."""
        where = f"{task_name}.{self.name}"
        try:
            result = self._adapter.validate_python(value)
        except pydantic.ValidationError as exc:
            err = exc.errors()[0]
            msg = f"{where}: invalid value {value!r:.60} for {self.type_name}: {err['msg']}"
            if any(k in err["type"] for k in _TYPE_ERRORS):
                raise PortTypeError(msg) from None
            raise PropertyValueError(msg) from None
        if self.check is not None:
            try:
                self.check(result)
            except ValueError as exc:
                raise PropertyValueError(f"{where}: rejected {value!r:.60}: {exc}") from None
        return result


class BoundProperty:
    """A property of one task: ``.name``, ``.type``, ``.type_name``, ``.doc``, ``.value``, ``.set()``."""

    __slots__ = ("task", "prop")

    def __init__(self, task: Any, prop: Property[Any]) -> None:
        self.task = task
        self.prop = prop

    @property
    def name(self) -> str:
        return self.prop.name

    @property
    def type(self) -> Any:
        return self.prop.type

    @property
    def type_name(self) -> str:
        return self.prop.type_name

    @property
    def doc(self) -> str:
        return self.prop.doc

    @property
    def default(self) -> Any:
        return self.prop.default

    @property
    def value(self) -> Any:
        """The current value."""
        return self.task._prop_values[self.prop.name]

    def set(self, value: Any) -> None:
        """Validate and store ``value`` (raises like ``Property.validate``)."""
        setattr(self.task, self.prop.name, value)

    def __repr__(self) -> str:
        return f"<Property {self.task.name}.{self.name}: {self.type_name} = {self.value!r}>"
