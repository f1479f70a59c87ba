"""numpy arrays as port types: a declared dtype and shape, named on the wire so that any
process knows the type by its name, each sample checked once (a wrong one refused at
``write`` naming what it got), and decoded as a read-only view of the bytes received."""

from __future__ import annotations

import numpy as np
import pytest

from dataflow import Array, ArraySpec, ConnPolicy, InputPort, OutputPort, PortTypeError
from scart_wire import codec
from scart_wire.types import registry


def test_an_array_type_is_named_by_its_dtype_and_shape_and_known_by_that_name_alone() -> None:
    image = Array[np.uint8, (480, 640, 3)]
    assert image == ArraySpec("uint8", (480, 640, 3)) and hash(image) == hash(Array["uint8", (480, 640, 3)])
    assert registry.type_name(image) == "ndarray<uint8>[480,640,3]"
    assert registry.type_name(Array[np.float32, (None, 3)]) == "ndarray<float32>[*,3]"
    assert registry.type_name(Array[np.float64]) == "ndarray<float64>"
    assert registry.type_name(Array[np.int16, 7]) == "ndarray<int16>[7]"
    for spec in (image, Array[np.float32, (None, 3)], Array[np.float64]):
        assert registry.python_type(spec.name) == spec  # another process needs only the name
    assert registry.python_type("ndarray<object>[3]") is None and registry.python_type("ndarray<uint8>[x]") is None
    assert image.fixed_bytes == 1 + 3 * 8 + 480 * 640 * 3 and Array[np.float32, (None, 3)].fixed_bytes is None
    with pytest.raises(TypeError, match="not one of"):
        Array[object, (3,)]
    with pytest.raises(TypeError, match="sizes"):
        Array[np.uint8, (3, -1)]


def test_each_sample_is_checked_once_at_write_naming_what_it_got() -> None:
    out = OutputPort(Array[np.uint8, (2, 3)], name="img")
    inp = InputPort(Array[np.uint8, (2, 3)], name="in")
    out.connect_to(inp, ConnPolicy.data())
    frame = np.arange(6, dtype=np.uint8).reshape(2, 3)
    assert out.write(frame).name == "WRITE_SUCCESS"
    assert inp.read()[1] is frame  # handed over by reference, as every sample in one process
    for wrong, said in ((np.zeros((3, 3), np.uint8), "ndarray<uint8>[3,3]"),
                        (np.zeros((2, 3)), "ndarray<float64>[2,3]"), ([[1, 2, 3], [4, 5, 6]], "list [[1, 2, 3]")):
        with pytest.raises(PortTypeError) as refused:
            out.write(wrong)
        assert str(refused.value).startswith(f"img: cannot write {said}")
        assert str(refused.value).endswith("; expected ndarray<uint8>[2,3]")


def test_an_array_crosses_the_wire_as_a_read_only_view_of_the_bytes() -> None:
    cloud = Array[np.float32, (None, 3)]
    points = np.random.default_rng(1).random((1000, 3), dtype=np.float32)
    points[5] = np.nan  # an invalid point: kept (finiteness is not checked in arrays)
    msg = codec.encode(points, cloud)
    assert msg.type_name == "ndarray<float32>[*,3]" and len(msg.data) == 1 + 16 + points.nbytes
    got = codec.decode(msg)
    assert got.shape == (1000, 3) and got.dtype == np.float32 and not got.flags.writeable
    assert np.array_equal(got, points, equal_nan=True)
    assert np.array_equal(codec.decode(codec.encode(points[:, 0])), points[:, 0], equal_nan=True)  # untyped: its own dtype and shape
    sliced = points[::2]  # not contiguous: sent as the C-order array it stands for
    assert np.array_equal(codec.decode(codec.encode(sliced, cloud)), sliced, equal_nan=True)


@pytest.mark.parametrize("data", [b"", b"\x09" + b"\x00" * 80, b"\x01" + (4).to_bytes(8, "little") + b"\x00" * 15])
def test_bytes_that_do_not_fit_the_type_are_refused(data: bytes) -> None:
    with pytest.raises(PortTypeError, match="cannot decode ndarray<float32>"):
        registry.decode("ndarray<float32>[*]", data)


def test_a_value_typed_by_hand_is_converted_and_checked() -> None:
    spec = Array[np.int32, (2, 2)]
    assert registry.validate(spec, [[1, 2], [3, 4]]).dtype == np.int32
    with pytest.raises(PortTypeError, match=r"expected ndarray<int32>\[2,2\]"):
        registry.validate(spec, [1, 2, 3])
    assert registry.to_jsonable(np.eye(2, dtype=np.int32)) == [[1, 0], [0, 1]]
