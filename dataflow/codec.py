"""The one ``Value`` codec, under the name this package has always given it: the same
functions and constants as :mod:`scart_wire.codec` (both worlds share them), not copies.
Importing this module imports protobuf, never grpc."""

from __future__ import annotations

from scart_wire.codec import FLOAT_LIST, JSON_TYPE, NONE_TYPE, Value, decode, encode

__all__ = ["FLOAT_LIST", "JSON_TYPE", "NONE_TYPE", "Value", "decode", "encode"]
