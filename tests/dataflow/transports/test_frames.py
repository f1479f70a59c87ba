"""The frames every scart transport sends: the fast encoder of number samples makes the
very bytes the generated protobuf code makes (so the two can never drift apart), and
what a reader parses back is what was written."""

from __future__ import annotations

import math
import time

import pytest

from dataflow.transports import frames
from dataflow.transports.ends import OutSample
from scart_wire.proto.scart.dataflow.v1 import dataflow_pb2 as pb

NUMBERS = {float: [0.0, -0.0, -1.5, math.nan, math.inf, -math.inf, 5e-324, 1.7976931348623157e308],
           int: [0, 1, -1, 127, 128, 2**63 - 1, -(2**63)]}
WRITES = [(1, 1), (127, 128), (128, 16_384), (2**63 - 1, time.time_ns()), (0, 5), (5, 0), (3, -7)]


@pytest.mark.parametrize("py_type", [float, int])
def test_the_number_encoder_makes_the_generated_codes_bytes(py_type: type) -> None:
    encode = frames.encoder(py_type)
    assert encode is not frames.sample_frame  # the fast one
    for value in NUMBERS[py_type]:
        for n, t_ns in WRITES:
            sample = OutSample(n, t_ns, value, py_type)
            data = encode(sample)
            assert data == frames.sample_frame(OutSample(n, t_ns, value, py_type)), (value, n, t_ns)
            parsed = pb.SubscribeResponse.FromString(data).samples[0]
            assert (parsed.sequence, parsed.source_time_ns) == (n, t_ns)


def test_a_number_subclass_takes_the_general_encoder() -> None:
    assert frames.encoder(int)(OutSample(1, 2, True, int)) == frames.sample_frame(OutSample(1, 2, True, int))
