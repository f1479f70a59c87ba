"""Ports and connections: RTT 2.9 FlowStatus/WriteStatus semantics, policies, fan-out/in."""

from __future__ import annotations

import pytest

from dataflow import (
    BufferPolicy,
    ConnPolicy,
    ConnType,
    DataflowError,
    FlowStatus,
    InputPort,
    LockPolicy,
    OutputPort,
    PortTypeError,
    WriteStatus,
)

NO, OLD, NEW = FlowStatus.NO_DATA, FlowStatus.OLD_DATA, FlowStatus.NEW_DATA
OK, FAIL, NC = WriteStatus.WRITE_SUCCESS, WriteStatus.WRITE_FAILURE, WriteStatus.NOT_CONNECTED
LOCKS = [LockPolicy.LOCK_FREE, LockPolicy.LOCKED, LockPolicy.UNSYNC]


def pair(policy: ConnPolicy | None = None, type_: type = int):
    out, inp = OutputPort(type_, "out"), InputPort(type_, "in")
    conn = out.connect_to(inp, policy if policy is not None else ConnPolicy())
    return out, inp, conn


def test_policy_defaults_pin_rtt_init_asymmetry():
    assert ConnPolicy().init is False
    assert ConnPolicy.data().init is True
    assert ConnPolicy.buffer(4).init is False
    assert ConnPolicy.circular_buffer(4).init is False
    p = ConnPolicy()
    assert (p.type, p.size, p.lock_policy, p.buffer_policy) == (
        ConnType.DATA, 0, LockPolicy.LOCK_FREE, BufferPolicy.PER_CONNECTION)


def test_policy_frozen_parse_and_str():
    for text in ("data", "buffer:8", "circular:3"):
        assert str(ConnPolicy.parse(text)) == text
    assert ConnPolicy.parse("buffer:8") == ConnPolicy.buffer(8)
    with pytest.raises(ValueError):
        ConnPolicy.parse("queue:3")
    with pytest.raises(ValueError):
        ConnPolicy.buffer(0)
    with pytest.raises(Exception):
        ConnPolicy().size = 3  # type: ignore[misc]


def test_unconnected_write_and_read():
    out, inp = OutputPort(int, "o"), InputPort(int, "i")
    assert out.write(1) is NC
    assert out.last_written_value() == 1
    assert inp.read() == (NO, None)
    assert not out.connected() and not inp.connected()


@pytest.mark.parametrize("lock", LOCKS)
def test_data_flow_status_sequence(lock):
    out, inp, conn = pair(ConnPolicy.data(lock_policy=lock))
    assert inp.read() == (NO, None)
    assert out.write(1) is OK
    assert inp.read() == (NEW, 1)
    assert inp.read() == (OLD, 1)
    out.write(2)
    out.write(3)
    assert inp.read() == (NEW, 3)
    assert conn.dropped == 1  # 2 was overwritten unread


@pytest.mark.parametrize("lock", LOCKS)
def test_buffer_full_rejects_new_sample(lock):
    out, inp, conn = pair(ConnPolicy.buffer(2, lock_policy=lock))
    assert [out.write(i) for i in range(3)] == [OK, OK, FAIL]
    assert conn.dropped == 1
    assert inp.read() == (NEW, 0)
    assert inp.read() == (NEW, 1)
    assert inp.read() == (OLD, 1)


@pytest.mark.parametrize("lock", LOCKS)
def test_circular_buffer_full_drops_oldest(lock):
    out, inp, conn = pair(ConnPolicy.circular_buffer(2, lock_policy=lock))
    assert [out.write(i) for i in range(4)] == [OK] * 4
    assert conn.dropped == 2
    assert inp.read() == (NEW, 2)
    assert inp.read() == (NEW, 3)
    assert inp.read() == (OLD, 3)


def test_buffer_never_read_is_no_data():
    _, inp, _ = pair(ConnPolicy.buffer(3))
    assert inp.read() == (NO, None)


def test_read_newest_skips_to_last():
    out, inp, conn = pair(ConnPolicy.buffer(5))
    for i in range(4):
        out.write(i)
    assert inp.read_newest() == (NEW, 3)
    assert inp.read_newest() == (OLD, 3)
    assert conn.dropped == 3


@pytest.mark.parametrize("policy", [ConnPolicy.data(), ConnPolicy.buffer(3), ConnPolicy.circular_buffer(3)])
def test_clear_gives_no_data_until_next_write(policy):
    out, inp, _ = pair(policy)
    out.write(1)
    inp.clear()
    assert inp.read() == (NO, None)
    out.write(2)
    assert inp.read() == (NEW, 2)


def test_init_data_seeds_new_connection():
    out, inp = OutputPort(int, "o"), InputPort(int, "i")
    out.write(7)
    out.connect_to(inp, ConnPolicy.data())
    assert inp.read() == (NEW, 7)


@pytest.mark.parametrize("policy", [ConnPolicy(), ConnPolicy.buffer(3), ConnPolicy.circular_buffer(3)])
def test_no_init_for_bare_and_buffers(policy):
    out, inp = OutputPort(int, "o"), InputPort(int, "i")
    out.write(7)
    out.connect_to(inp, policy)
    assert inp.read() == (NO, None)


def test_init_buffer_when_asked():
    out, inp = OutputPort(int, "o"), InputPort(int, "i")
    out.write(7)
    out.connect_to(inp, ConnPolicy.buffer(3, init=True))
    assert inp.read() == (NEW, 7)


def test_fan_out_each_reader_own_buffer():
    out = OutputPort(int, "o")
    fast, slow = InputPort(int, "fast"), InputPort(int, "slow")
    out.connect_to(fast, ConnPolicy.buffer(10))
    c_slow = out.connect_to(slow, ConnPolicy.buffer(2))
    statuses = [out.write(i) for i in range(4)]
    assert statuses == [OK, OK, FAIL, FAIL]  # the full buffer is reported
    assert [fast.read()[1] for _ in range(4)] == [0, 1, 2, 3]
    assert [slow.read() for _ in range(3)] == [(NEW, 0), (NEW, 1), (OLD, 1)]
    assert c_slow.dropped == 2
    assert out.connection_count() == 2


def test_fan_in_drains_current_then_others_in_order():
    a, b = OutputPort(int, "a"), OutputPort(int, "b")
    inp = InputPort(int, "in")
    a.connect_to(inp, ConnPolicy.buffer(5))
    b.connect_to(inp, ConnPolicy.buffer(5))
    a.write(1)
    b.write(10)
    b.write(11)
    a.write(2)
    got = [inp.read() for _ in range(5)]
    assert got == [(NEW, 1), (NEW, 2), (NEW, 10), (NEW, 11), (OLD, 11)]
    assert inp.connection_count() == 2


def test_per_input_port_storage_merges_writers():
    a, b = OutputPort(int, "a"), OutputPort(int, "b")
    inp = InputPort(int, "in")
    pol = ConnPolicy.buffer(5, buffer_policy=BufferPolicy.PER_INPUT_PORT)
    ca, cb = a.connect_to(inp, pol), b.connect_to(inp, pol)
    assert ca.storage is cb.storage
    a.write(1), b.write(2), a.write(3)
    assert [inp.read()[1] for _ in range(3)] == [1, 2, 3]


def test_per_output_port_storage_readers_compete():
    out = OutputPort(int, "o")
    r1, r2 = InputPort(int, "r1"), InputPort(int, "r2")
    pol = ConnPolicy.buffer(5, buffer_policy=BufferPolicy.PER_OUTPUT_PORT)
    out.connect_to(r1, pol), out.connect_to(r2, pol)
    for i in range(3):
        out.write(i)
    assert [r1.read()[1], r2.read()[1], r1.read()[1]] == [0, 1, 2]


def test_shared_storage_and_policy_mismatch():
    out = OutputPort(int, "o")
    r1, r2 = InputPort(int, "r1"), InputPort(int, "r2")
    shared = ConnPolicy.buffer(4, buffer_policy=BufferPolicy.SHARED)
    c1, c2 = out.connect_to(r1, shared), out.connect_to(r2, shared)
    assert c1.storage is c2.storage
    r3 = InputPort(int, "r3")
    with pytest.raises(DataflowError):
        out.connect_to(r3, ConnPolicy.buffer(8, buffer_policy=BufferPolicy.SHARED))


def test_connect_idempotent_disconnect_and_reconnect():
    out, inp, conn = pair(ConnPolicy.data())
    assert out.connect_to(inp, ConnPolicy.buffer(3)) is conn
    assert out.connection_count() == 1
    out.disconnect(inp)
    assert not out.connected() and not inp.connected()
    assert out.write(1) is NC
    assert inp.read() == (NO, None)
    out.disconnect(inp)  # idempotent
    conn2 = out.connect_to(inp, ConnPolicy.buffer(3))
    assert conn2 is not conn and out.write(2) is OK
    assert inp.read() == (NEW, 2)
    inp.disconnect()
    assert not out.connected()
    conn2.close()


def test_wrong_types_refused_with_names():
    out, inp = OutputPort(int, "o"), InputPort(str, "i")
    with pytest.raises(PortTypeError) as err:
        out.connect_to(inp)
    assert "o" in str(err.value) and "int64" in str(err.value) and "string" in str(err.value)
    f = OutputPort(float, "f")
    with pytest.raises(PortTypeError, match="float64"):
        f.write("3.0")
    with pytest.raises(PortTypeError):
        f.write(True)
    assert f.write(3) is NC and f.last_written_value() == 3.0
    lst = OutputPort(list[float], "l")
    with pytest.raises(PortTypeError):
        lst.write([1.0, "x"])
    assert lst.write((1, 2.0)) is NC and lst.last_written_value() == [1.0, 2.0]
    with pytest.raises(DataflowError):
        out.connect_to(OutputPort(int, "o2"))  # type: ignore[arg-type]


def test_data_callback_in_writer_thread_not_for_rejected_write():
    out, inp, _ = pair(ConnPolicy.buffer(1))
    seen = []
    cb = seen.append
    inp.add_data_callback(cb)
    assert out.write(1) is OK
    assert out.write(2) is FAIL
    assert seen == [inp]
    inp.remove_data_callback(cb)
    inp.read()
    out.write(3)
    assert seen == [inp]


def test_raising_callback_does_not_break_writer():
    out, inp, _ = pair(ConnPolicy.data())

    def bad(_):
        raise RuntimeError("boom")

    inp.add_data_callback(bad)
    assert out.write(1) is OK
    assert inp.read() == (NEW, 1)


def test_port_attributes():
    inp = InputPort(list[float], "cmd", doc="set-points", event=True)
    assert (inp.name, inp.type, inp.type_name, inp.doc, inp.task, inp.is_input, inp.event) == (
        "cmd", list[float], "float64[]", "set-points", None, True, True)
    assert OutputPort(float).is_input is False


def test_non_mandatory_full_buffer_does_not_fail_the_write():
    out = OutputPort(int, "o")
    a, b = InputPort(int, "a"), InputPort(int, "b")
    out.connect_to(a, ConnPolicy.buffer(1).with_(mandatory=False))
    cb = out.connect_to(b, ConnPolicy.buffer(5))
    assert [out.write(i) for i in range(3)] == [OK, OK, OK]
    assert out.connections()[0].dropped == 2 and cb.dropped == 0
    assert ConnPolicy().mandatory is True


def test_connecting_another_writer_keeps_the_current_channel():
    """A port that holds data keeps answering OLD_DATA when an unrelated writer connects."""
    a, b, c = OutputPort(float, name="a"), OutputPort(float, name="b"), OutputPort(float, name="c")
    inp = InputPort(float, name="in")
    a.connect_to(inp, ConnPolicy.data())
    b.connect_to(inp, ConnPolicy.data())
    b.write(1.0)
    assert inp.read() == (FlowStatus.NEW_DATA, 1.0)
    c.connect_to(inp, ConnPolicy.data())
    assert inp.read() == (FlowStatus.OLD_DATA, 1.0)
    a.disconnect(inp)
    assert inp.read() == (FlowStatus.OLD_DATA, 1.0)
    b.disconnect(inp)
    assert inp.read() == (FlowStatus.NO_DATA, None)


def test_closing_an_old_connection_leaves_the_newer_one():
    out, inp = OutputPort(float, name="out"), InputPort(float, name="in")
    old = out.connect_to(inp, ConnPolicy.data())
    out.disconnect(inp)
    out.connect_to(inp, ConnPolicy.buffer(2))
    old.close()
    assert out.connected() and out.write(1.0) is WriteStatus.WRITE_SUCCESS


def test_a_connection_can_be_given_its_own_storage_for_its_policy() -> None:
    """A remote subscriber's inbox is the connection's storage (made for its policy);
    one made for another policy, or for a shared storage, is refused."""
    from dataflow.buffers import make_storage
    from dataflow.policy import BufferPolicy

    out, inp = OutputPort(int, name="o"), InputPort(int, name="i")
    policy = ConnPolicy.buffer(4)
    storage = make_storage(policy)
    conn = out.connect_to(inp, policy, storage=storage)
    assert conn.storage is storage
    out.write(7)
    assert storage.size() == 1 and inp.read() == (FlowStatus.NEW_DATA, 7)
    other = InputPort(int, name="j")
    with pytest.raises(DataflowError, match="must be made for"):
        out.connect_to(other, ConnPolicy.buffer(8), storage=make_storage(policy))
    shared = ConnPolicy.buffer(4).with_(buffer_policy=BufferPolicy.SHARED)
    with pytest.raises(DataflowError, match="PER_CONNECTION"):
        out.connect_to(other, shared, storage=make_storage(shared))
