"""scart's YARP stack (:mod:`scart_yarp`, no scart port in sight) judged by YARP's own
``yarpserver`` and ``yarp``: names registered and withdrawn, bottles both ways on every
carrier, ``yarp connect``/``disconnect`` either way, ``yarp rpc``, a name server that
restarts, and raw TCP peers that break the protocol."""

from __future__ import annotations

import logging
import resource
import socket
import struct
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from support import wait_until
from support.yarp import YarpServer, yarpserver

from scart_yarp import BottleError, Incoming, Network, PortLimits, Vocab, bottle, rpc_call
from scart_yarp.names import parse_address
from scart_yarp.wire import carrier_header, command_block, data_frame, sender_specifier

pytestmark = pytest.mark.integration


@pytest.fixture
def yarp(tmp_path: Path) -> Iterator[YarpServer]:
    with yarpserver(tmp_path / "yarp") as server:
        yield server


@pytest.fixture
def net(yarp: YarpServer) -> Iterator[Network]:
    network = Network(parse_address(yarp.address), timeout=5.0, limits=PortLimits(handshake=1.0, strangers=8))
    try:
        yield network
    finally:
        network.close()


class Inbox:
    """What a reading port got: (source, values) pairs, and the refusals."""

    def __init__(self) -> None:
        self.got: list[tuple[str, list[Any]]] = []
        self.refused: list[str] = []

    def __call__(self, msg: Incoming) -> None:
        try:
            self.got.append((msg.source, msg.values()))
        except BottleError as exc:
            self.refused.append(str(exc))

    def wait(self, n: int, timeout: float = 15.0) -> list[list[Any]]:
        wait_until(lambda: len(self.got) >= n, timeout=timeout, message=f"{len(self.got)} of {n} bottles: {self.got}")
        return [values for _, values in self.got]


def registered(net: Network, name: str) -> None:
    wait_until(lambda: net.ports()[name].registered, timeout=10, message=f"{name} never registered")


def test_a_port_is_registered_listed_and_withdrawn(yarp: YarpServer, net: Network) -> None:
    port = net.open_port("/scart/probe")
    registered(net, "/scart/probe")
    query = yarp.tool("name", "query", "/scart/probe").stdout
    assert f"registration name /scart/probe ip 127.0.0.1 port {port.tcp_port} type tcp" in query
    assert "/scart/probe" in yarp.tool("name", "list").stdout
    port.close()
    assert not yarp.registered("/scart/probe")


@pytest.mark.parametrize("carrier", ["tcp", "fast_tcp", "text", "udp"])
def test_yarp_write_reaches_a_reading_port_on_each_carrier(yarp: YarpServer, net: Network, carrier: str) -> None:
    inbox = Inbox()
    net.open_port("/scart/in", reader=inbox)
    registered(net, "/scart/in")
    writer = yarp.spawn("write", "/w")
    try:
        writer.read_until("active", timeout=15)
        done = yarp.tool("connect", "/w", "/scart/in", carrier)
        assert done.returncode == 0, done.stdout + done.stderr
        assert writer.proc.stdin is not None
        writer.proc.stdin.write(b'hello 42 3.5 (nested list) "two words" {1 2}\n')
        writer.proc.stdin.flush()
        assert inbox.wait(1) == [["hello", 42, 3.5, ["nested", "list"], "two words", b"\x01\x02"]]
        assert [c.carrier for c in net.ports()["/scart/in"].inputs] == [carrier]
        assert yarp.tool("disconnect", "/w", "/scart/in").returncode == 0
        wait_until(lambda: not net.ports()["/scart/in"].inputs, timeout=10, message="the input stayed")
    finally:
        writer.stop()


@pytest.mark.parametrize("carrier", ["tcp", "fast_tcp", "text", "udp"])
def test_yarp_read_gets_what_a_writing_port_writes_on_each_carrier(yarp: YarpServer, net: Network,
                                                                    carrier: str) -> None:
    out = net.open_port("/scart/out")
    registered(net, "/scart/out")
    reader = yarp.spawn("read", "/r")
    try:
        reader.read_until("active", timeout=15)
        done = yarp.tool("connect", "/scart/out", "/r", carrier)
        assert done.returncode == 0 and "Added connection from /scart/out to /r" in done.stderr + done.stdout
        assert yarp.tool("name", "query", "/r").returncode == 0
        written_until_read(out, reader, ["sample", 1, 0.5, b"\x01\x02", ["a", 2], True], 'sample 1 0.5 {1 2} (a 2) true')
        written_until_read(out, reader, ["big", list(range(30_000))], "big (0 1 2 ")  # 120 kB: datagrams on udp
        listed = yarp.tool("connect", "/scart/out", "/r", carrier)  # again: YARP lists it, then replaces it
        assert listed.returncode == 0
        done = yarp.tool("disconnect", "/scart/out", "/r")
        assert done.returncode == 0 and "Removed connection from /scart/out to /r" in done.stderr + done.stdout
        reader.read_until("Removing input from /scart/out to /r", timeout=15)
        assert out.outputs == {}
    finally:
        reader.stop()


def written_until_read(out: Any, reader: Any, values: list[Any], needle: str) -> None:
    """Write until ``yarp read`` prints it: once on tcp; on udp, where a datagram may be
    lost on a loaded host (and its message with it, as YARP's udp does), a few times."""
    for _ in range(20):  # bounded: 20 × 1 s
        out.write(values)
        try:
            reader.read_until(needle, timeout=1.0)
            return
        except AssertionError:
            continue
    raise AssertionError(f"yarp read never printed {needle!r}: {reader.text()[-500:]}")


def test_a_port_keeps_the_connections_it_was_asked_for(yarp: YarpServer, net: Network) -> None:
    """``connect``: a writer connects to its readers (once they exist, and again after
    they restart); a reader asks its writers to connect to it."""
    out = net.open_port("/scart/kept", connect={"/r": "tcp"})
    inbox = Inbox()
    net.open_port("/scart/asks", reader=inbox, connect={"/scart/kept": "fast_tcp"})
    wait_until(lambda: "/scart/asks" in out.outputs, timeout=15, message="the reader's request was not kept")
    for attempt in range(2):  # the YARP reader, then the same reader restarted
        reader = yarp.spawn("read", "/r")
        try:
            wait_until(lambda: "/r" in out.outputs, timeout=15, message=f"never connected to /r (round {attempt})")
            out.write(["round", attempt])
            reader.read_until(f"round {attempt}", timeout=15)
        finally:
            reader.stop()
    assert [values for _, values in inbox.got][:2] == [["round", 0], ["round", 1]]


def test_acknowledgements_pile_up_unread_until_a_writer_waits_for_them(net: Network) -> None:
    """A tcp writer's io thread is not woken by each acknowledgement (each would cost the
    writer's process a wake-up while its reader takes the message); wait-after and
    wait-before still see every one at once."""
    inbox = Inbox()
    net.open_port("/scart/acking", reader=inbox)
    out = net.open_port("/scart/acked", connect={"/scart/acking": "tcp"})
    wait_until(lambda: "/scart/acking" in out.outputs, timeout=15, message="never connected")
    conn = out.outputs["/scart/acking"]
    for i in range(10):
        out.write([i])
    assert inbox.wait(10) == [[i] for i in range(10)]
    assert conn.acked == 0  # acknowledged by the reader, not read yet: no wake-up for them
    started = time.monotonic()
    for i in range(10, 30):  # each write waited for: its acknowledgement read at once (no timeout)
        out.write([i])
        assert out.wait_sent(5.0)
    assert conn.acked == conn.sent == 30 and time.monotonic() - started < 4.0


def test_yarp_rpc_calls_a_responding_port(yarp: YarpServer, net: Network) -> None:
    def respond(cmd: list[Any]) -> list[Any]:
        if cmd and cmd[0] == "boom":
            raise RuntimeError("it broke")
        return [Vocab("ok"), *cmd]

    net.open_port("/scart/rpc", responder=respond)
    registered(net, "/scart/rpc")
    done = yarp.tool("rpc", "/scart/rpc", stdin="set speed 3\nboom\n")
    assert "Response: [ok] set speed 3" in done.stdout, done.stdout + done.stderr
    assert 'Response: fail "RuntimeError: it broke"' in done.stdout
    assert rpc_call(net, "/scart/rpc", ["get", 1.5]) == [Vocab("ok"), "get", 1.5]


def test_a_restarted_name_server_learns_every_port_again(yarp: YarpServer, net: Network) -> None:
    net.open_port("/scart/again")
    registered(net, "/scart/again")
    yarp.stop()
    yarp.start()  # the same port, an empty database
    wait_until(lambda: yarp.registered("/scart/again"), timeout=20, interval=0.2,
               message="the port was not registered again")


def raw(port: Any) -> socket.socket:
    return socket.create_connection(("127.0.0.1", port.tcp_port), timeout=5)


def test_peers_breaking_the_protocol_cost_no_sample_and_each_is_said_once(
        yarp: YarpServer, net: Network, caplog: pytest.LogCaptureFixture) -> None:
    inbox = Inbox()
    port = net.open_port("/scart/victim", reader=inbox)
    registered(net, "/scart/victim")
    good = raw(port)
    good.sendall(carrier_header("tcp") + sender_specifier("/good"))
    good.recv(8)

    def send(values: list[Any]) -> None:
        good.sendall(b"".join(data_frame([command_block("D"), bottle.encode(values)])))
        assert good.recv(8) == b"YA\x00\x00\x00\x00RP"  # each message acknowledged

    send(["before", 1])
    caplog.set_level(logging.WARNING, logger="scart_yarp")
    attacks = {
        "wrong magic": b"NOTYARP!",
        "huge length": carrier_header("tcp") + sender_specifier("/h") + b"YA\n\x00\x00\x00RP\x01\x01" + b"\xff" * 8
        + struct.pack("<ii", 2 ** 31 - 1, 0),
    }
    for name, data in attacks.items():
        with raw(port) as bad:
            bad.sendall(data)
            assert bad.recv(4096) is not None  # YARP's "Protocol not found" or the close
    deep = struct.pack("<ii", 256, 1) + struct.pack("<ii", 256, 1) * 9999 + struct.pack("<i", 0)
    for payload in (bottle.encode(["cut", 1])[:-2], deep):  # a truncated bottle, one nested 10 000 deep
        good.sendall(b"".join(data_frame([command_block("D"), payload])))
        assert good.recv(8) == b"YA\x00\x00\x00\x00RP"
    assert len(inbox.refused) == 2 and "truncated" in inbox.refused[0] and "nested" in inbox.refused[1]
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft < 1200 <= hard or hard == resource.RLIM_INFINITY:
        resource.setrlimit(resource.RLIMIT_NOFILE, (4096 if hard == resource.RLIM_INFINITY else min(hard, 4096), hard))
    idle = [raw(port) for _ in range(1000)]
    try:
        send(["after", 2])
        assert inbox.wait(2) == [["before", 1], ["after", 2]]
        done = yarp.tool("write", "/w", "/scart/victim", stdin="still 3\n")  # a new writer gets in
        assert done.returncode == 0
        assert inbox.wait(3)[-1] == ["still", 3]
    finally:
        for sock in idle:
            sock.close()
        good.close()
    assert port.counters["protocol_errors"] == 2 and port.counters["strangers_closed"] >= 900
    lines = [r.getMessage() for r in caplog.records if r.name == "scart_yarp"]
    assert sum("broke the protocol" in line for line in lines) == 2, lines
    assert sum("have not said who they are" in line for line in lines) == 1, lines
