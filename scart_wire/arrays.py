"""numpy arrays as port types, with their dtype and shape declared (images, point clouds,
depth maps)::

    import numpy as np
    from dataflow import Array, OutputPort

    image = OutputPort(Array[np.uint8, (480, 640, 3)])     # one 640x480 RGB frame
    cloud = OutputPort(Array[np.float32, (None, 3)])       # any number of XYZ points
    blob = OutputPort(Array[np.uint8])                     # any shape

``Array[dtype, shape]`` is an :class:`ArraySpec`: a frozen value naming the type on the
wire (``ndarray<uint8>[480,640,3]``, ``*`` for a free size, no brackets for any shape),
known to every process by that name alone. Each sample is checked once, as every sample
is (``write`` raises :class:`~scart_wire.errors.PortTypeError` for another dtype or
shape; an array from outside is checked as it is decoded). The values' finiteness is not
checked: NaN marks an invalid point of a cloud.

On the wire a value is its shape (one byte of dimensions, then each as 8 bytes) and its
C-order little-endian bytes; decoded, it is a read-only array over the received bytes
(no copy). numpy is imported when an array type is first used.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import DTypeLike
    from pydantic import GetCoreSchemaHandler
    from pydantic_core import CoreSchema

T = TypeVar("T")

__all__ = ["Array", "ArraySpec", "DTYPES", "RAW_IMAGE", "array_spec", "from_message", "image_encoding", "to_message"]

#: The element types an array port may declare (numpy's names), little-endian on the wire.
DTYPES = ("bool", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
          "float16", "float32", "float64", "complex64", "complex128")
MAX_DIMS = 8  #: dimensions of an array type, at most
PREFIX = "ndarray<"
_NAME = re.compile(r"^ndarray<([a-z0-9]+)>(?:\[((?:\*|\d{1,10})(?:,(?:\*|\d{1,10})){0,7})\])?$")


def _dtype_name(dtype: DTypeLike) -> str:
    import numpy as np

    try:
        name = np.dtype(dtype).name
    except TypeError:
        raise TypeError(f"Array: {dtype!r} is not a numpy element type") from None
    if name not in DTYPES:
        raise TypeError(f"Array: element type {name!r} is not one of {', '.join(DTYPES)}")
    return name


@dataclass(frozen=True)
class ArraySpec:
    """An array port type: its element type (a numpy name) and shape (``None``: any
    shape; a ``None`` size: any size along that axis). Hashable; equal specs are one type."""

    dtype: str
    shape: tuple[int | None, ...] | None = None

    def __post_init__(self) -> None:
        if self.dtype not in DTYPES:
            raise TypeError(f"Array: element type {self.dtype!r} is not one of {', '.join(DTYPES)}")
        if self.shape is not None:
            if len(self.shape) > MAX_DIMS:
                raise TypeError(f"Array: at most {MAX_DIMS} dimensions, got {len(self.shape)}")
            for size in self.shape:
                if size is not None and (isinstance(size, bool) or not isinstance(size, int) or size < 0):
                    raise TypeError(f"Array: a shape holds sizes (int >= 0) or None, got {self.shape!r}")

    @property
    def name(self) -> str:
        """The type's name on the wire: ``ndarray<uint8>[480,640,3]``."""
        if self.shape is None:
            return f"{PREFIX}{self.dtype}>"
        return f"{PREFIX}{self.dtype}>[{','.join('*' if s is None else str(s) for s in self.shape)}]"

    def __repr__(self) -> str:
        return f"Array[{self.dtype}, {self.shape!r}]" if self.shape is not None else f"Array[{self.dtype}]"

    @property
    def image(self) -> str | None:
        """Its image encoding when its arrays are images (``rgb8``...), else None."""
        return image_encoding(self.dtype, self.shape)

    @property
    def fixed_bytes(self) -> int | None:
        """Bytes of one sample on the wire when the shape is fixed (else None)."""
        if self.shape is None or any(s is None for s in self.shape):
            return None
        count = 1
        for size in self.shape:
            count *= size  # type: ignore[operator]  # no None left (checked above)
        return 1 + 8 * len(self.shape) + count * _itemsize(self.dtype)

    # ---- checks ---------------------------------------------------------------------
    def mismatch(self, value: object) -> str:
        """What ``value`` is, when it is not a sample of this type ("" when it is):
        ``ndarray<float64>[480,640]``, ``list [[1, 2], ...``."""
        import numpy as np

        if not isinstance(value, np.ndarray):
            return f"{type(value).__name__} {value!r:.40}"
        if value.dtype.name != self.dtype:
            return describe(value)
        shape = self.shape
        if shape is not None and (len(value.shape) != len(shape) or
                                  any(s is not None and s != v for s, v in zip(shape, value.shape))):
            return describe(value)
        return ""

    def check(self, value: T) -> T:
        """``value`` when it is an array of this dtype and shape; ``TypeError`` saying what
        it is otherwise (a port's check: exact, no conversion)."""
        why = self.mismatch(value)
        if why:
            raise TypeError(why)
        return value

    def coerce(self, value: object) -> np.ndarray:
        """``value`` as an array of this type: an array of it as it is, else a list (a
        value typed on the command line) converted; ``ValueError`` when it does not fit."""
        import numpy as np

        if isinstance(value, np.ndarray) and not self.mismatch(value):
            return value
        if isinstance(value, dict):  # a recorded message (scart record, the Foxglove app)
            value = from_message(value, self)
        try:
            array = np.asarray(value, dtype=self.dtype) if not isinstance(value, np.ndarray) else value
        except (TypeError, ValueError, OverflowError) as exc:
            raise ValueError(f"not an array of {self.dtype}: {exc}") from None
        why = self.mismatch(array)
        if why:
            raise ValueError(f"expected {self.name}, got {why}")
        return array

    # ---- the wire ---------------------------------------------------------------------
    def encode(self, value: np.ndarray) -> bytes:
        """``value`` (checked) as wire bytes: shape, then the C-order little-endian data."""
        import numpy as np

        if value.dtype.byteorder == ">":
            value = value.astype(value.dtype.newbyteorder("<"))
        head = struct.pack(f"<B{value.ndim}Q", value.ndim, *value.shape)
        return b"".join((head, np.ascontiguousarray(value).data))

    def decode(self, data: bytes | bytearray | memoryview) -> np.ndarray:
        """Wire bytes (``bytes`` or a buffer) as a read-only array of this type, over
        ``data`` (no copy); ``ValueError`` when they do not fit."""
        import numpy as np

        view = memoryview(data).cast("B")
        if not view:
            raise ValueError(f"{self.name}: no bytes")
        ndim = view[0]
        if ndim > MAX_DIMS or len(view) < 1 + 8 * ndim:
            raise ValueError(f"{self.name}: a malformed shape")
        shape = struct.unpack_from(f"<{ndim}Q", view, 1)
        count = 1
        for size in shape:
            count *= size
        body = len(view) - 1 - 8 * ndim
        if count * _itemsize(self.dtype) != body:
            raise ValueError(f"{self.name}: shape {shape} needs {count * _itemsize(self.dtype)} bytes, got {body}")
        array = np.frombuffer(view, dtype=np.dtype(self.dtype).newbyteorder("<"), offset=1 + 8 * ndim)
        array = array.reshape(shape)
        if array.dtype.byteorder == ">":  # never on a little-endian host
            array = array.astype(self.dtype)
        array.flags.writeable = False
        why = self.mismatch(array)
        if why:
            raise ValueError(f"expected {self.name}, got {why}")
        return array

    # ---- pydantic (lax validation: registry.validate, scart write) ----------------------
    def __get_pydantic_core_schema__(self, source: object, handler: GetCoreSchemaHandler) -> CoreSchema:
        from pydantic_core import core_schema

        return core_schema.no_info_plain_validator_function(
            self.coerce, serialization=core_schema.plain_serializer_function_ser_schema(
                lambda a: a.tolist(), when_used="json"))


#: The encodings of images (``sensor_msgs/Image``'s and ``foxglove.RawImage``'s names), by
#: element type and channels.
IMAGE_ENCODINGS = MappingProxyType({("uint8", 1): "mono8", ("uint8", 3): "rgb8", ("uint8", 4): "rgba8",
                                    ("uint16", 1): "mono16", ("uint16", 3): "rgb16", ("float32", 1): "32FC1"})
RAW_IMAGE = "foxglove.RawImage"  #: the schema an image-shaped array is shown and recorded as


def image_encoding(dtype: str, shape: tuple[int | None, ...] | None) -> str | None:
    """The image encoding of arrays of ``dtype`` and ``shape`` (height, width[, channels]),
    or None when they are not images."""
    if shape is None or len(shape) not in (2, 3):
        return None
    channels = 1 if len(shape) == 2 else shape[2]
    return IMAGE_ENCODINGS.get((dtype, channels)) if channels is not None else None


def to_message(value: np.ndarray) -> dict[str, object]:
    """An array as a JSON message (what ``scart record`` and the Foxglove app carry): an
    image as ``foxglove.RawImage`` (width, height, encoding, step, base64 data), any other
    array as its shape, element type and base64 data."""
    import base64

    import numpy as np

    data = base64.b64encode(np.ascontiguousarray(value).data).decode("ascii")
    encoding = image_encoding(value.dtype.name, value.shape)
    if encoding is None:
        return {"shape": list(value.shape), "dtype": value.dtype.name, "data": data}
    height, width = value.shape[:2]
    return {"timestamp": {"sec": 0, "nsec": 0}, "frame_id": "", "width": width, "height": height,
            "encoding": encoding, "step": width * (value.shape[2] if value.ndim == 3 else 1) * value.itemsize,
            "data": data}


def from_message(message: dict[str, Any], spec: ArraySpec) -> np.ndarray:
    """The array a :func:`to_message` message holds, as ``spec``; ``ValueError`` when it
    does not fit."""
    import base64

    import numpy as np

    try:
        data = base64.b64decode(message["data"], validate=True)
        if "shape" in message:
            shape = tuple(int(s) for s in message["shape"])
        else:
            shape = (int(message["height"]), int(message["width"]))
            if spec.shape is not None and len(spec.shape) == 3:
                shape = (*shape, len(data) // max(1, shape[0] * shape[1] * _itemsize(spec.dtype)))
        return np.frombuffer(data, dtype=spec.dtype).reshape(shape)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"not a message of {spec.name}: {exc}") from None


def _itemsize(dtype: str) -> int:
    import numpy as np

    return int(np.dtype(dtype).itemsize)


def describe(value: np.ndarray) -> str:
    """An array in a few words: ``ndarray<float64>[480,640]``."""
    return f"{PREFIX}{value.dtype.name}>[{','.join(str(s) for s in value.shape)}]"


class Array:
    """``Array[dtype]`` or ``Array[dtype, shape]``: an :class:`ArraySpec` (see the module
    docstring). ``shape`` is a tuple of sizes or ``None`` (any size), or one size."""

    def __class_getitem__(cls, params: object) -> ArraySpec:
        if not isinstance(params, tuple):
            params = (params,)
        if len(params) not in (1, 2):
            raise TypeError("Array[dtype] or Array[dtype, shape]")
        shape = params[1] if len(params) == 2 else None
        if isinstance(shape, int) and not isinstance(shape, bool):
            shape = (shape,)
        if shape is not None and not isinstance(shape, tuple):
            raise TypeError(f"Array: a shape is a tuple of sizes, got {shape!r}")
        return ArraySpec(_dtype_name(params[0]), shape)


def array_spec(name: str) -> ArraySpec | None:
    """The array type called ``name`` (``ndarray<uint8>[480,640,3]``), or None for a name
    that is not one."""
    if not name.startswith(PREFIX):
        return None
    found = _NAME.match(name)
    if found is None or found.group(1) not in DTYPES:
        return None
    dims = found.group(2)
    shape = None if dims is None else tuple(None if d == "*" else int(d) for d in dims.split(","))
    return ArraySpec(found.group(1), shape)
