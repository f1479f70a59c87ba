"""binding.grpc's wire format: the proto (buf style), and values through the one codec
(the type registry plus the None / JSON additions)."""

from __future__ import annotations

import math

import pytest
from pydantic import BaseModel

from dataflow.codec import Value
from dataflow.types import UnknownValue
from scart.ext.grpc._wire import JSON_TYPE, NONE_TYPE, SCA_SERVICE, Signature, converter, decode, encode, fault, pb
from scart.errors import InvocationError


class Pose(BaseModel):
    x: float
    theta: float


def test_proto_is_buf_style() -> None:
    assert SCA_SERVICE.file.name == "scart/sca/v1/sca.proto"
    assert SCA_SERVICE.full_name == "scart.sca.v1.ScaService"
    for method in SCA_SERVICE.methods:
        assert method.input_type.name == f"{method.name}Request"
        assert method.output_type.name == f"{method.name}Response"
    kinds = {m.name: (m.client_streaming, m.server_streaming) for m in SCA_SERVICE.methods}
    assert kinds["Invoke"] == (False, True) and kinds["OpenCallbackSession"] == (True, True)
    assert kinds["Call"] == kinds["Send"] == kinds["ReplyCallback"] == (False, False)


@pytest.mark.parametrize("value", [
    None, 0, -7, 2.5, math.inf, True, "", "héllo", b"\x00\x01", [], [1.0, 2.0], [1, 2], ["a", "b"],
    {"k": [1, "x"], "n": None}, [1, "mixed"], 2**70, [True, False], Pose(x=1.0, theta=0.5),
])
def test_values_round_trip(value: object) -> None:
    msg = Value.FromString(encode(value).SerializeToString())
    back = decode(msg)
    if isinstance(value, BaseModel):
        assert converter(Pose)(back) == value  # unregistered model: a mapping, coerced by annotation
    else:
        assert back == value and type(back) is type(value)


def test_none_and_json_have_their_own_names() -> None:
    assert encode(None).type_name == NONE_TYPE
    assert encode({"a": 1}).type_name == JSON_TYPE
    assert encode([Pose(x=0, theta=0)]).type_name == JSON_TYPE


def test_unknown_type_names_decode_to_mappings() -> None:
    back = decode(Value(type_name="Elsewhere", data=b'{"a": 1}'))
    assert isinstance(back, UnknownValue) and back == {"a": 1} and back.type_name == "Elsewhere"


def test_values_that_cannot_be_sent_raise_invocation_error() -> None:
    with pytest.raises(InvocationError, match="cannot send a value of type object"):
        encode(object())


def test_signature_coerces_by_annotation() -> None:
    def op(self: object, poses: list[Pose], k: float, *, tag: str = "") -> Pose: ...
    sig = Signature(op)
    args = sig.args([encode([{"x": 1, "theta": 2}]), encode(3)])
    assert args == ([Pose(x=1, theta=2)], 3.0) and type(args[1]) is float
    assert sig.kwargs({"tag": encode("t")}) == {"tag": "t"}
    with pytest.raises(InvocationError, match="expected"):
        sig.args([encode("not poses")])


def test_fault_names_the_qualified_type() -> None:
    assert fault(ZeroDivisionError("x")).type == "ZeroDivisionError"
    assert fault(InvocationError("y")).type == "scart.errors.InvocationError"
