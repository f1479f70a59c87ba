"""Operations: task methods callable by name, introspectable (RTT ``addOperation``).

``@operation`` marks a method; ``@operation(own_thread=True)`` makes calls run in the
task's activity thread (RTT's ``OwnThread``), queued and executed between cycles, the
caller blocking until the result is ready. By default (``ClientThread``) they run in the
caller's thread. See :mod:`dataflow.activities` for when no thread exists.
"""

from __future__ import annotations

import inspect
import typing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar, overload

from .introspection import OperationDescription
from scart_wire.types import registry

__all__ = ["operation", "OperationSpec"]

F = TypeVar("F", bound=Callable[..., Any])
_MARK = "__dataflow_operation__"


@dataclass(frozen=True)
class OperationSpec:
    """How an operation was declared."""

    own_thread: bool = False


@overload
def operation(fn: F) -> F: ...
@overload
def operation(*, own_thread: bool = False) -> Callable[[F], F]: ...


def operation(fn: F | None = None, *, own_thread: bool = False) -> F | Callable[[F], F]:
    """Declare a TaskContext method an operation (``@operation`` or ``@operation(own_thread=True)``)."""

    def mark(f: F) -> F:
        setattr(f, _MARK, OperationSpec(own_thread))
        return f

    return mark(fn) if fn is not None else mark


def spec_of(fn: object) -> OperationSpec | None:
    """The OperationSpec of a declared operation, or None."""
    return getattr(fn, _MARK, None)


def _name_of(tp: object) -> str:
    if tp is None or tp is type(None):
        return "None"
    if tp is inspect.Parameter.empty:
        return "any"
    return registry.type_name(tp)


def describe_operation(name: str, fn: Callable[..., object], spec: OperationSpec) -> OperationDescription:
    """An OperationDescription with params, return type and signature ``name(a: float64) -> None``."""
    try:
        hints = typing.get_type_hints(fn)
    except Exception:  # unresolvable forward refs: fall back to raw annotations
        hints = dict(getattr(fn, "__annotations__", {}))
    sig = inspect.signature(fn)
    params = [
        (p.name, _name_of(hints.get(p.name, p.annotation)))
        for p in sig.parameters.values()
        if p.name != "self"
    ]
    returns = _name_of(hints.get("return", sig.return_annotation))
    text = ", ".join(f"{n}: {t}" for n, t in params)
    return OperationDescription(
        name=name,
        params=params,
        returns=returns,
        doc=inspect.getdoc(fn) or "",
        own_thread=spec.own_thread,
        signature=f"{name}({text}) -> {returns}",
    )
