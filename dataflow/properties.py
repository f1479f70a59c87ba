"""Typed, documented, validated task properties (RTT ``Property<T>``).

Declared on a TaskContext class: ``gain = Property(float, 1.0, doc="...", ge=0.0, le=10.0)``;
then ``task.gain`` reads the task's value and ``task.gain = x`` validates ``x`` with
pydantic (lax mode: ``"2"`` → ``2.0`` for a float) and stores it, or raises
:class:`~dataflow.errors.PortTypeError` (wrong type) /
:class:`~dataflow.errors.PropertyValueError` (out of its bounds, or rejected by
``check``), naming ``task.property``. A number (or a list of numbers) must be finite
unless ``finite=False`` (see :mod:`scart_wire.bounds`). Reads and writes are single
reference operations: thread-safe.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, TypeVar, overload

import pydantic

from scart_wire.bounds import Bounds, bounded_adapter, unknown_field
from .errors import PortTypeError, PropertyValueError
from scart_wire.types import registry

if TYPE_CHECKING:
    from .task import TaskContext

__all__ = ["Property", "BoundProperty"]

T = TypeVar("T")
_TYPE_ERRORS = ("_type", "_parsing", "model_attributes_type", "is_instance_of")


class Property(Generic[T]):
    """A task property: type, default value, doc, optional ``check(value)`` raising
    ValueError, and bounds (``ge``/``gt``/``le``/``lt``, ``finite``; see :mod:`scart_wire.bounds`).
    Raises ``ValueError`` for bounds that cannot hold or a default outside them."""

    def __init__(
        self,
        type: Any,
        default: T,
        doc: str = "",
        check: Callable[[T], None] | None = None,
        *,
        ge: float | None = None,
        gt: float | None = None,
        le: float | None = None,
        lt: float | None = None,
        finite: bool | None = None,
    ) -> None:
        self.type = type
        self.doc = doc
        self.check = check
        self.name = ""
        self.bounds: Bounds | None = Bounds.of(type, ge, gt, le, lt, finite)
        # one adapter per type (and bounds), cached
        self._adapter: pydantic.TypeAdapter[T] = (
            bounded_adapter(type, self.bounds) if self.bounds is not None else registry._adapter(type))
        self.default = self._adapter.validate_python(default)

    @property
    def type_name(self) -> str:
        """Registry name of the property's type."""
        return registry.type_name(self.type)

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @overload
    def __get__(self, obj: None, owner: type | None = None) -> Property[T]: ...
    @overload
    def __get__(self, obj: TaskContext, owner: type | None = None) -> T: ...

    def __get__(self, obj: TaskContext | None, owner: type | None = None) -> Property[T] | T:
        if obj is None:
            return self
        value: T = obj._prop_values[self.name]
        return value

    def __set__(self, obj: TaskContext, value: object) -> None:
        obj._prop_values[self.name] = self.validate(value, getattr(obj, "name", "?"))

    def validate(self, value: object, task_name: str = "?") -> T:
        """Coerce ``value`` to the property's type and run ``check``; raises as the module says."""
        where = f"{task_name}.{self.name}"
        said = unknown_field(self.type, value)
        if said is not None:
            raise PortTypeError(f"{where}: invalid value for {self.type_name}: unknown field {said}")
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

    def __init__(self, task: TaskContext, prop: Property[Any]) -> None:
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
    def default(self) -> object:
        return self.prop.default

    @property
    def value(self) -> object:
        """The current value."""
        return self.task._prop_values[self.prop.name]

    def set(self, value: object) -> None:
        """Validate and store ``value`` (raises like ``Property.validate``)."""
        setattr(self.task, self.prop.name, value)

    def __repr__(self) -> str:
        return f"<Property {self.task.name}.{self.name}: {self.type_name} = {self.value!r}>"
