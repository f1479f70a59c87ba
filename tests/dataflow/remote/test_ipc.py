"""The same-host fast path (transport ``ipc``): chosen by default on one host, gRPC when
asked or when ipc cannot work, tickets that cannot be forged, a reader that stops never
blocks the writer, and a peer killed leaves nothing behind and the other side working."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import threading
import time

import pytest
from support import wait_until
from support.remote import start_scart, stop_process

from dataflow import ConnPolicy, Deployer, InputPort, OutputPort, TaskContext
from dataflow.remote import connect
from dataflow.remote._proto import df as pb
from dataflow.transports import TransportError
from dataflow.transports import ipc as ipc_transport
from dataflow.transports.ipc import _wire as _ipc

DEPLOY_FAR = ["deploy", "support.remote:Pinger", "--name", "far", "--period", "0.01", "--heartbeat-ms", "200"]

pytestmark = pytest.mark.skipif(not _ipc.available(), reason="ipc needs Linux abstract sockets")


class Counter(TaskContext):
    out = OutputPort(int)


class Collector(TaskContext):
    inp = InputPort(int)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list[int] = []
        self.inp.add_data_callback(self._take)

    def _take(self, port: InputPort) -> None:
        for _ in range(10_000):
            status, value = port.read()
            if status.name != "NEW_DATA":
                return
            self.got.append(value)


@contextlib.contextmanager
def serving(sink_task: TaskContext):
    """Two deployers serving on one host (the second, with ``sink_task``, joins the first's
    name service): the system, the source task and the sink task."""
    d1, d2 = Deployer(), Deployer()
    src = d1.add(Counter("src"))
    sink = d2.add(sink_task)
    s1 = d1.serve("127.0.0.1:0")
    s2 = d2.serve("127.0.0.1:0", ns=s1.address)
    try:
        with connect(s1.address, timeout=5.0) as system:
            yield system, src, sink
    finally:
        s2.stop()
        s1.stop()


@pytest.fixture
def two():
    with serving(Collector("sink")) as ends:
        yield ends


def _transport(system, name: str) -> str:
    return wait_until(lambda: next((lk.transport for lk in system.links() if lk.name == name
                                    and lk.transport != "auto?"), None), timeout=10)


def test_one_host_takes_ipc_and_grpc_when_asked(two) -> None:
    system, src, sink = two
    system.connect_ports("src.out", "sink.inp", ConnPolicy.buffer(100), name="fast")
    assert _transport(system, "fast") == "ipc"
    for k in range(50):
        src.out.write(k)
    wait_until(lambda: len(sink.got) == 50, timeout=10, message=f"got {sink.got}")
    assert sink.got == list(range(50))  # in order, none lost (a burst: the link's thread sends most)
    src.out.write(50)  # and a lone write after it goes too
    wait_until(lambda: sink.got[-1:] == [50], timeout=10, message=f"got {sink.got[-3:]}")
    system.disconnect_link("fast")

    system.connect_ports("src.out", "sink.inp", ConnPolicy.buffer(100).with_(transport="grpc"), name="slow")
    assert _transport(system, "slow") == "grpc"
    src.out.write(99)
    wait_until(lambda: sink.got[-1:] == [99], timeout=10)

    seen: list[int] = []
    fast = system.component("src").subscribe("out", lambda e: seen.append(e.value), ConnPolicy.buffer(10))
    slow = system.component("src").subscribe("out", lambda e: None, ConnPolicy.data().with_(transport="shm"))
    both = system.component("src").subscribe("out", lambda e: None, ConnPolicy.data().with_(transport="grpc"))
    try:
        assert (fast.transport, slow.transport, both.transport) == ("ipc", "shm", "grpc")  # shm when asked, even small
        src.out.write(7)
        wait_until(lambda: seen == [7], timeout=10)
        assert fast.dropped == 0
    finally:
        for sub in (fast, slow, both):
            sub.close()


def test_another_host_falls_back_to_grpc_and_ipc_alone_says_why(two, monkeypatch) -> None:
    system, src, _ = two
    monkeypatch.setattr(ipc_transport, "host_id", lambda: "another-host")  # what the deployer hears from us
    seen: list[int] = []
    sub = system.component("src").subscribe("out", lambda e: seen.append(e.value), ConnPolicy.buffer(10))
    try:
        assert sub.transport == "grpc"
        src.out.write(3)
        wait_until(lambda: seen == [3], timeout=10)
    finally:
        sub.close()
    with pytest.raises(TransportError, match="transport ipc to src.out: the caller is on another host"):
        system.component("src").subscribe("out", lambda e: None, ConnPolicy.data().with_(transport="ipc"))


def test_a_ticket_cannot_be_guessed_and_the_socket_goes_with_its_server() -> None:
    deployer = Deployer()
    deployer.add(Counter("src"))
    server = deployer.serve("127.0.0.1:0")
    try:
        stub = connect(server.address)
        try:
            reply = stub._stub(server.address).OpenIpcReader(  # noqa: SLF001 - the wire, as a stranger sees it
                pb.OpenIpcReaderRequest(task="src", port="out", host_id=_ipc.host_id()), timeout=5)
        finally:
            stub.close()
        name = reply.ticket.socket
        assert f"@{name}" in _unix_sockets()  # abstract: no file anywhere
        with socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET) as forged:
            forged.settimeout(10)
            forged.connect("\0" + name)
            forged.send(os.urandom(16))
            assert forged.recv(100) == b""  # closed at once: no samples for a guessed ticket
        good, first = _ipc.connect(name, reply.ticket.secret)
        with good:
            hello = pb.SubscribeResponse.FromString(first)
            assert hello.heartbeat and hello.boot_id == server.boot_id
            with pytest.raises(_ipc.IpcUnavailable, match="closed the connection"):
                _ipc.connect(name, reply.ticket.secret)  # a ticket is good once
    finally:
        server.stop()
    assert f"@{name}" not in _unix_sockets()


def _unix_sockets() -> str:
    with open("/proc/net/unix") as table:
        return table.read()


def _shm() -> set[str]:
    """What is in /dev/shm, but Zenoh's own segments (``*.zenoh``: made and removed by Zenoh
    sessions of other processes, e.g. tests running alongside)."""
    names = os.listdir("/dev/shm") if os.path.isdir("/dev/shm") else []
    return {n for n in names if not n.endswith(".zenoh")}


def test_a_stopped_reader_never_blocks_the_writer_and_a_killed_one_leaves_nothing() -> None:
    """A reader process frozen (SIGSTOP) fills its socket: the writer keeps writing at its
    own pace (the samples beyond the policy's storage are dropped, counted); killed, its
    socket goes with it and the writer is unaffected."""
    before = _shm()
    deployer = Deployer()
    src = deployer.add(Counter("src"))
    server = deployer.serve("127.0.0.1:0")
    proc = _start_echo(server.address)
    try:
        src.out.write(0)
        wait_until(lambda: _readers(server) == 1, timeout=15, message="the echo never subscribed over ipc")
        os.kill(proc.pid, signal.SIGSTOP)
        start = time.monotonic()
        for k in range(20_000):  # far more than the socket holds
            src.out.write(k)
        took = time.monotonic() - start
        assert took < 20, f"20000 writes took {took:.1f} s: the writer was held up by a frozen reader"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        wait_until(lambda: _readers(server) == 0, timeout=10, message="the dead reader's socket stayed")
        for k in range(100):
            src.out.write(k)  # the writer goes on
    finally:
        stop_process(proc, signal.SIGKILL)
        server.stop()
    assert _shm() == before  # nothing was ever put in /dev/shm


def _start_echo(ns: str):
    import subprocess
    import sys

    from support.remote import subprocess_env

    return subprocess.Popen([sys.executable, "-m", "scart", "echo", "src.out", "--ns", ns, "--json"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=subprocess_env())


def _readers(server) -> int:
    from dataflow.transports.ipc._tickets import IpcServing

    serving = server._servicer.channels.serving_of(IpcServing)  # noqa: SLF001 - the connections it serves over ipc
    return 0 if serving is None or serving.server is None else serving.server.connections


class FloatSource(TaskContext):
    out = OutputPort(float)


def test_a_killed_sink_process_leaves_the_source_working() -> None:
    before = _shm()
    deployer = Deployer()
    src = deployer.add(FloatSource("src"))
    server = deployer.serve("127.0.0.1:0")
    procs = []
    try:
        sink, _ = start_scart([*DEPLOY_FAR, "--ns", server.address])
        procs.append(sink)
        with connect(server.address, timeout=5.0) as system:
            system.connect_ports("src.out", "far.input", ConnPolicy.data(), name="toFar")
            assert _transport(system, "toFar") == "ipc"
            src.out.write(1.0)
            sink.kill()
            sink.wait(timeout=10)
            for k in range(1000):
                src.out.write(float(k))  # never raises, never waits for the dead sink
            wait_until(lambda: next(lk for lk in system.links() if lk.name == "toFar").transport == "auto?",
                       timeout=10, message="the link never noticed its sink died")
            again, _ = start_scart([*DEPLOY_FAR, "--ns", server.address])
            procs.append(again)
            assert _transport(system, "toFar") == "ipc"  # back on the fast path by itself
            far = system.component("far")

            def crossed() -> bool:
                src.out.write(5.0)  # DATA: the newest is what counts; written until it shows
                return far.read("output")[1] == 5.0

            wait_until(crossed, timeout=15, message="nothing crossed again")
    finally:
        for proc in procs:
            stop_process(proc, signal.SIGKILL)
        server.stop()
    assert _shm() == before


class SlowCollector(Collector):
    """A sink that holds its first sample until the test lets it go (a reader behind)."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.go = threading.Event()

    def _take(self, port: InputPort) -> None:
        self.go.wait(10)
        super()._take(port)


def test_a_link_whose_sink_falls_behind_delivers_every_sample_in_order() -> None:
    with serving(SlowCollector("sink")) as (system, src, sink):
        try:
            system.connect_ports("src.out", "sink.inp", ConnPolicy.buffer(5000), name="behind")
            assert _transport(system, "behind") == "ipc"
            statuses = {src.out.write(k).name for k in range(3000)}  # the socket fills; the policy's queue keeps the rest
            assert statuses == {"WRITE_SUCCESS"}
            sink.go.set()
            wait_until(lambda: len(sink.got) == 3000, timeout=20, message=f"{len(sink.got)} arrived")
            assert sink.got == list(range(3000))  # in order, none lost, none twice
            assert next(lk.dropped for lk in system.links() if lk.name == "behind") == 0
        finally:
            sink.go.set()  # before the servers stop: never leave the sink's delivering thread waiting


class Floats(TaskContext):
    out = OutputPort(list[float])


def _raw_reader(server, task: str, port: str, policy: ConnPolicy):
    """A reader on the wire itself (it reads only when the test says): socket, first message."""
    from dataflow.remote import _convert as cv

    system = connect(server.address)
    try:
        reply = system._stub(server.address).OpenIpcReader(  # noqa: SLF001
            pb.OpenIpcReaderRequest(task=task, port=port, policy=cv.policy_to_msg(policy), host_id=_ipc.host_id(),
                                    heartbeat_ms=10_000), timeout=5)
    finally:
        system.close()
    return _ipc.connect(reply.ticket.socket, reply.ticket.secret)


def test_a_reader_that_falls_behind_gets_true_write_numbers_and_never_fails_the_writer() -> None:
    deployer = Deployer()
    src = deployer.add(Counter("src"))
    server = deployer.serve("127.0.0.1:0")
    try:
        sock, _ = _raw_reader(server, "src", "out", ConnPolicy.circular_buffer(5))  # keeps the newest
        with sock:
            statuses = {src.out.write(k).name for k in range(2000)}  # far more than the socket holds: it fills
            assert statuses == {"WRITE_SUCCESS"}  # a subscriber never makes the task's writes fail
            seen: list[int] = []
            sock.setblocking(True)
            for message in _ipc.messages_in(sock, 10.0):  # silence bound: a lost wake-up, not a slow run
                reply = pb.SubscribeResponse.FromString(message)
                seen += [sample.sequence for sample in reply.samples]
                if seen and seen[-1] == 2000:
                    break
            unsent = server._servicer.channels.served.all()[0].dropped  # noqa: SLF001 - what the deployer could not send
        assert seen == sorted(seen) and len(set(seen)) == len(seen)
        values_ok = all(1 <= s <= 2000 for s in seen)
        assert values_ok and seen[-1] == 2000  # each sample tagged with its own write number
        assert len(seen) + unsent == 2000  # and every write not delivered is counted, once
    finally:
        server.stop()


def test_samples_larger_than_a_frame_cross_whole() -> None:
    deployer = Deployer()
    src = deployer.add(Floats("big"))
    server = deployer.serve("127.0.0.1:0")
    got: list[list[float]] = []
    try:
        with connect(server.address, timeout=5.0) as system:
            sub = system.component("big").subscribe("out", lambda e: got.append(e.value), ConnPolicy.buffer(10))
            try:
                assert sub.transport == "ipc"
                sample = [float(i) for i in range(40_000)]  # ~360 KB encoded: six frames
                src.out.write(sample)
                src.out.write([1.0])
                wait_until(lambda: len(got) == 2, timeout=10, message=f"{len(got)} arrived")
                assert got[0] == sample and got[1] == [1.0] and sub.dropped == 0
            finally:
                sub.close()
    finally:
        server.stop()


def test_frames_reassemble_and_bad_ones_are_dropped_not_delivered() -> None:
    whole = _ipc.frames_of(b"x" * 10)
    parts = _ipc.frames_of(b"y" * (_ipc.CHUNK * 2 + 5))
    assert len(whole) == 1 and len(parts) == 3
    r = _ipc.Reassembler()
    assert r.feed(whole[0]) == b"x" * 10
    assert [r.feed(f) for f in parts[:2]] == [None, None] and r.feed(parts[2]) == b"y" * (_ipc.CHUNK * 2 + 5)
    assert r.feed(parts[0]) is None and r.feed(whole[0]) == b"x" * 10  # a message whose end never came
    assert r.feed(b"\x07junk") is None and r.feed(whole[0], truncated=True) is None
    assert r.dropped == 3
