"""Streams: a port joined to a named topic of a transport (``ConnPolicy.topic``,
``Deployer.stream``, ``scart stream``, ``<scart:stream>``). Here on Zenoh, with real
sessions on Unix sockets: an output port's stream publishes, another deployer's input
port's stream is fed from the same key under its own policy, every write is either
delivered or counted, both are listed with the links, and a stream is refused clearly
where it cannot be made."""

from __future__ import annotations

import threading

import pytest
from support import wait_until

from dataflow import ConnPolicy, DataflowError, Deployer, FlowStatus, InputPort, OutputPort, TaskContext
from dataflow.transports import TransportError

zenoh = pytest.importorskip("dataflow.transports.zenoh")
pytest.importorskip("zenoh")


class Source(TaskContext):
    out = OutputPort(int)


class Slow(TaskContext):
    """Reads one sample each time the test lets it (a sink behind its writer)."""

    inp = InputPort(int, le=1000)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list[int] = []
        self.lock = threading.Lock()

    def take_all(self) -> list[int]:
        for _ in range(100_000):
            flow, value = self.inp.read()
            if flow is not FlowStatus.NEW_DATA:
                break
            with self.lock:
                self.got.append(value)
        return self.got


@pytest.fixture
def sessions(tmp_path):
    here = f"unixsock-stream/{tmp_path}/a.sock"
    a = zenoh.open_session(listen=[here])
    b = zenoh.open_session(connect=[here], listen=[f"unixsock-stream/{tmp_path}/b.sock"])
    try:
        yield a, b
    finally:
        b.close()
        a.close()


def test_a_stream_on_zenoh_delivers_or_counts_every_write(sessions) -> None:
    a, b = sessions
    writer, reader = Deployer(), Deployer()
    src = writer.add(Source("src"))
    sink = reader.add(Slow("sink"))
    zenoh.use_session(a)
    try:
        out = writer.stream("src.out", ConnPolicy.data().with_(transport="zenoh", topic="lab/counter"))
    finally:
        zenoh.use_session(None)
    zenoh.use_session(b)
    try:
        into = reader.stream("sink.inp", ConnPolicy.buffer(10).with_(transport="zenoh", topic="lab/counter"),
                             name="counter-in")
    finally:
        zenoh.use_session(None)
    try:
        assert (out.kind, out.source, out.sink) == ("stream", "src.out", "zenoh:lab/counter")
        assert (into.name, into.source, into.sink) == ("counter-in", "zenoh:lab/counter", "sink.inp")
        probes = iter(range(-1, -100_000, -1))  # distinct until Zenoh matched: -j is the j-th write
        wait_until(lambda: src.out.write(next(probes)) and sink.take_all(), timeout=15, message="Zenoh never matched")
        first = len(sink.take_all())
        before = -sink.take_all()[0] - 1  # written before the reader was there: never part of its stream
        for k in range(1, 101):  # a burst into a buffer of 10 that nobody reads meanwhile
            src.out.write(k)
        wait_until(lambda: _listed(reader, "counter-in").samples >= 100 + first, timeout=10,
                   message=f"{_listed(reader, 'counter-in')}")
        src.out.write(2000)  # out of the input port's bounds: refused, counted
        # Zenoh drops rather than wait when its queue is full (never the writer's thread):
        # written until one arrives, each write still delivered or counted
        wait_until(lambda: src.out.write(5) and sink.take_all()[-1:] == [5], timeout=10)
        written = src.out.last_sample()[0]  # every write: delivered, or counted (once the last ones arrived)
        wait_until(lambda: len(sink.take_all()) + _listed(reader, "counter-in").dropped == written - before,
                   timeout=10, message=f"{len(sink.take_all())} delivered, {_listed(reader, 'counter-in')}, "
                                       f"{written - before} written")
        listed = _listed(reader, "counter-in")
        assert listed.dropped >= 90 and listed.transport == "zenoh"
        assert _listed(writer, out.name).dropped == 0
    finally:
        reader.unstream("counter-in")
        writer.unstream(out.name)
    assert writer.links() == [] and reader.links() == []


def _listed(deployer: Deployer, name: str):
    return next(lk for lk in deployer.links() if lk.name == name)


def test_a_stream_is_refused_clearly_where_it_cannot_be_made() -> None:
    d = Deployer()
    d.add(Source("src"))
    with pytest.raises(DataflowError, match="a stream needs a topic"):
        d.stream("src.out", ConnPolicy.data().with_(transport="zenoh"))
    with pytest.raises(TransportError, match="transport 'grpc' carries links and subscriptions, not topics"):
        d.stream("src.out", ConnPolicy.data().with_(transport="grpc", topic="x"))
    with pytest.raises(TransportError, match="no session in this process"):
        d.stream("src.out", ConnPolicy.data().with_(transport="zenoh", topic="x"))
    with pytest.raises(TransportError, match="Zenoh topic 'a/\\*'"):
        d.stream("src.out", ConnPolicy.data().with_(transport="zenoh", topic="a/*"))
    assert d.links() == [] and d.task("src").port("out")._fanout is None  # nothing left behind
