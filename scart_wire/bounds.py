"""Ranges and finiteness of values that come from outside: properties, input ports written
remotely, and operation arguments called remotely.

``Property(float, 0.01, ge=0.001, le=1.0)`` and ``InputPort(float, ge=0.0, le=1.0)``
declare a :class:`Bounds` (limits apply to numbers and lists of numbers). Every number in
a value from outside must also be finite unless ``finite=False`` — a float, the items of
a list or tuple, an ``Optional[float]``, the fields of a pydantic model, the values of a
dict — so a NaN or an infinite set-point is refused before it reaches the task. Operation
parameters declare limits with ``typing.Annotated[float, pydantic.Field(ge=0.0)]`` and
are held finite the same way (``Field(allow_inf_nan=True)`` lets NaN and inf through).
Operation arguments from outside go through one check, :func:`check_argument`, whatever
the entry (the data-flow path, Foxglove, binding.grpc and the services endpoint): the
declared type with numbers strict (``"0.5"`` and ``true`` are no float), the bounds,
finiteness; every entry refuses a value with the same message. A field a model does not
declare is refused too (:func:`refuse_unknown_fields`): pydantic would drop it silently,
so ``{x: 1, y: 2, z: 3}`` written to a port of ``{x, y}`` would "succeed" without ``z``.
The check walks the value once (linear in its size, which the transport bounds). What a
task writes to its own output ports is not checked here (the hot path stays free of
it): bounds are for what crosses in.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types
import typing
from dataclasses import dataclass
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Any, TypeVar, cast

import pydantic

from . import rosmsgs
from .errors import PortTypeError, PortValueError

if TYPE_CHECKING:
    from typing_extensions import TypeForm

__all__ = ["Bounds", "argument_adapter", "bounded_adapter", "check_argument", "from_outside", "nesting_depth",
           "non_finite", "refuse_unknown_fields", "unknown_field"]

T = TypeVar("T")

_NUMBERS = (float, int)
_ATOMS = (int, bool, str, bytes, type(None))


def non_finite(value: object) -> float | None:
    """The first NaN or infinite number found anywhere in ``value`` (floats, complex
    numbers, lists, tuples, sets, dict values, pydantic models, dataclasses), else None."""
    stack: list[Any] = [value]  # any data, walked by exact type (no isinstance on the common kinds)
    while stack:
        v = stack.pop()
        kind = type(v)
        if kind is float:
            if v - v != 0.0:  # NaN and +-inf (cheaper than math.isfinite in this loop)
                return v
        elif kind in _ATOMS:
            continue
        elif kind is list or kind is tuple or isinstance(v, (list, tuple, set, frozenset)):
            stack.extend(v)
        elif isinstance(v, dict):
            stack.extend(v.values())
        elif isinstance(v, float):
            if not math.isfinite(v):
                return float(v)
        elif isinstance(v, complex):
            if not (math.isfinite(v.real) and math.isfinite(v.imag)):
                return v.real if not math.isfinite(v.real) else v.imag
        elif isinstance(v, pydantic.BaseModel):
            stack.extend(v.__dict__.values())
        elif dataclasses.is_dataclass(v) and not isinstance(v, type):
            stack.extend(getattr(v, f.name) for f in dataclasses.fields(v))
    return None


def _all_finite(value: T) -> T:
    bad = non_finite(value)
    if bad is not None:
        raise ValueError(f"{bad} is not a finite number")
    return value


#: A pydantic validator refusing a value that holds a NaN or an infinite number.
FINITE = pydantic.AfterValidator(_all_finite)


@functools.lru_cache(maxsize=1024)
def _may_hold_floats(hint: object, depth: int = 0) -> bool:
    """Can a value of ``hint`` hold a float (so that finiteness applies)?"""
    if depth > 8:
        return True
    if hint in (float, complex, Any, object) or isinstance(hint, typing.TypeVar):
        return True
    if hint in _ATOMS or hint is type(None):
        return False
    origin = typing.get_origin(hint)
    if origin is Annotated:
        return _may_hold_floats(typing.get_args(hint)[0], depth + 1)
    if origin is not None:
        return any(_may_hold_floats(a, depth + 1) for a in typing.get_args(hint) if a is not Ellipsis) \
            or not typing.get_args(hint)
    if isinstance(hint, type):
        if rosmsgs.is_message_class(hint):  # ROS's own: a NaN means what ROS says (an invalid point), as in arrays
            return False
        if issubclass(hint, pydantic.BaseModel):
            annotations: list[object] = [f.annotation for f in hint.model_fields.values()]  # any type form
            return any(_may_hold_floats(a, depth + 1) for a in annotations)
        if dataclasses.is_dataclass(hint):
            try:
                hints = typing.get_type_hints(hint)
            except Exception:
                return True
            return any(_may_hold_floats(h, depth + 1) for h in hints.values())
        return issubclass(hint, (float, complex, list, tuple, set, frozenset, dict))
    return False


def _allows_inf_nan(hint: object) -> bool:
    """Does an ``Annotated`` hint say ``allow_inf_nan=True`` (pydantic ``Field``)?"""
    if typing.get_origin(hint) is not Annotated:
        return False
    for meta in typing.get_args(hint)[1:]:
        for item in (meta, *getattr(meta, "metadata", ())):
            if getattr(item, "allow_inf_nan", None) is True:
                return True
    return False


def from_outside(hint: object) -> object:
    """The annotation to check a value of ``hint`` from outside with: ``hint`` itself, held
    finite when it can hold floats (unless its ``Field`` allows inf and NaN)."""
    try:
        if not _may_hold_floats(hint) or _allows_inf_nan(hint):
            return hint
    except TypeError:  # unhashable annotation: not cached, checked as is
        return hint
    return Annotated[hint, FINITE]


@dataclass(frozen=True)
class Bounds:
    """Lower and upper limits (inclusive ``ge``/``le``, exclusive ``gt``/``lt``) and
    whether numbers must be finite. Hashable (a cache key)."""

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    finite: bool = True

    @classmethod
    def of(cls, py_type: object, ge: float | None = None, gt: float | None = None, le: float | None = None,
           lt: float | None = None, finite: bool | None = None) -> Bounds | None:
        """The bounds of a value of ``py_type`` (None when nothing applies: not a number nor a
        list of numbers, and no limit given). Raises ``ValueError`` for limits that cannot
        hold (not finite, or lower above upper) or limits on a type without numbers."""
        limits = {k: v for k, v in (("ge", ge), ("gt", gt), ("le", le), ("lt", lt)) if v is not None}
        for key, value in limits.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"{key}={value!r}: a finite number")
        low = max((v for k, v in limits.items() if k in ("ge", "gt")), default=-math.inf)
        high = min((v for k, v in limits.items() if k in ("le", "lt")), default=math.inf)
        if low > high:
            raise ValueError(f"no value can satisfy {limits}")
        if _item(py_type) is None:
            if limits:
                raise ValueError(f"ge/gt/le/lt apply to numbers and lists of numbers, not {py_type!r}")
            holds = _may_hold_floats(py_type)
            if finite and not holds:
                raise ValueError(f"finite applies to values that can hold numbers, not {py_type!r}")
            return cls(finite=True) if holds and finite is not False else None
        return cls(ge, gt, le, lt, True if finite is None else finite)

    @property
    def text(self) -> str:
        """``"0.001 <= x <= 1, finite"``: what ``scart describe`` shows."""
        low = f"{self.ge:g} <= " if self.ge is not None else (f"{self.gt:g} < " if self.gt is not None else "")
        high = f" <= {self.le:g}" if self.le is not None else (f" < {self.lt:g}" if self.lt is not None else "")
        parts = [f"{low}x{high}"] if low or high else []
        if self.finite:
            parts.append("finite")
        return ", ".join(parts)


def _item(py_type: object) -> type[float] | type[int] | None:
    """The number type of ``py_type`` (itself, or a list's items), or None."""
    if py_type in _NUMBERS:
        return py_type
    if typing.get_origin(py_type) is list:
        args = typing.get_args(py_type)
        if args and args[0] in _NUMBERS:
            return args[0]
    return None


@functools.lru_cache(maxsize=1024)
def bounded_adapter(py_type: Any, bounds: Bounds) -> pydantic.TypeAdapter[Any]:
    """A pydantic adapter validating a value of ``py_type`` within ``bounds`` (cached)."""
    item = _item(py_type)
    if item is None:  # no limits: only finiteness, anywhere in the value
        return pydantic.TypeAdapter(Annotated[py_type, FINITE] if bounds.finite else py_type)
    field = pydantic.Field(ge=bounds.ge, gt=bounds.gt, le=bounds.le, lt=bounds.lt,
                           allow_inf_nan=not bounds.finite if item is float else None)
    checked: Any = Annotated[item, field]
    return pydantic.TypeAdapter(list[checked] if item is not py_type else checked)


def argument_adapters(fn: Callable[..., object]) -> dict[str, pydantic.TypeAdapter[object]]:
    """For each annotated parameter of ``fn`` pydantic can check, the adapter that checks
    a value from outside (see :func:`argument_adapter`)."""
    return _argument_adapters(getattr(fn, "__func__", fn))


@functools.lru_cache(maxsize=1024)
def _argument_adapters(fn: Callable[..., object]) -> dict[str, pydantic.TypeAdapter[object]]:
    try:
        hints = typing.get_type_hints(fn, include_extras=True)
    except Exception:  # unresolvable annotations: nothing checkable
        return {}
    out: dict[str, pydantic.TypeAdapter[object]] = {}
    for name, hint in hints.items():
        adapter = argument_adapter(hint) if name != "return" else None
        if adapter is not None:
            out[name] = adapter
    return out


def argument_adapter(hint: object) -> pydantic.TypeAdapter[object] | None:
    """The adapter checking an operation argument of type ``hint`` from outside: its type,
    with numbers strict (a string or a bool is no number), its declared bounds, numbers
    finite (:func:`from_outside`). None when there is nothing to check (no annotation,
    ``Any``, a type pydantic cannot check)."""
    if hint is None or hint is Any or hint is object or isinstance(hint, (str, typing.TypeVar)):
        return None
    try:
        return _cached_argument_adapter(hint)
    except TypeError:  # unhashable annotation: made each time
        return _make_argument_adapter(hint)


@functools.lru_cache(maxsize=1024)
def _cached_argument_adapter(hint: object) -> pydantic.TypeAdapter[object] | None:
    return _make_argument_adapter(hint)


def _make_argument_adapter(hint: object) -> pydantic.TypeAdapter[object] | None:
    checked = from_outside(hint)
    try:
        return pydantic.TypeAdapter(cast("TypeForm[object]", _strict_numbers(checked)))  # a type form, as given
    except Exception:  # noqa: BLE001 - a type pydantic cannot check: finiteness alone, where it applies
        return pydantic.TypeAdapter(Annotated[Any, FINITE]) if checked is not hint else None


def _strict_numbers(hint: object, depth: int = 0) -> object:
    """``hint`` with each ``float`` and ``int`` in it (inside ``Annotated``, unions and
    containers) strict: pydantic's lax mode would take ``"0.5"`` or ``true`` as a number."""
    if hint is float or hint is int:
        return Annotated[hint, pydantic.Strict()]
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is None or not args or depth > 8:
        return hint
    if origin is Annotated:
        return Annotated[(_strict_numbers(args[0], depth + 1), *args[1:])]
    new = tuple(a if a is Ellipsis else _strict_numbers(a, depth + 1) for a in args)
    if new == args:
        return hint
    if origin is typing.Union or isinstance(hint, types.UnionType):
        return typing.Union[new]  # noqa: UP007 - rebuilt from a tuple
    if isinstance(hint, types.GenericAlias):
        return types.GenericAlias(origin, new)
    try:
        copy_with: Callable[[tuple[object, ...]], object] = getattr(hint, "copy_with")  # noqa: B009
        return copy_with(new)
    except Exception:  # noqa: BLE001 - a generic we cannot rebuild: as declared
        return hint


_MAX_WALK = 10_000  #: mappings :func:`unknown_field` looks into, at most (the transport bounds the value anyway)


def unknown_field(hint: object, value: object) -> str | None:
    """Where ``value`` (plain data from outside: mappings, lists) names a field that the
    pydantic model it would become does not declare, e.g. ``"pose.z (Pose has: x, y)"``;
    None when every field is known. Follows ``hint`` through models, ``Optional``/unions
    of one model, lists, tuples and ``Annotated``, bounded in depth and work."""
    budget = [_MAX_WALK]
    return _unknown(hint, value, "", 0, budget)


def _unknown(hint: object, value: object, path: str, depth: int, budget: list[int]) -> str | None:
    if depth > 32 or budget[0] <= 0:
        return None
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is Annotated:
        return _unknown(args[0], value, path, depth + 1, budget)
    if origin is typing.Union or isinstance(hint, types.UnionType):
        models = [a for a in args if isinstance(a, type) and issubclass(a, pydantic.BaseModel)]
        return _unknown(models[0], value, path, depth + 1, budget) if len(models) == 1 else None
    if origin in (list, tuple, set, frozenset) and isinstance(value, (list, tuple)):
        item_hint = args[0] if args else Any
        for i, item in enumerate(value):
            said = _unknown(args[i] if origin is tuple and len(args) == len(value) else item_hint, item,
                            f"{path}[{i}]", depth + 1, budget)
            if said is not None:
                return said
        return None
    if not (isinstance(hint, type) and issubclass(hint, pydantic.BaseModel) and isinstance(value, dict)):
        return None
    budget[0] -= 1
    fields = hint.model_fields
    names = {alias for name, f in fields.items() for alias in (name, f.alias) if alias}
    if hint.model_config.get("extra") != "allow":
        for key in value:
            if key not in names:
                from difflib import get_close_matches

                near = get_close_matches(str(key), list(fields), n=1, cutoff=0.6)
                hint_text = f"; did you mean {near[0]!r}?" if near else ""
                return (f"{path + '.' if path else ''}{str(key)[:80]} ({hint.__name__} has: "
                        f"{', '.join(list(fields)[:20])}{hint_text})")
    for name, f in fields.items():
        key = name if name in value else f.alias
        if key in value:
            said = _unknown(f.annotation, value[key], f"{path + '.' if path else ''}{name}", depth + 1, budget)
            if said is not None:
                return said
    return None


def refuse_unknown_fields(where: str, hint: object, value: object) -> None:
    """Raise :class:`~scart_wire.errors.PortTypeError` (``WHERE: unknown field ...``) when
    ``value`` names a field its model does not declare (see :func:`unknown_field`)."""
    said = unknown_field(hint, value)
    if said is not None:
        raise PortTypeError(f"{where}: unknown field {said}")


@typing.overload
def check_argument(where: str, hint: type[T], value: object) -> T: ...
@typing.overload
def check_argument(where: str, hint: object, value: object) -> object: ...
def check_argument(where: str, hint: object, value: object) -> object:
    """The one check of an operation argument from outside, used by every entry (the
    data-flow path and its CLI, Foxglove, binding.grpc, the services endpoint): ``value``
    validated as :func:`argument_adapter` says, returned as converted. Raises
    :class:`~scart_wire.errors.PortTypeError` (not of the declared type) or
    :class:`~scart_wire.errors.PortValueError` (out of bounds, not finite), each saying
    ``WHERE: VALUE refused: REASON`` (``where`` is e.g. ``task.operation(parameter)``)."""
    adapter = argument_adapter(hint)
    if adapter is None:
        return value
    refuse_unknown_fields(where, hint, value)
    try:
        return adapter.validate_python(value)
    except pydantic.ValidationError as exc:
        error = exc.errors()[0]
        kind = PortTypeError if error["type"].endswith(("_type", "_parsing", "_class")) else PortValueError
        raise kind(f"{where}: {value!r:.80} refused: {error['msg']}") from None


def nesting_depth(value: object, limit: int, max_items: int) -> int:
    """How deeply lists and mappings nest in ``value`` (a value typed on a command line, a
    recorded message): iterative, so any depth is safe to measure; stops past ``limit`` + 1
    levels. Raises ``ValueError`` past ``max_items`` items (YAML aliases can make a short
    text a huge or cyclic value)."""
    deepest = 0
    seen = 0
    stack: list[tuple[object, int]] = [(value, 0)]
    while stack:
        item, level = stack.pop()
        seen += 1
        if seen > max_items:
            raise ValueError(f"a value of more than {max_items} items")
        if isinstance(item, dict):
            item = list(item.values())
        if isinstance(item, list):
            level += 1
            deepest = max(deepest, level)
            if level <= limit:
                stack.extend((child, level) for child in item)
    return deepest
