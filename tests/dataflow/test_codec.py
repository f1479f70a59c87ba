"""The one Value codec (scart_wire.codec): every value round-trips with its type, None and
unregistered values have their own names, unknown names decode to mappings, bad bytes
are a PortTypeError naming the type, and a port-typed encode uses the port's type."""

from __future__ import annotations

import math
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import BaseModel

from dataflow import PortTypeError, UnknownValue, register_type
from scart_wire.codec import FLOAT_LIST, JSON_TYPE, NONE_TYPE, Value, decode, encode


class Pose(BaseModel):
    x: float
    theta: float


@register_type("test.codec.Registered")
class Registered(BaseModel):
    name: str
    values: list[float]


@pytest.mark.parametrize("value", [
    None, 0, -7, 2.5, math.inf, True, "", "héllo", b"\x00\x01", [], [1.0, 2.0], [1, 2], ["a", "b"],
    {"k": [1, "x"], "n": None}, [1, "mixed"], 2**70, [True, False],
    Registered(name="r", values=[1.0, -math.inf]),
])
def test_values_round_trip_with_their_type(value: object) -> None:
    back = decode(Value.FromString(encode(value).SerializeToString()))
    assert back == value and type(back) is type(value)


def test_nan_survives() -> None:
    assert math.isnan(decode(encode(math.nan))) and math.isnan(decode(encode([math.nan]))[0])


def test_none_json_and_float_lists_have_their_own_names() -> None:
    assert encode(None).type_name == NONE_TYPE
    assert encode({"a": 1}).type_name == JSON_TYPE
    assert encode([Pose(x=0, theta=0)]).type_name == JSON_TYPE
    assert encode([1.0, 2.0]).type_name == FLOAT_LIST


def test_an_unregistered_model_arrives_as_a_mapping_with_its_name() -> None:
    back = decode(encode(Pose(x=1.0, theta=0.5)))
    assert isinstance(back, UnknownValue) and back == {"x": 1.0, "theta": 0.5} and back.type_name == "Pose"


def test_unknown_type_names_decode_to_mappings() -> None:
    back = decode(Value(type_name="Elsewhere", data=b'{"a": 1}'))
    assert isinstance(back, UnknownValue) and back == {"a": 1} and back.type_name == "Elsewhere"


def test_a_port_type_decides_the_encoding() -> None:
    assert encode(3, float).type_name == "float64" and decode(encode(3, float)) == 3.0
    assert encode([1, 2], list[float]).type_name == FLOAT_LIST


@pytest.mark.parametrize("value", [0, -7, 2**63 - 1, -(2**63), 2**70, 2.5, -0.0, math.inf, -math.inf])
def test_a_number_of_the_port_type_encodes_as_without_one(value: object) -> None:
    """The numbers' short path (a port's own type) gives the registry's bytes, and its limits."""
    typed = encode(value, type(value))
    assert typed == encode(value) and decode(Value.FromString(typed.SerializeToString())) == value
    assert typed.type_name == ("scart.json" if value == 2**70 else {int: "int64", float: "float64"}[type(value)])


@register_type("test.codec.Nested")
class Nested(BaseModel):
    pose: Pose
    poses: list[Pose] = []
    label: str | None = None
    count: int = 0


@pytest.mark.parametrize("value", [
    Registered(name="r", values=[1.0, 2.5]), Registered(name="r", values=[1.0, -math.inf, math.nan]),
    Nested(pose=Pose(x=1.0, theta=-0.5), poses=[Pose(x=2.0, theta=0.0)] * 3, label="é", count=-3),
    Nested(pose=Pose(x=math.inf, theta=0.0)), Nested(pose=Pose(x=0.0, theta=0.0)),
])
def test_a_model_of_the_port_type_encodes_as_without_one(value: BaseModel) -> None:
    """A model's short path (one pydantic call) gives the general path's bytes, inf and NaN kept."""
    typed = encode(value, type(value))
    assert typed == encode(value)
    back = decode(Value.FromString(typed.SerializeToString()))
    assert type(back) is type(value) and back.model_dump_json() == value.model_dump_json()
    assert ("Infinity" in typed.data.decode()) == ("inf" in repr(value))


@pytest.mark.parametrize(("name", "data"), [(FLOAT_LIST, b"\0" * 12), ("float64", b"\0"), ("int64", b"\0" * 9),
                                            (JSON_TYPE, b"{nope")])
def test_bad_bytes_are_a_port_type_error_naming_the_type(name: str, data: bytes) -> None:
    with pytest.raises(PortTypeError, match=re.escape(f"cannot decode {name}")):
        decode(Value(type_name=name, data=data))


def test_a_model_decodes_and_refuses_alike_every_time() -> None:
    """The first decode of a model's name takes the registry's lookups; later ones go
    straight to its validator: the same value, and the same error for bad bytes."""
    good = encode(Registered(name="r", values=[1.0, math.nan]), Registered)
    bad = Value(type_name=good.type_name, data=b'{"name": "r", "values": ["x"]}')
    for _ in range(3):
        back = decode(good)
        assert type(back) is Registered and back.name == "r" and math.isnan(back.values[1])
        with pytest.raises(PortTypeError, match=re.escape("cannot decode test.codec.Registered")):
            decode(bad)


def test_a_model_encodes_alike_every_time_and_takes_its_name_once_registered() -> None:
    """The first encode of a registered model's class takes the registry's lookups; later
    ones go straight to its serializer: the same bytes, inf and NaN kept. A class sent
    before it is registered is not remembered under its unregistered name."""
    sample = Registered(name="r", values=[1.0, math.inf, math.nan])
    first = encode(sample, Registered)
    for _ in range(3):
        again = encode(sample, Registered)
        assert again == first and b"Infinity" in again.data and b"NaN" in again.data

    class Late(BaseModel):
        x: float

    assert encode(Late(x=1.0), Late).type_name == Late.__qualname__
    register_type("test.codec.Late")(Late)
    for _ in range(3):
        sent = encode(Late(x=2.0), Late)
        assert sent.type_name == "test.codec.Late" and decode(sent) == Late(x=2.0)


def test_a_value_that_cannot_be_encoded_names_its_type() -> None:
    with pytest.raises(PortTypeError, match="cannot encode a value of type object"):
        encode(object())


@given(st.lists(st.floats(allow_nan=False), max_size=64))
def test_float_lists_round_trip(values: list[float]) -> None:
    assert decode(encode(values)) == values
