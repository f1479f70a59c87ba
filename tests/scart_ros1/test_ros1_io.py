"""The ROS 1 node's io loop and send queues, on socket pairs (no master, no ROS): a peer
that stops reading never blocks the sender, the oldest queued messages are dropped and
counted, and what arrives is still a clean stream of whole frames, in order."""

from __future__ import annotations

import socket
import struct
import threading

import pytest
from support import wait_until

import scart_ros1 as ros1
from scart_ros1.io import Conn, FrameReader, IoLoop


@pytest.fixture
def loop():
    io_loop = IoLoop("test")
    io_loop.start()
    yield io_loop
    io_loop.close()


def frame(i: int, size: int) -> bytes:
    body = struct.pack("<I", i) + b"x" * (size - 4)
    return struct.pack("<I", len(body)) + body


def received(sock: socket.socket, size: int) -> bytes:
    """What ``sock`` has (its timeout bounds the wait); fails when the other end closed,
    which would otherwise make a receive loop spin on empty reads."""
    data = sock.recv(size)
    assert data, "the connection closed before every message arrived"
    return data


def test_a_stalled_reader_costs_the_sender_nothing_and_loses_only_counted_messages(loop: IoLoop) -> None:
    ours, theirs = socket.socketpair()
    theirs.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    conn = Conn(loop, ours, "peer")
    conn.max_queue, conn.max_queue_bytes = 50, 1 << 20
    loop.call_soon(loop.register, ours, conn)
    count, sent = 2000, []

    def send_all() -> None:  # the peer reads nothing meanwhile: a blocking send would never end
        sent.extend(conn.send(frame(i, 16 * 1024)) for i in range(count))

    sender = threading.Thread(target=send_all, name="test-sender", daemon=True)
    sender.start()
    sender.join(timeout=30)
    assert not sender.is_alive() and sent == [True] * count, "send() blocked on a peer that reads nothing"
    dropped = conn.stats["dropped"]
    assert dropped > 0
    got: list[int] = []
    reader = FrameReader(1 << 20, lambda p: got.append(struct.unpack_from("<I", p)[0]), pytest.fail)
    theirs.settimeout(10)
    while not got or got[-1] != count - 1:  # ends: the last message is never dropped
        reader.feed(received(theirs, 65536))
    assert got == sorted(got) and len(got) + dropped == count  # whole frames, in order, all accounted for
    # the io thread counts a message sent after its last byte left: the reader may be first
    wait_until(lambda: conn.stats["messages_sent"] == count - dropped, timeout=5,
               message="messages_sent never reached the messages not dropped")
    theirs.close()
    conn.close("test")
    conn.close("again")  # idempotent
    wait_until(lambda: ours.fileno() < 0, timeout=5)


def test_unsent_header_and_partial_message_are_never_dropped(loop: IoLoop) -> None:
    ours, theirs = socket.socketpair()
    conn = Conn(loop, ours, "peer")
    conn.max_queue, conn.max_queue_bytes = 1, 1  # every droppable message beyond the head goes
    loop.call_soon(loop.register, ours, conn)
    header = struct.pack("<I", 5) + b"hello"
    big = frame(0, 4 << 20)  # larger than the socket buffers: it stays partly sent
    assert conn.send(big) and conn.send(header, droppable=False) and conn.send(frame(1, 8)) and conn.send(frame(2, 8))
    got: list[bytes] = []
    reader = FrameReader(8 << 20, got.append, pytest.fail)
    theirs.settimeout(10)
    while len(got) < 3:
        reader.feed(received(theirs, 1 << 20))
    assert [len(g) for g in got] == [(4 << 20), 5, 8] and got[1] == b"hello"
    assert struct.unpack_from("<I", got[2])[0] == 2 and conn.stats["dropped"] == 1
    theirs.close()


def test_closing_the_loop_closes_what_it_owns_and_ends_its_thread() -> None:
    io_loop = IoLoop("test")
    io_loop.start()
    ours, theirs = socket.socketpair()
    conn = Conn(io_loop, ours, "peer")
    io_loop.call_soon(io_loop.register, ours, conn)
    closed = threading.Event()
    conn.on_close = lambda c, reason: closed.set()
    io_loop.close()
    io_loop.close()
    assert closed.is_set() and ours.fileno() < 0 and conn.closed
    assert not any(t.name == "ros1-io test" for t in threading.enumerate())
    theirs.close()


def test_the_public_api_is_what_the_package_docstring_tells() -> None:
    assert sorted(ros1.__all__) == sorted([
        "FieldDef", "HeaderError", "Limits", "Master", "MasterError", "MasterUnreachable", "MessageTypes", "MsgType",
        "NODE_COUNTERS", "Node", "NodeNames", "Publisher", "RosNameError", "ServiceError", "ServiceServer",
        "SrvType", "Subscriber", "TypeDefinitionError", "UnknownTypeError",
    ])
    for name in ("Node", "MessageTypes", "Limits", "advertise", "subscribe", "advertise_service", "call_service"):
        assert name in (ros1.__doc__ or "")
