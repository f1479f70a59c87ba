"""binding.grpc's wire format: the proto (buf style), values through the one codec
(:mod:`scart_wire.codec`, tested on its own), coercion to annotations, faults."""

from __future__ import annotations

import pytest
from pydantic import BaseModel

from scart.bindings.grpc._wire import SCA_SERVICE, Signature, converter, decode, encode, fault
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


def test_the_binding_uses_the_one_codec() -> None:
    """Values go through scart_wire.codec: the same bytes as the remote layer's."""
    from scart_wire import codec

    for value in (None, 2.5, [1.0, 2.0], {"k": 1}, Pose(x=1.0, theta=0.5)):
        assert encode(value) == codec.encode(value)
    assert decode(codec.encode([3.0])) == [3.0]


def test_an_unregistered_model_arrives_as_the_annotated_model() -> None:
    assert converter(Pose)(decode(encode(Pose(x=1.0, theta=0.5)))) == Pose(x=1.0, theta=0.5)


def test_values_that_cannot_be_sent_raise_invocation_error() -> None:
    with pytest.raises(InvocationError, match="cannot send a value of type object"):
        encode(object())


def test_signature_coerces_by_annotation() -> None:
    def op(self: object, poses: list[Pose], k: float, *, tag: str = "") -> Pose: ...
    sig = Signature(op)
    args = sig.args([encode([{"x": 1, "theta": 2}]), encode(3)])
    assert args == ([Pose(x=1, theta=2)], 3.0) and type(args[1]) is float
    assert sig.kwargs({"tag": encode("t")}) == {"tag": "t"}
    with pytest.raises(InvocationError, match=r"op\(poses\): 'not poses' refused: Input should be a valid list"):
        sig.args([encode("not poses")])


def test_fault_names_the_qualified_type() -> None:
    assert fault(ZeroDivisionError("x")).type == "ZeroDivisionError"
    assert fault(InvocationError("y")).type == "scart.errors.InvocationError"
