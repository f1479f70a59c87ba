"""Named links: ``connect(..., name=)``, ``links()``, ``reroute()`` and ``disconnect_link()``,
in one deployer and across deployers; a reroute while samples flow loses none on the link
that stays, and the new input gets every sample written once it returns."""

from __future__ import annotations

import threading

import pytest

from dataflow import (
    ConnPolicy, DataflowError, Deployer, DeploymentError, FlowStatus, InputPort, NotFoundError, OutputPort, TaskContext,
)
from dataflow.remote import connect, serve_nameserver
from support import wait_until


class Counter(TaskContext):
    out = OutputPort(int)


class Collector(TaskContext):
    inp = InputPort(int, event=True)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list[int] = []
        self._lock = threading.Lock()

    def update_hook(self) -> None:
        for _ in range(100_000):
            flow, v = self.inp.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            with self._lock:
                self.got.append(v)

    def seen(self) -> list[int]:
        with self._lock:
            return list(self.got)


@pytest.fixture
def deployer():
    d = Deployer()
    d.add(Counter("src"))
    for name in ("a", "b", "c"):
        d.add(Collector(name))
    d.configure_all()
    d.start_all()
    try:
        yield d
    finally:
        d.stop_all()
        d.cleanup_all()


def test_links_are_named_listed_and_removed_by_name(deployer: Deployer) -> None:
    deployer.connect("src.out", "a.inp", ConnPolicy.buffer(16), name="l1")
    deployer.connect("src.out", "b.inp")
    links = {lk.name: lk for lk in deployer.links()}
    assert set(links) == {"l1", "src.out->b.inp"}
    assert (links["l1"].sink, links["l1"].policy, links["l1"].transport) == ("a.inp", "buffer:16", "local")
    deployer.task("src").port("out").write(1)
    assert {lk.name: lk.samples for lk in deployer.links()}["l1"] == 1
    with pytest.raises(DeploymentError, match="a link named 'l1' exists already"):
        deployer.connect("src.out", "c.inp", name="l1")
    with pytest.raises(DeploymentError, match="link name"):
        deployer.connect("src.out", "c.inp", name="no spaces")
    with pytest.raises(NotFoundError, match="no link 'l9'; links: l1, src.out->b.inp"):
        deployer.reroute("l9", "c.inp")
    link = deployer.find_link("l1")
    assert deployer.disconnect(link.source, link.sink)
    assert [lk.name for lk in deployer.links()] == ["src.out->b.inp"]


def test_names_stay_with_made_links_only(deployer: Deployer) -> None:
    """A refused connection or reroute keeps no name, a link gone loses its name, and an
    observer's connection on the source does not get in the way."""
    from dataflow import PortTypeError

    class Text(TaskContext):
        inp = InputPort(str)

    deployer.add(Text("t"))
    probe: InputPort[int] = InputPort(int, "probe")
    deployer.task("src").port("out").connect_to(probe)  # a subscription-like observer
    with pytest.raises(PortTypeError):
        deployer.connect("src.out", "t.inp", name="N")
    deployer.connect("src.out", "a.inp", name="N")  # the name was not kept by the refused one
    with pytest.raises(PortTypeError):
        deployer.reroute("N", "t.inp")
    assert deployer.find_link("N").sink == "a.inp"
    assert deployer.reroute("N", "b.inp").sink == "b.inp"
    deployer.task("b").port("inp").disconnect()  # gone without the deployer
    assert deployer.links() == []
    deployer.connect("src.out", "b.inp")
    assert [lk.name for lk in deployer.links()] == ["src.out->b.inp"]  # not the old name back
    with pytest.raises(DeploymentError, match="link name"):
        deployer.connect("src.out", "c.inp", name="src.out->b.inp")  # default names are apart


def test_reroute_while_running_loses_no_sample(deployer: Deployer) -> None:
    deployer.connect("src.out", "a.inp", ConnPolicy.buffer(100_000), name="moving")
    deployer.connect("src.out", "b.inp", ConnPolicy.buffer(100_000), name="staying")
    out = deployer.task("src").port("out")
    a, b, c = (deployer.task(n) for n in "abc")
    n = 20_000
    rerouted = threading.Event()

    def write() -> None:
        for i in range(n):
            out.write(i)
            if i == n // 2:
                rerouted.wait(10)  # the reroute happens while the writer is mid-stream

    writer = threading.Thread(target=write, name="test-writer")
    writer.start()
    try:
        wait_until(lambda: len(a.seen()) > 100, timeout=10, message="nothing flows")
        moved = deployer.reroute("moving", "c.inp")
        at = out.last_sample()[0]  # samples written before the reroute returned
        rerouted.set()
        assert (moved.name, moved.sink, moved.policy) == ("moving", "c.inp", "buffer:100000")
    finally:
        rerouted.set()
        writer.join(30)
    wait_until(lambda: b.seen()[-1:] == [n - 1] and c.seen()[-1:] == [n - 1], timeout=20,
               message="the samples did not all arrive")
    assert b.seen() == list(range(n))  # the link that stays: every sample, in order
    # the moved one: the new input has every sample written once the reroute returned (what the
    # old input had buffered but not read when it was disconnected is its own, as in RTT)
    assert set(range(at, n)) <= set(c.seen()) and c.seen() == sorted(c.seen()) and at < n
    assert {lk.name: lk.sink for lk in deployer.links()} == {"moving": "c.inp", "staying": "b.inp"}


def test_links_across_deployers_through_the_name_service() -> None:
    ns = serve_nameserver("127.0.0.1:0")
    d1, d2 = Deployer(), Deployer()
    d1.add(Counter("src"))
    d1.add(Collector("local"))
    d1.add(Collector("local2"))
    d2.add(Collector("far"))
    servers = []
    try:
        for d in (d1, d2):
            d.configure_all()
            d.start_all()
            servers.append(d.serve("127.0.0.1:0", ns=ns.address))
        with connect(ns.address) as system:
            system.connect_ports("src.out", "far.inp", ConnPolicy.buffer(64), name="toFar")
            system.connect_ports("src.out", "local.inp")
            # two processes' worth of deployers on one host: the link takes the fast path
            links = wait_until(lambda: all(lk.transport != "auto?" for lk in system.links())
                               and {lk.name: lk for lk in system.links()}, timeout=10)
            assert links["toFar"].transport == "ipc" and links["src.out->local.inp"].transport == "local"
            d1.task("src").port("out").write(5)
            wait_until(lambda: d2.task("far").seen() == [5], timeout=10, message="nothing crossed")
            with pytest.raises(DataflowError, match="src.out feeds local.inp already"):
                system.reroute("toFar", "local.inp")  # never take over another link
            moved = system.reroute("toFar", "local2.inp")
            assert (moved.sink, moved.transport, moved.policy) == ("local2.inp", "local", "buffer:64")
            assert {lk.name for lk in system.links()} == {"toFar", "src.out->local.inp"}
            assert system.disconnect_link("toFar")
            assert [lk.name for lk in system.links()] == ["src.out->local.inp"]
            with pytest.raises(NotFoundError, match="no link 'toFar'"):
                system.reroute("toFar", "far.inp")
    finally:
        for s in servers:
            s.stop()
        for d in (d1, d2):
            d.stop_all()
            d.cleanup_all()
        ns.stop()


def test_a_link_stream_carries_samples_checked_once_and_reports_what_it_lost() -> None:
    """The ``Link`` RPC as a foreign writer end speaks it: frames holding several samples
    (joined frames are one), a sample of another type refused alone and counted, a jump in
    the write numbers counted, and every report telling the writer end what it has had."""
    import grpc

    from scart_wire import codec
    from dataflow.remote import _convert as cv
    from dataflow.remote._proto import df as pb
    from dataflow.remote._proto import df_grpc

    d = Deployer()
    sink = d.add(Collector("sink"))
    d.configure_all()
    d.start_all()
    server = d.serve("127.0.0.1:0")

    def frame(*samples: tuple[int, object]) -> object:
        return pb.LinkRequest(samples=[pb.Sample(value=codec.encode(v), sequence=n) for n, v in samples])

    try:
        hello = pb.LinkHello(task="sink", port="inp", policy=cv.policy_to_msg(ConnPolicy.buffer(100)),
                             channel="test/1", after=0, boot_id="b1", source="src.out", type_name="int64")

        def frames():
            yield pb.LinkRequest(hello=hello)
            yield frame(*[(k + 1, k) for k in range(5)])
            yield frame((6, "five"))  # another type: refused alone, the link goes on
            yield frame((7, 5), (9, 6))  # 8 never came
            yield pb.LinkRequest(closing=True)

        with grpc.insecure_channel(server.address) as channel:
            reports = list(df_grpc.DeployerServiceStub(channel).Link(frames(), timeout=10))
        assert reports[0].known is False and not reports[0].refused
        assert reports[-1].final and reports[-1].last == 9 and reports[-1].lost == 2  # "five" and write 8
        assert sink.seen() == list(range(7))
    finally:
        server.stop()
        d.stop_all()
        d.cleanup_all()


def test_a_link_of_another_type_is_refused_at_connect_naming_both_types() -> None:
    from dataflow import PortTypeError

    class Text(TaskContext):
        inp = InputPort(str)

    d1, d2 = Deployer(), Deployer()
    d1.add(Counter("src"))
    d2.add(Text("t"))
    d2.add(Counter("other"))
    s1 = d1.serve("127.0.0.1:0")
    s2 = d2.serve("127.0.0.1:0", ns=s1.address)
    try:
        with connect(s1.address, timeout=5.0) as system:
            with pytest.raises(PortTypeError, match=r"src.out \(int64\) to t.inp \(string\): types differ \[SCART-T003\]"):
                system.connect_ports("src.out", "t.inp")
            with pytest.raises(DataflowError, match=r"other.out is an output port.*\[SCART-T002\]"):
                system.connect_ports("src.out", "other.out")
            with pytest.raises(NotFoundError, match="t has no port 'nope'"):
                system.connect_ports("src.out", "t.nope")
            assert system.links() == []  # nothing was linked
    finally:
        s2.stop()
        s1.stop()

