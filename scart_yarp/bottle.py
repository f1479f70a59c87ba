"""Bottles, YARP's messages, in Python: the binary form of the ``tcp`` and ``fast_tcp``
carriers and the text form of the ``text`` carrier and ``yarp read``/``yarp write``
(YARP 3.5's ``Bottle``, ``BottleImpl`` and ``Storable``, read from its sources).

A bottle is a ``list`` of values, each one of:

===========================  ==================  ========================================
Python                       YARP tag            text form
===========================  ==================  ========================================
``int``                      INT32 (1), INT64    ``42``
                             (17) beyond 32 bits
``float``                    FLOAT64 (10)        ``3.5``, ``inf``, ``nan``
``str``                      STRING (4)          ``hello``, ``"two words"``
``bytes``                    BLOB (12)           ``{1 2 255}``
:class:`Vocab`               VOCAB32 (9)         ``[set]``; ``true``/``false`` are the
                                                 vocabs ``'1'`` and 0
``list``                     LIST (256), with    ``(1 2 3)``
                             the tag of its
                             items when all are
                             of one primitive
                             kind (no tag each)
===========================  ==================  ========================================

``bool`` is written as the vocab YARP reads ``true`` and ``false`` as. Decoding also
reads INT8, INT16, FLOAT32 and DICT (as a list of ``[key, value]`` lists).

Everything from a peer is bounded (:class:`Limits`): bytes, items and nesting depth, so
a bottle nested 10 000 deep or claiming 2**31 items is refused with :class:`BottleError`
before anything is allocated for it. Not thread-safe state: none (pure functions).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, TypeAlias

__all__ = ["BottleError", "Item", "Limits", "Vocab", "decode", "encode", "from_text", "to_text", "TAGS"]

#: One value of a bottle as decoding gives it (see the table above; a DICT: a list of pairs).
Item: TypeAlias = "int | float | str | bytes | Vocab | list[Item]"

INT8, INT16, INT32, INT64, VOCAB32 = 32, 64, 1, 17, 9
FLOAT32, FLOAT64, STRING, BLOB, LIST, DICT = 128, 10, 4, 12, 256, 512
GROUP_MASK = LIST | DICT
UNIT_MASK = 0xFF  # the item tag of a specialised (homogeneous) list
#: Every tag a bottle's item may carry, by name.
TAGS = MappingProxyType({"int8": INT8, "int16": INT16, "int32": INT32, "int64": INT64, "vocab32": VOCAB32,
                       "float32": FLOAT32, "float64": FLOAT64, "string": STRING, "blob": BLOB, "list": LIST,
                       "dict": DICT})

_I32 = struct.Struct("<i")
_II = struct.Struct("<ii")
_INT32_MIN, _INT32_MAX = -(2 ** 31), 2 ** 31 - 1
_INT64_MIN, _INT64_MAX = -(2 ** 63), 2 ** 63 - 1
_FIXED = MappingProxyType({INT8: struct.Struct("<b"), INT16: struct.Struct("<h"), INT32: _I32,
                         INT64: struct.Struct("<q"), VOCAB32: _I32, FLOAT32: struct.Struct("<f"),
                         FLOAT64: struct.Struct("<d")})
_FORMAT = MappingProxyType({INT8: "b", INT16: "h", INT32: "i", INT64: "q", VOCAB32: "i", FLOAT32: "f", FLOAT64: "d"})


class BottleError(ValueError):
    """A bottle that cannot be read (truncated, over a limit, an unknown tag) or a value
    that has no bottle form (an int over 64 bits, a type with no tag)."""


@dataclass(frozen=True)
class Limits:
    """What a bottle from a peer may hold, at most: nesting ``depth``, ``items`` in all,
    and (text) ``chars``. A message's bytes are bounded by the connection that carries it."""

    depth: int = 64
    items: int = 1_000_000
    chars: int = 1 << 20


DEFAULT_LIMITS = Limits()


class Vocab:
    """A YARP vocab: up to four characters packed in a 32-bit int (``Vocab("set")``,
    ``Vocab.of(code)``). Compares equal to another vocab of the same code."""

    __slots__ = ("code",)

    def __init__(self, text: str) -> None:
        raw = text.encode("latin-1")
        if len(raw) > 4:
            raise BottleError(f"a vocab has at most 4 characters, got {text!r}")
        self.code = int.from_bytes(raw.ljust(4, b"\0"), "little", signed=True)

    @classmethod
    def of(cls, code: int) -> Vocab:
        vocab = cls.__new__(cls)
        vocab.code = code
        return vocab

    @property
    def text(self) -> str:
        return (self.code & 0xFFFFFFFF).to_bytes(4, "little").replace(b"\0", b"").decode("latin-1")

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Vocab) and other.code == self.code

    def __hash__(self) -> int:
        return hash(("vocab", self.code))

    def __repr__(self) -> str:
        return f"Vocab({self.text!r})"


TRUE, FALSE = Vocab.of(ord("1")), Vocab.of(0)


# ---- binary ----------------------------------------------------------------------------
def _tag(value: Any) -> int:
    kind = type(value)
    if kind is float:
        return FLOAT64
    if kind is int:
        return INT32 if _INT32_MIN <= value <= _INT32_MAX else INT64
    if kind is str:
        return STRING
    if kind is list or kind is tuple:
        return LIST | _subcode(value)
    if kind is bytes or kind is bytearray or kind is memoryview:
        return BLOB
    if kind is bool or kind is Vocab:
        return VOCAB32
    if isinstance(value, float):
        return FLOAT64
    if isinstance(value, int):
        return INT32 if _INT32_MIN <= value <= _INT32_MAX else INT64
    raise BottleError(f"a {kind.__name__} has no bottle form (int, float, str, bytes, bool, Vocab or a list)")


def _subcode(items: Any) -> int:
    """The one primitive tag of every item (YARP's ``subCoder``), else 0."""
    if not items:
        return 0
    first = _tag(items[0])
    if first & GROUP_MASK:
        return 0
    for item in items:
        if _tag(item) != first:
            return 0
    return first


_ONE_INT32, _ONE_INT64, _ONE_FLOAT64 = struct.Struct("<iii"), struct.Struct("<iiq"), struct.Struct("<iid")


def encode(values: Sequence[object]) -> bytes:
    """The binary form of a bottle holding ``values`` (its tag, count and items); raises
    :class:`BottleError` for a value with no bottle form."""
    if len(values) == 1:  # one number (a port of int or float): one pack
        value = values[0]
        if type(value) is float:
            return _ONE_FLOAT64.pack(LIST | FLOAT64, 1, value)
        if type(value) is int:
            if _INT32_MIN <= value <= _INT32_MAX:
                return _ONE_INT32.pack(LIST | INT32, 1, value)
            if _INT64_MIN <= value <= _INT64_MAX:
                return _ONE_INT64.pack(LIST | INT64, 1, value)
    out: list[bytes] = []
    _encode_list(values, out, top=True)
    return b"".join(out)


def _encode_list(values: Any, out: list[bytes], top: bool) -> None:
    sub = _subcode(values)
    if top:
        out.append(_II.pack(LIST | sub, len(values)))
    else:
        out.append(_I32.pack(len(values)))
    if sub in _FORMAT:  # one struct for the whole homogeneous list
        items = [v.code if type(v) is Vocab else (ord("1") if v is True else 0 if v is False else v) for v in values] \
            if sub == VOCAB32 else values
        out.append(struct.pack(f"<{len(values)}{_FORMAT[sub]}", *items))
        return
    for value in values:
        tag = LIST | _subcode(value) if isinstance(value, (list, tuple)) else _tag(value)
        if not sub:
            out.append(_I32.pack(tag))
        _encode_item(value, tag, out)


def _encode_item(value: Any, tag: int, out: list[bytes]) -> None:
    if tag & GROUP_MASK:
        _encode_list(value, out, top=False)
    elif tag == STRING:
        raw = value.encode("utf-8")
        out.append(_I32.pack(len(raw)))
        out.append(raw)
    elif tag == BLOB:
        out.append(_I32.pack(len(value)))
        out.append(bytes(value))
    elif tag == VOCAB32:
        out.append(_I32.pack(value.code if type(value) is Vocab else (ord("1") if value else 0)))
    else:
        out.append(_FIXED[tag].pack(value))


class _Reader:
    """A bounded cursor over a bottle's bytes."""

    __slots__ = ("data", "pos", "items", "limits")

    def __init__(self, data: bytes | memoryview, limits: Limits) -> None:
        self.data = data
        self.pos = 0
        self.items = 0
        self.limits = limits

    def int32(self) -> int:
        if self.pos + 4 > len(self.data):
            raise BottleError(f"truncated bottle: an int at byte {self.pos} of {len(self.data)}")
        (value,) = _I32.unpack_from(self.data, self.pos)
        self.pos += 4
        return value

    def count(self, min_size: int) -> int:
        """An item count, bounded by the bytes left and the limit on items."""
        n = self.int32()
        left = len(self.data) - self.pos
        if n < 0 or n * min_size > left:
            raise BottleError(f"a list of {n} items in {left} bytes: truncated or malformed bottle")
        self.items += n
        if self.items > self.limits.items:
            raise BottleError(f"a bottle of over {self.limits.items} items (the limit)")
        return n

    def raw(self, n: int) -> bytes:
        if n < 0 or self.pos + n > len(self.data):
            raise BottleError(f"truncated bottle: {n} bytes at byte {self.pos} of {len(self.data)}")
        chunk = bytes(self.data[self.pos:self.pos + n])
        self.pos += n
        return chunk


#: A bottle that is one list of numbers (a port of int, float or a list of them), by its
#: tag: the format of one item and its size; such a bottle is read with one unpack.
_NUMBERS = MappingProxyType({LIST | tag: (_FORMAT[tag], _FIXED[tag].size) for tag in _FORMAT if tag != VOCAB32})


def decode(data: bytes | memoryview, limits: Limits = DEFAULT_LIMITS) -> list[Item]:
    """The values of a bottle's binary form; :class:`BottleError` for anything malformed,
    truncated, over ``limits`` or followed by stray bytes."""
    if len(data) >= 8:
        tag, n = _II.unpack_from(data)
        numbers = _NUMBERS.get(tag)
        if numbers is not None and 0 <= n <= limits.items and len(data) == 8 + n * numbers[1] and limits.depth:
            return list(struct.unpack_from(f"<{n}{numbers[0]}", data, 8))  # the common case, whole
    reader = _Reader(data, limits)
    tag = reader.int32()
    if not tag & GROUP_MASK:
        raise BottleError(f"a bottle starts with a list tag, got {tag}")
    values = _decode_list(reader, tag & UNIT_MASK, tag & DICT, 1)
    if reader.pos != len(data):
        raise BottleError(f"{len(data) - reader.pos} stray bytes after the bottle")
    return values


def _decode_list(reader: _Reader, sub: int, is_dict: int, depth: int) -> list[Item]:
    if depth > reader.limits.depth:
        raise BottleError(f"a bottle nested over {reader.limits.depth} deep (the limit)")
    fixed = _FIXED.get(sub)
    n = reader.count(fixed.size if fixed is not None else (4 if sub else 8))
    if fixed is not None:  # a homogeneous list of numbers: one unpack
        values = list(struct.unpack_from(f"<{n}{_FORMAT[sub]}", reader.data, reader.pos))
        reader.pos += n * fixed.size
        return [Vocab.of(v) for v in values] if sub == VOCAB32 else values
    out = [_decode_item(reader, sub or reader.int32(), depth) for _ in range(n)]
    if is_dict:
        return [list(pair) for pair in zip(out[::2], out[1::2])]
    return out


def _decode_item(reader: _Reader, tag: int, depth: int) -> Item:
    fixed = _FIXED.get(tag)
    if fixed is not None:
        if reader.pos + fixed.size > len(reader.data):
            raise BottleError(f"truncated bottle: a number at byte {reader.pos} of {len(reader.data)}")
        (value,) = fixed.unpack_from(reader.data, reader.pos)
        reader.pos += fixed.size
        return Vocab.of(value) if tag == VOCAB32 else value
    if tag == STRING:
        return reader.raw(reader.int32()).decode("utf-8", errors="replace")
    if tag == BLOB:
        return reader.raw(reader.int32())
    if tag & GROUP_MASK:
        return _decode_list(reader, tag & UNIT_MASK, tag & DICT, depth + 1)
    raise BottleError(f"unknown item tag {tag} at byte {reader.pos - 4}")


# ---- text ------------------------------------------------------------------------------
def to_text(values: Sequence[object]) -> str:
    """The text form of a bottle (what ``yarp read`` prints)."""
    return " ".join(_item_text(v) for v in values)


def _item_text(value: Any) -> str:
    kind = type(value)
    if kind is bool or kind is Vocab:
        code = (ord("1") if value else 0) if kind is bool else value.code
        return "true" if code == ord("1") else "false" if code == 0 else f"[{Vocab.of(code).text}]"
    if kind is int or (isinstance(value, int) and kind is not bool):
        return str(int(value))
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        text = repr(float(value))
        return text if ("." in text or "e" in text) else text + ".0"
    if kind is str:
        return _quoted(value)
    if isinstance(value, (bytes, bytearray, memoryview)):
        return "{" + " ".join(str(b) for b in bytes(value)) + "}"
    if isinstance(value, (list, tuple)):
        return "(" + to_text(value) + ")"
    raise BottleError(f"a {kind.__name__} has no bottle form")


def _quoted(text: str) -> str:
    """YARP's ``quotedString``: bare when it is a word (letters, ``_``, and digits, ``.``
    or ``-`` after the first character), else quoted with ``\\``, ``"``, CR, LF, NUL escaped."""
    bare = bool(text) and text not in ("true", "false", "nan", "inf", "null") and all(
        ch.isascii() and (ch.isalpha() or ch == "_" or (i > 0 and (ch.isdigit() or ch in ".-")))
        for i, ch in enumerate(text))
    if bare:
        return text
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n").replace("\r", "\\r")
    return '"' + escaped.replace("\0", "\\0") + '"'


def from_text(line: str, limits: Limits = DEFAULT_LIMITS) -> list[Item]:
    """The values of a bottle's text form (YARP's ``fromString``: words, numbers, quoted
    strings, ``(lists)``, ``{blobs}``, ``[vocabs]``); :class:`BottleError` over ``limits``
    or for an unbalanced line."""
    if len(line) > limits.chars:
        raise BottleError(f"a bottle of {len(line)} characters (the limit is {limits.chars})")
    budget = [limits.items]
    return _words(line, limits, 1, budget)


def _words(line: str, limits: Limits, depth: int, budget: list[int]) -> list[Item]:
    if depth > limits.depth:
        raise BottleError(f"a bottle nested over {limits.depth} deep (the limit)")
    out: list[Item] = []
    for word in _split(line):
        budget[0] -= 1
        if budget[0] < 0:
            raise BottleError(f"a bottle of over {limits.items} items (the limit)")
        out.append(_word(word, limits, depth, budget))
    return out


def _split(line: str) -> list[str]:
    """The top-level words of ``line`` (quotes, ``()`` and ``{}`` kept whole, ``\\`` escapes)."""
    words: list[str] = []
    arg: list[str] = []
    quoted = back = False
    nested = nested_alt = 0
    for ch in line + " ":
        if back:
            arg.append(ch)
            back = False
            continue
        if ch == '"':
            quoted = not quoted
        elif not quoted:
            nested += (ch == "(") - (ch == ")")
            nested_alt += (ch == "{") - (ch == "}")
        if ch == "\\":
            back = True
            arg.append(ch)
        elif not quoted and ch in ", \t\n\r" and nested == 0 and nested_alt == 0:
            if arg:
                words.append("".join(arg))
            arg = []
        else:
            arg.append(ch)
    if quoted or nested or nested_alt:
        raise BottleError(f"unbalanced quotes or brackets in {line[:80]!r}")
    return words


def _word(word: str, limits: Limits, depth: int, budget: list[int]) -> Item:
    first = word[0]
    if first == "(":
        return _words(word[1:-1], limits, depth + 1, budget)
    if first == "{":
        try:
            return bytes(int(b) & 0xFF for b in _split(word[1:-1]))
        except ValueError:
            raise BottleError(f"a blob holds numbers: {word[:80]!r}") from None
    if first == "[":
        return Vocab(word[1:-1][:4])
    if first == '"':
        return _unquoted(word)
    if word == "null":
        return Vocab("null")
    if word in ("true", "false"):
        return TRUE if word == "true" else FALSE
    number = _number(word)
    return word if number is None else number


def _number(word: str) -> int | float | None:
    """YARP's ``smartAdd`` rules: a number-like word is an int (decimal, or 0x hex of at
    most 8 digits) or, with ``.``, ``e`` (or ``inf``/``nan``), a float."""
    if word in ("inf", "-inf", "nan"):
        return float(word)
    if not (word[0].isdigit() or word[0] in "+-." ) or word == ".":
        return None
    try:
        if word.lower().lstrip("+-").startswith("0x"):
            return int(word, 16) if len(word.lower().split("x", 1)[1]) <= 8 else None
        if any(c in word for c in ".eE"):
            return float(word)
        return int(word, 10)
    except ValueError:
        return None


def _unquoted(word: str) -> str:
    out: list[str] = []
    back = False
    for ch in word[1:-1]:
        if back:
            out.append({"n": "\n", "r": "\r", "0": "\0"}.get(ch, ch))
            back = False
        elif ch == "\\":
            back = True
        else:
            out.append(ch)
    return "".join(out)
