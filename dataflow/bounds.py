"""Ranges and finiteness of values that come from outside: properties, input ports written
remotely, and operation arguments called remotely.

``Property(float, 0.01, ge=0.001, le=1.0)`` and ``InputPort(float, ge=0.0, le=1.0)``
declare a :class:`Bounds`; numbers (``float``, ``int``, and the items of ``list[float]`` /
``list[int]``) are also required to be finite unless ``finite=False``: a NaN or an
infinite set-point is refused before it reaches the task. Operation parameters declare
theirs with ``typing.Annotated[float, pydantic.Field(ge=0.0)]``, and float parameters
are required to be finite too. What a task writes to its own output ports is not
checked here (the hot path stays free of it): bounds are for what crosses in.
"""

from __future__ import annotations

import functools
import math
import typing
from dataclasses import dataclass
from typing import Annotated, Any

import pydantic

__all__ = ["Bounds", "bounded_adapter"]

_NUMBERS = (float, int)


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
    def of(cls, py_type: Any, ge: float | None = None, gt: float | None = None, le: float | None = None,
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
            if limits or finite:
                raise ValueError(f"ge/gt/le/lt/finite apply to numbers and lists of numbers, not {py_type!r}")
            return None
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


def _item(py_type: Any) -> Any:
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
    field = pydantic.Field(ge=bounds.ge, gt=bounds.gt, le=bounds.le, lt=bounds.lt,
                           allow_inf_nan=not bounds.finite if item is float else None)
    checked: Any = Annotated[item, field]  # type: ignore[valid-type]
    return pydantic.TypeAdapter(list[checked] if item is not py_type else checked)


def argument_adapters(fn: Any) -> dict[str, pydantic.TypeAdapter[Any]]:
    """For each parameter of ``fn`` that declares bounds (``Annotated[..., Field(...)]``)
    or is a number (then: finite), the adapter that checks a value from outside."""
    return _argument_adapters(getattr(fn, "__func__", fn))


@functools.lru_cache(maxsize=1024)
def _argument_adapters(fn: Any) -> dict[str, pydantic.TypeAdapter[Any]]:
    try:
        hints = typing.get_type_hints(fn, include_extras=True)
    except Exception:  # unresolvable annotations: nothing checkable
        return {}
    out: dict[str, pydantic.TypeAdapter[Any]] = {}
    for name, hint in hints.items():
        if name == "return":
            continue
        if typing.get_origin(hint) is Annotated:
            out[name] = pydantic.TypeAdapter(hint)
        elif _item(hint) is not None:
            out[name] = bounded_adapter(hint, Bounds())
    return out
