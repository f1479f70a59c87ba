"""Bottles and the port protocol's framing, byte for byte as YARP 3.5 writes them (the
bytes below were captured from ``yarp write`` sending ``hello 42 3.5 (nested list)
"quoted str" 0x10 -7 1e300 {01 02}``), and every limit on what a peer sends."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scart_yarp import bottle
from scart_yarp.bottle import BottleError, Limits, Vocab
from scart_yarp.wire import (IncomingParser, ProtocolError, carrier_header, carrier_of, command_block, data_frame,
                             data_parts, sender_specifier, yarp_number)

FROM_YARP_WRITE = (b"\x00\x01\x00\x00\t\x00\x00\x00\x04\x00\x00\x00\x05\x00\x00\x00hello\x01\x00\x00\x00*\x00\x00\x00"
                   b"\n\x00\x00\x00\x00\x00\x00\x00\x00\x00\x0c@\x04\x01\x00\x00\x02\x00\x00\x00\x06\x00\x00\x00nested"
                   b"\x04\x00\x00\x00list\x04\x00\x00\x00\n\x00\x00\x00quoted str\x01\x00\x00\x00\x10\x00\x00\x00\x01"
                   b"\x00\x00\x00\xf9\xff\xff\xff\n\x00\x00\x00\x9cu\x00\x88<\xe47~\x0c\x00\x00\x00\x02\x00\x00\x00"
                   b"\x01\x02")
VALUES = ["hello", 42, 3.5, ["nested", "list"], "quoted str", 16, -7, 1e300, b"\x01\x02"]
#: The whole message yarp write sent for it: index (2 blocks + 1 empty reply block), 'D' command, bottle.
MESSAGE = (b"YA\n\x00\x00\x00RP\x02\x01" + b"\xff" * 8 + b"\x08\x00\x00\x00{\x00\x00\x00\x00\x00\x00\x00"
           + b"\x00\x00\x00\x00~D\x00\x01" + FROM_YARP_WRITE)


def test_a_bottle_encodes_byte_for_byte_as_yarp_and_decodes_yarps() -> None:
    assert bottle.encode(VALUES) == FROM_YARP_WRITE
    assert bottle.decode(FROM_YARP_WRITE) == VALUES
    assert b"".join(data_parts(FROM_YARP_WRITE)) == MESSAGE  # what a port writes: yarp write's message


def test_homogeneous_lists_carry_one_tag_as_yarp_specialises_them() -> None:
    data = bottle.encode([1.0, 2.0])
    assert struct.unpack("<ii", data[:8]) == (256 | 10, 2) and len(data) == 8 + 16
    nested = bottle.encode([[1, 2], [3.5, "a"]])
    assert struct.unpack_from("<i", nested, 8)[0] == 256 | 1  # (1 2): a list of int32s
    assert bottle.decode(nested) == [[1, 2], [3.5, "a"]]
    assert bottle.decode(bottle.encode([True, False, Vocab("set")])) == [Vocab("1"), Vocab.of(0), Vocab("set")]
    assert bottle.decode(bottle.encode([2 ** 40, -(2 ** 40)])) == [2 ** 40, -(2 ** 40)]  # int64 beyond 32 bits


@pytest.mark.parametrize("value", [0, -1, 2 ** 31 - 1, -(2 ** 31), 2 ** 31, -(2 ** 31) - 1, 2 ** 63 - 1,
                                   -(2 ** 63), 0.0, -3.5, 1e300, math.inf])
def test_a_bottle_of_one_number_is_the_general_form(value: object) -> None:
    """A port of int or float sends a bottle of one number, packed at once: the bytes the
    general encoder (YARP's) gives, an int32 as long as it fits, else an int64."""
    general: list[bytes] = []
    bottle._encode_list([value], general, top=True)  # noqa: SLF001 - the general path, bypassing the shortcut
    assert bottle.encode([value]) == b"".join(general)
    assert bottle.decode(bottle.encode([value])) == [value]


def test_the_text_form_is_yarps() -> None:
    assert bottle.to_text(VALUES) == 'hello 42 3.5 (nested list) "quoted str" 16 -7 1e+300 {1 2}'
    line = 'hello 42 3.5 (nested list) "quoted str" 0x10 -7 1e300 {01 02} [set] true "a \\"q\\"\\n"'
    assert bottle.from_text(line) == [*VALUES, Vocab("set"), Vocab("1"), 'a "q"\n']
    assert bottle.to_text([1.0, float("inf"), float("nan"), "", "true", "3d", "d3", True, "nan"]) == \
        '1.0 inf nan "" "true" "3d" d3 true "nan"'
    assert bottle.from_text("1 2.0 -3e2 0x1F 1.5.2") == [1, 2.0, -300.0, 31, "1.5.2"]
    assert math.isnan(bottle.from_text("nan")[0])


words = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=12)
atoms = st.one_of(st.integers(-(2 ** 63), 2 ** 63 - 1), st.floats(allow_nan=False), words, st.binary(max_size=8))
bottles = st.lists(st.recursive(atoms, lambda inner: st.lists(inner, max_size=4), max_leaves=12), max_size=6)


@settings(max_examples=150, deadline=None)
@given(bottles)
def test_any_bottle_survives_both_forms(values: list) -> None:
    assert bottle.decode(bottle.encode(values)) == values
    assert bottle.from_text(bottle.to_text(values)) == [_as_text_reads(v) for v in values]


def _as_text_reads(value: object) -> object:
    """What the text form gives back: floats stay floats, everything else itself."""
    if isinstance(value, list):
        return [_as_text_reads(v) for v in value]
    return value


@pytest.mark.parametrize("data, why", [
    (FROM_YARP_WRITE[:-1], "truncated"),
    (FROM_YARP_WRITE + b"\0", "1 stray bytes"),
    (struct.pack("<ii", 256, 2 ** 30), "a list of 1073741824 items in 0 bytes"),
    (struct.pack("<iiii", 256, 1, 99, 0), "unknown item tag 99"),
    (struct.pack("<i", 4), "starts with a list tag"),
])
def test_a_malformed_bottle_is_refused_naming_why(data: bytes, why: str) -> None:
    with pytest.raises(BottleError, match=why):
        bottle.decode(data)


def test_a_bottle_nested_10000_deep_is_refused_before_it_is_walked() -> None:
    deep = struct.pack("<ii", 256, 1) + struct.pack("<ii", 256, 1) * 9999 + struct.pack("<i", 0)
    with pytest.raises(BottleError, match="nested over 64 deep"):
        bottle.decode(deep)
    with pytest.raises(BottleError, match="nested over 64 deep"):
        bottle.from_text("(" * 10_000 + ")" * 10_000)
    with pytest.raises(BottleError, match="over 5 items"):
        bottle.decode(bottle.encode(list(range(3)) + [[1, 2, 3]]), Limits(items=5))


def test_headers_name_their_carriers_and_refuse_multicast_and_strangers() -> None:
    assert carrier_header("tcp") == b"YA\xe4\x1e\x00\x00RP"  # what yarp write opened with: 7777 + 3 + 128
    assert [carrier_of(carrier_header(c)) for c in ("tcp", "fast_tcp", "text", "text_ack")] == \
        ["tcp", "fast_tcp", "text", "text_ack"]
    assert carrier_of(carrier_header("udp")) == "udp" and carrier_header("udp") == yarp_number(7777)
    with pytest.raises(ValueError, match="no multicast"):
        carrier_header("mcast")
    with pytest.raises(ProtocolError, match="mcast asked"):
        carrier_of(yarp_number(7778))
    with pytest.raises(ProtocolError, match="not a YARP connection"):
        carrier_of(b"GET / HT")


def test_the_parser_reads_what_yarp_write_sends_in_any_chunks() -> None:
    stream = carrier_header("tcp") + sender_specifier("/w") + MESSAGE + b"".join(data_frame([command_block("\0", "q")]))
    for size in (1, 7, len(stream)):
        parser = IncomingParser(max_message=1 << 20)
        frames = [f for i in range(0, len(stream), size) for f in parser.feed(stream[i:i + size])]
        assert parser.sender == "/w" and parser.carrier == "tcp"
        assert [(f.key, f.text) for f in frames] == [("D", ""), ("q", "q")]
        assert bottle.decode(frames[0].payload) == VALUES


def test_a_data_message_read_whole_is_the_frame_the_general_path_makes() -> None:
    """One data message per read (the commonest case) has a shortcut: the same frame as
    in pieces, and a message over the limit is still refused."""
    greeting = carrier_header("tcp") + sender_specifier("/w")
    parser = IncomingParser(max_message=1 << 20)
    assert parser.feed(greeting) == []
    assert [(f.key, f.text, f.payload) for f in parser.feed(MESSAGE)] == [("D", "", FROM_YARP_WRITE)]
    assert parser.feed(MESSAGE[:20]) == [] and [f.payload for f in parser.feed(MESSAGE[20:])] == [FROM_YARP_WRITE]
    small = IncomingParser(max_message=len(FROM_YARP_WRITE))  # its port command's 8 bytes too many
    small.feed(greeting)
    with pytest.raises(ProtocolError, match="a message of"):
        small.feed(MESSAGE)


def test_the_parser_reads_a_text_session() -> None:
    parser = IncomingParser(max_message=1 << 20)
    frames = parser.feed(b"CONNECT /human\r\nd\r\n1 2 (3 4)\r\n*\r\nq\r\n")
    assert parser.carrier == "text" and parser.sender == "/human"
    assert [(f.key, f.payload) for f in frames] == [("d", "1 2 (3 4)"), ("*", ""), ("q", "")]


@pytest.mark.parametrize("stream, why", [
    (b"GARBAGE!", "not a YARP connection"),
    (carrier_header("tcp") + struct.pack("<i", 5000), "sender name of 5000 bytes"),
    (carrier_header("tcp") + sender_specifier("/w") + b"YA\n\x00\x00\x00RP\x01\x01" + b"\xff" * 8
     + struct.pack("<ii", 2 ** 31 - 1, 0), "message of 2147483647 bytes"),
    (carrier_header("tcp") + sender_specifier("/w") + b"YB\n\x00\x00\x00RP" + b"\0" * 10, "broken index"),
])
def test_a_peer_breaking_the_protocol_is_refused_naming_why(stream: bytes, why: str) -> None:
    with pytest.raises(ProtocolError, match=why):
        IncomingParser(max_message=64 << 20).feed(stream)


def test_a_message_crosses_in_datagrams_and_a_lost_one_costs_its_message_only() -> None:
    """YARP's udp carrier: each datagram a CRC-32 and its number in the message; a
    datagram lost or damaged loses its message (counted) and the next message is whole."""
    from scart_yarp.dgram import MAX_PAYLOAD, DatagramReader, datagrams

    def message(values: list) -> list[bytes]:
        return datagrams(data_frame([command_block("D"), bottle.encode(values)]))

    big, small = message(["big", list(range(40_000))]), message(["small", 1])
    assert len(big) == 3 and all(len(d) <= MAX_PAYLOAD + 8 for d in big) and len(small) == 1
    reader = DatagramReader("/w", max_message=1 << 20)
    got = [f for d in [*big, *small] for f in reader.feed(d)]
    assert [bottle.decode(f.payload)[0] for f in got] == ["big", "small"] and reader.lost == 0
    damaged = big[1][:-1] + bytes([big[1][-1] ^ 1])
    got = [f for d in [big[0], damaged, big[2], *small, big[0], big[2], *small] for f in reader.feed(d)]
    assert [bottle.decode(f.payload)[0] for f in got] == ["small", "small"] and reader.lost == 2
