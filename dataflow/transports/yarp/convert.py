"""A port's type onto a YARP bottle and back, planned once per type and checked when a
stream is made (``scart validate`` asks it at load).

======================================  ======================================================
port type                               bottle (``yarp read`` prints; ``yarp write`` takes)
======================================  ======================================================
``int``, ``float``, ``str``, ``bool``,  one item: ``42``, ``3.5``, ``"two words"``, ``true``,
``bytes``                               ``{1 2 3}`` (a blob)
``list[X]``, ``tuple[X, ...]``          the items: ``0.1 0.2 0.3``; nested lists nest:
                                        ``(1 2) (3 4)``
a pydantic model                        its fields in declaration order, each by these rules
                                        (a nested model or a list is a nested list), as YARP's
                                        IDL structs are: ``((0.1 0.0 1.2 25.0 0 0.1) ...) 12.5 7``
======================================  ======================================================

Numbers widen, never narrow: an int is taken where a float is wanted, a float is refused
where an int is. A vocab is taken where a string is wanted (its text), and ``true``,
``false``, 1 and 0 where a bool is. A bottle of another shape — a missing or extra item,
a list where a number is wanted — is refused whole, naming the item; nothing is passed on
half-decoded. ``Optional`` fields, dicts and unions have no bottle form: refused at load.
"""

from __future__ import annotations

import types
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, TypeGuard

import pydantic

from scart_yarp.bottle import Item, Vocab

__all__ = ["Conversion", "Unfit", "item_reader", "plan"]

#: A value of the port's type as one bottle item.
Out = Callable[[Any], Item]  # Any: the value as its converter reads it (a list, a model...)
#: One bottle item as a value of the port's type (raises :class:`Unfit`).
In = Callable[[Item], object]


class Unfit(ValueError):
    """A bottle that does not fit the port's type (refused and counted)."""


@dataclass(frozen=True)
class Conversion:
    """How one port type crosses: ``to_bottle(value) -> list`` (the items of the bottle),
    ``from_bottle(items) -> value`` (raises :class:`Unfit`), and the shape in words."""

    to_bottle: Callable[[Any], list[Item]]
    from_bottle: Callable[[list[Item]], object]
    shape: str
    #: For a bottle of one scalar item: what makes that item (``to_bottle`` is then
    #: ``lambda v: [one(v)]``; a writer calls it itself, one call less per sample).
    one: Callable[[Any], Any] | None = None


def plan(py_type: object) -> tuple[Conversion | None, list[str]]:
    """The conversion of ``py_type``, or None and the problems found (each naming the field)."""
    try:
        if _is_model(py_type):
            out, inp, shape = _model(py_type, py_type.__name__)
            return Conversion(out, inp, shape), []
        item = _item_type(py_type)
        if item is not None:
            each_out, each_in, shape = _convert(item, "")
            return Conversion(lambda v: [each_out(x) for x in v], _list_in(each_in, "the bottle"),
                              f"{shape} ..."), []
        if py_type in _SCALARS:  # the commonest: one number or string, read with one call
            one_out, one_in, shape = _SCALARS[py_type]
            return Conversion(lambda v: [one_out(v)], _single(one_in, "the value"), shape, one_out), []
        one_out, one_in, shape = _convert(py_type, "the value")
        return Conversion(lambda v: [one_out(v)], _single(one_in), shape), []
    except TypeError as exc:
        return None, [str(exc)]


def item_reader(py_type: object) -> In:
    """What reads one bottle item as a value of ``py_type`` (an operation's argument; a
    model from the list of its fields), raising :class:`Unfit`; a type with no bottle form
    is read as plain data (its own check then judges it)."""
    try:
        return _convert(py_type, "argument")[1]
    except TypeError:
        return _plain


def _is_model(t: object) -> TypeGuard[type[pydantic.BaseModel]]:
    return isinstance(t, type) and issubclass(t, pydantic.BaseModel)


def _item_type(t: object) -> object | None:
    origin, args = typing.get_origin(t), typing.get_args(t)
    if origin in (list, Sequence, typing.Sequence) or t in (list, tuple):
        return args[0] if args else Any
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return args[0]
        raise TypeError(f"{_label(t)}: a fixed tuple has no bottle form; use tuple[X, ...] or a model")
    return None


def _label(t: object) -> str:
    return t.__name__ if isinstance(t, type) else str(t).replace("typing.", "")


def _convert(t: object, where: str) -> tuple[Out, In, str]:
    """The converters of one item of type ``t`` (``where`` names it in problems)."""
    if typing.get_origin(t) is typing.Annotated:
        return _convert(typing.get_args(t)[0], where)
    if t is Any or t is object:
        return (lambda v: v), _plain, "any"
    if t in _SCALARS:
        out, inp, shape = _SCALARS[t]
        return out, _named(inp, where), shape
    if _is_model(t):
        out, inp, shape = _model(t, where)
        return out, inp, f"({shape})"
    item = _item_type(t)
    if item is not None:
        each_out, each_in, shape = _convert(item, f"{where}[]")
        return (lambda v: [each_out(x) for x in v]), _list_in(each_in, where), f"({shape} ...)"
    origin = typing.get_origin(t)
    if origin in (typing.Union, types.UnionType):
        raise TypeError(f"{where} is {_label(t)}: a union (or Optional) has no bottle form")
    raise TypeError(f"{where} is {_label(t)}, which has no bottle form (int, float, str, bool, bytes, lists, models)")


def _model(model: type[pydantic.BaseModel], where: str) -> tuple[Callable[[Any], list[Item]], In, str]:
    names, outs, ins, shapes = [], [], [], []
    for name, info in model.model_fields.items():
        out, inp, shape = _convert(info.annotation, f"{model.__name__}.{name}")
        names.append(name)
        outs.append(out)
        ins.append(inp)
        shapes.append(shape)
    pairs = tuple(zip(names, outs))
    checks = tuple(zip(names, ins))

    def to_bottle(value: pydantic.BaseModel) -> list[Item]:
        return [out(getattr(value, name)) for name, out in pairs]

    def from_bottle(items: Item) -> dict[str, object]:
        if type(items) is not list:
            raise Unfit(f"{where}: a list of {len(names)} items is wanted, got {_what(items)}")
        if len(items) != len(names):
            raise Unfit(f"{where}: {len(names)} items ({', '.join(names)}) are wanted, got {len(items)}")
        return {name: inp(item) for (name, inp), item in zip(checks, items)}

    return to_bottle, from_bottle, " ".join(shapes)


def _list_in(each: In, where: str) -> In:
    def from_bottle(items: Item) -> list[object]:
        if type(items) is not list:
            raise Unfit(f"{where}: a list is wanted, got {_what(items)}")
        try:
            return [each(x) for x in items]
        except Unfit:
            for i, x in enumerate(items):  # the first that does not fit, by its place
                try:
                    each(x)
                except Unfit as exc:
                    raise Unfit(f"item {i + 1} of {len(items)}: {exc}") from None
            raise
    return from_bottle


def _single(each: In, where: str = "") -> Callable[[list[Item]], object]:
    """A bottle of one item read by ``each`` (``where``: named in its refusal, as
    :func:`_named` would)."""
    def from_bottle(items: list[Item]) -> object:
        if len(items) != 1:
            raise Unfit(f"one item is wanted, got {len(items)}")
        try:
            return each(items[0])
        except Unfit as exc:
            if not where:
                raise
            raise Unfit(f"{where}: {exc}") from None
    return from_bottle


def _named(inp: In, where: str) -> In:
    if not where:
        return inp

    def check(item: Item) -> object:
        try:
            return inp(item)
        except Unfit as exc:
            raise Unfit(f"{where}: {exc}") from None
    return check


def _what(item: object) -> str:
    if isinstance(item, list):
        return f"a list of {len(item)}"
    if isinstance(item, Vocab):
        return f"the vocab [{item.text}]"
    return f"{type(item).__name__} {item!r}"[:80]


def _int_in(item: Item) -> int:
    if type(item) is int:
        return item
    raise Unfit(f"an int is wanted, got {_what(item)}")


def _float_in(item: Item) -> float:
    if type(item) is float or type(item) is int:
        return float(item)
    raise Unfit(f"a number is wanted, got {_what(item)}")


def _str_in(item: Item) -> str:
    if type(item) is str:
        return item
    if type(item) is Vocab:
        return item.text
    raise Unfit(f"a string is wanted, got {_what(item)}")


def _bool_in(item: Item) -> bool:
    if type(item) is Vocab and item.code in (0, ord("1")):
        return item.code != 0
    if type(item) is int and item in (0, 1):
        return bool(item)
    raise Unfit(f"true or false is wanted, got {_what(item)}")


def _bytes_in(item: Item) -> bytes:
    if type(item) is bytes:
        return item
    raise Unfit(f"a blob is wanted, got {_what(item)}")


def _plain(item: Item) -> object:
    if isinstance(item, list):
        return [_plain(x) for x in item]
    return item.text if isinstance(item, Vocab) else item


_SCALARS: Mapping[object, tuple[Out, In, str]] = MappingProxyType({
    int: (int, _int_in, "int"),
    float: (float, _float_in, "float"),
    str: (str, _str_in, "string"),
    bool: (bool, _bool_in, "bool"),
    bytes: (bytes, _bytes_in, "blob"),
})
