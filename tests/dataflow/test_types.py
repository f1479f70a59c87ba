"""Type registry: names, wire round-trips (hypothesis), unknown types, JSON."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from dataflow import Encoded, PortTypeError, UnknownValue, register_type, registry


@register_type("TestPoint")
class Point(BaseModel):
    x: float
    y: float
    tags: list[str] = []


def test_names():
    assert registry.type_name(float) == "float64"
    assert registry.type_name(list[float]) == "float64[]"
    assert registry.python_type("int64") is int
    assert registry.python_type("TestPoint") is Point
    assert registry.python_type("nope") is None
    registry.register(Point, "TestPoint")  # idempotent
    with pytest.raises(ValueError):
        registry.register(int, "TestPoint")


def test_float_list_is_packed():
    enc = registry.encode([1.0, 2.0, 3.0], list[float])
    assert enc == Encoded("float64[]", enc.data) and len(enc.data) == 24


finite = st.floats(allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(
    st.one_of(
        finite.map(lambda v: (float, v)),
        st.integers(-(2**63), 2**63 - 1).map(lambda v: (int, v)),
        st.booleans().map(lambda v: (bool, v)),
        st.text().map(lambda v: (str, v)),
        st.binary().map(lambda v: (bytes, v)),
        st.lists(finite).map(lambda v: (list[float], v)),
        st.lists(st.integers(-(2**63), 2**63 - 1)).map(lambda v: (list[int], v)),
        st.lists(st.text()).map(lambda v: (list[str], v)),
        st.builds(Point, x=finite, y=finite, tags=st.lists(st.text(max_size=5))).map(lambda v: (Point, v)),
    )
)
def test_round_trip(case):
    py_type, value = case
    enc = registry.encode(value, py_type)
    assert enc.type_name == registry.type_name(py_type)
    assert registry.decode(enc.type_name, enc.data) == value
    assert registry.from_jsonable(py_type, registry.to_jsonable(value)) == value


def test_nan_round_trip():
    enc = registry.encode(math.nan, float)
    assert math.isnan(registry.decode("float64", enc.data))


def test_unknown_type_decodes_to_mapping():
    v = registry.decode("Mystery", b'{"a": 1}')
    assert isinstance(v, UnknownValue) and isinstance(v, dict)
    assert v.type_name == "Mystery" and v == {"a": 1}
    raw = registry.decode("Blob", b"\xff\x00")
    assert raw.type_name == "Blob" and raw == {"data": "ff00"}
    again = registry.encode(v)
    assert again.type_name == "Mystery" and registry.decode("Mystery", again.data) == v
    assert registry.from_jsonable("Mystery", {"b": 2}).type_name == "Mystery"


def test_validate_and_bad_bytes():
    assert registry.validate(float, "2") == 2.0
    with pytest.raises(PortTypeError):
        registry.validate(float, "x")
    with pytest.raises(PortTypeError):
        registry.decode("float64", b"\x00")
    assert registry.from_jsonable("TestPoint", {"x": 1, "y": 2}) == Point(x=1, y=2)
