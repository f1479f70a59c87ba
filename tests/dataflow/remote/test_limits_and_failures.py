"""The remote data-flow layer at its limits and on failures: batching by size, duplicate
names at run time, no hidden server connections, observer failures, server threads that
end, retries of idempotent calls only, refused names on heartbeat, ``scart deploy``
without ``--name``, policy validation, decode errors and the subscribe contract.
Real gRPC servers on 127.0.0.1:0; conditions are awaited with deadlines."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator

import grpc
import pytest

from dataflow import ConnPolicy, Deployer, OutputPort, SlaveActivity, TaskContext, WriteStatus
from dataflow.remote import RemoteTimeoutError, RemoteTypeError, UnavailableError, connect, local_system
from scart_wire import codec
from dataflow.remote import _convert as cv
from dataflow.remote import _proto
from dataflow.remote import _subscription
from scart_wire import rpc
from dataflow.remote._proto import DEPLOYER_SERVICE, DEPLOYER_SERVICE_NAME, NAMING_SERVICE_NAME
from dataflow.remote._proto import df as pb
from dataflow.remote.client import GrpcSystem
from dataflow.remote.naming import NameRegistry, NamingServicer, serve_nameserver

from support import free_port, wait_until
from support.remote import Pinger, start_scart, stop_process

N_FLOATS = 20_000


class Big(TaskContext):
    """An output port of large float lists."""

    big = OutputPort(list[float], doc="large samples")

    def __init__(self, name: str = "big") -> None:
        super().__init__(name)


def _started(deployer: Deployer, task: TaskContext) -> TaskContext:
    deployer.add(task)
    task.set_activity(SlaveActivity())
    task.configure()
    task.start()
    return task


@pytest.fixture
def served() -> Iterator[tuple[Deployer, Pinger, object]]:
    deployer = Deployer()
    task = _started(deployer, Pinger("p"))
    server = deployer.serve("127.0.0.1:0")
    try:
        yield deployer, task, server
    finally:
        server.stop()
        deployer.stop_all()
        deployer.cleanup_all()


# ---- 1. batches bounded by bytes ----------------------------------------------------------
def test_buffered_subscription_of_large_samples_loses_nothing_silently() -> None:
    deployer = Deployer()
    task = _started(deployer, Big())
    server = deployer.serve("127.0.0.1:0")
    got: list[int] = []
    try:
        with connect(server.address, timeout=5.0) as system:
            sub = system.component("big").subscribe("big", lambda e: got.append(e.sequence), ConnPolicy.buffer(200))
            for i in range(150):  # quick writes: the server finds them all pending at once
                task.big.write([float(i)] * N_FLOATS)
            wait_until(lambda: sub.delivered + sub.dropped >= 150, timeout=30, message="samples vanished")
            assert sub.delivered + sub.dropped == 150
            assert sub.reconnects == 0 and sub.connected
            assert got == sorted(got)
            # one sample larger than a gRPC message on its own: delivered too (in parts), none lost
            before, delivered = sub.dropped, sub.delivered
            task.big.write([1.0] * (rpc.MAX_MESSAGE_BYTES // 8 + 1000))
            task.big.write([2.0])
            wait_until(lambda: sub.delivered == delivered + 2 and sub.dropped == before, timeout=10)
            assert sub.reconnects == 0 and sub.connected
    finally:
        server.stop()
        deployer.stop_all()


# ---- 2. a duplicate added at run time does not break the embedded name service -----------
def test_duplicate_name_added_at_run_time_keeps_name_service_serving(caplog) -> None:
    home = Deployer()
    _started(home, Pinger("a"))
    server = home.serve("127.0.0.1:0")
    other = Deployer()
    _started(other, Pinger("b"))
    joined = other.serve("127.0.0.1:0", ns=server.address)
    try:
        caplog.set_level(logging.WARNING, logger="dataflow.remote.server")
        _started(home, Pinger("b"))  # the same name, now also in the embedded name service's deployer
        _started(home, Pinger("c"))
        with connect(server.address, timeout=5.0) as system:
            assert system.component_names() == ["a", "b", "c"]
            assert system.resolve("b", fresh=True) == joined.address
            assert system.component("c").state == "RUNNING"
        assert server.refused_names == ["b"] and server.refresh_names() == ["b"]
        warning = " ".join(r.getMessage() for r in caplog.records)
        assert "'b'" in warning and joined.address in warning and server.address in warning
    finally:
        joined.stop()
        server.stop()
        for d in (home, other):
            d.stop_all()


# ---- 3. remote write/read leave no hidden connection ---------------------------------------
def test_failed_write_and_reads_leave_no_connection(served) -> None:
    _, task, server = served
    with connect(server.address, timeout=5.0) as system:
        proxy = system.component("p")
        with pytest.raises(RemoteTypeError):
            proxy.write("input", "not a float")
        assert task.input.connection_count() == 0
        assert proxy.read("output")[0].name == "NO_DATA"
        task.output.write(1.0)
        flow, value, seq1, _ = proxy.read_sample("output")
        assert (flow.name, value) == ("NEW_DATA", 1.0)
        task.output.write(2.0)
        flow, value, seq2, stamp = proxy.read_sample("output")
        assert (flow.name, value, seq2) == ("NEW_DATA", 2.0, seq1 + 1) and stamp > 0
        assert proxy.read_sample("output")[0].name == "OLD_DATA"
        assert task.output.connection_count() == 0 and task.ticks.connection_count() == 0
        assert proxy.write("input", 3.0) is WriteStatus.WRITE_SUCCESS
        ports = proxy.ports()
        assert ports["input"].connections == 0 and ports["output"].connections == 0


def test_reads_and_polling_see_the_same_object_written_again(served) -> None:
    """A task writing one constant object every cycle still produces new samples."""
    _, task, server = served
    same = 1.5
    with connect(server.address, timeout=5.0) as system:
        proxy = system.component("p")
        task.output.write(same)
        _, _, seq1, _ = proxy.read_sample("output")
        assert proxy.read_sample("output")[0].name == "OLD_DATA"
        task.output.write(same)
        flow, value, seq2, _ = proxy.read_sample("output")
        assert (flow.name, value, seq2) == ("NEW_DATA", same, seq1 + 1)
        got: list[float] = []
        sub = proxy.subscribe("output", lambda ev: got.append(ev.value), period=0.01)
        try:
            for n in range(1, 4):  # bounded: three writes of the same object, each seen
                task.output.write(same)
                wait_until(lambda n=n: len(got) >= n, timeout=10, message=f"poll {n} not delivered")
        finally:
            sub.close()


# ---- 4. in-process subscription survives its observer ---------------------------------------
def test_local_subscription_survives_observer_exception_and_stamps_on_store() -> None:
    deployer = Deployer()
    task = _started(deployer, Pinger("p"))
    system = local_system(deployer)
    events = []
    release = threading.Event()

    def observer(event) -> None:
        events.append(event)
        if len(events) == 1:
            release.wait(10)
            raise RuntimeError("observer bug")

    try:
        sub = system.component("p").subscribe("output", observer, ConnPolicy.buffer(10))
        task.output.write(1.0)
        wait_until(lambda: events, timeout=5)
        task.output.write(2.0)  # stored while the observer is busy
        stored_by = time.time()
        release.set()
        wait_until(lambda: len(events) >= 2, timeout=5, message="the subscription died with its observer")
        assert sub.connected
        assert events[1].value == 2.0 and events[1].sequence == 2
        assert events[1].source_time <= stored_by
        task.output.write(3.0)
        wait_until(lambda: len(events) >= 3, timeout=5)
    finally:
        system.close()
        deployer.stop_all()


# ---- 5. servers end their worker threads -------------------------------------------------
def _rpc_threads() -> set[threading.Thread]:
    return {t for t in threading.enumerate() if t.name.startswith("scart-rpc")}  # rpc.THREAD_PREFIX


def test_servers_end_their_worker_threads() -> None:
    before = _rpc_threads()
    deployer = Deployer()
    _started(deployer, Pinger("p"))
    ns = serve_nameserver("127.0.0.1:0")
    try:
        server = deployer.serve("127.0.0.1:0", ns=ns.address)
        try:
            with connect(ns.address, timeout=5.0) as system:
                assert system.component("p").get_property("gain") == 1.0
            assert _rpc_threads() - before, "the servers should have started workers"
        finally:
            server.stop()
    finally:
        ns.stop()
        deployer.stop_all()
    wait_until(lambda: not (_rpc_threads() - before), timeout=10, message=f"left: {_rpc_threads() - before}")


# ---- 6. non-idempotent calls are not retried ------------------------------------------------
class _Flaky:
    """A DeployerService whose every method aborts UNAVAILABLE after receiving the request
    (ReadPort answers NO_DATA); counts calls per method."""

    def __init__(self) -> None:
        self.calls: dict[str, int] = {}

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        streaming = DEPLOYER_SERVICE.methods_by_name[name].server_streaming

        def handler(request, context):
            self.calls[name] = self.calls.get(name, 0) + 1
            if name == "ReadPort":
                return pb.ReadPortResponse(flow_status=cv.flow_to_msg(cv.FlowStatus.NO_DATA))
            context.abort(grpc.StatusCode.UNAVAILABLE, "going away")

        if streaming:
            def stream(request, context):
                handler(request, context)
                yield from ()
            return stream
        return handler


@pytest.fixture
def flaky() -> Iterator[tuple[_Flaky, str]]:
    fake = _Flaky()
    registry = NameRegistry()
    servicers = [(_proto.df_grpc.add_DeployerServiceServicer_to_server, fake),
                 (_proto.ns_grpc.add_NamingServiceServicer_to_server, NamingServicer(registry))]
    server, port, _health, executor = rpc.make_server(
        "127.0.0.1:0", servicers, [DEPLOYER_SERVICE_NAME, NAMING_SERVICE_NAME], 8)
    address = f"127.0.0.1:{port}"
    registry.register(address, ["x"], permanent=True)
    try:
        yield fake, address
    finally:
        rpc.stop_server(server, executor, 0.0)


def test_only_idempotent_calls_are_retried(flaky) -> None:
    fake, address = flaky
    with connect(address, timeout=2.0) as system:
        proxy = system.component("x")
        with pytest.raises(UnavailableError):
            proxy.call("op")
        with pytest.raises(UnavailableError):
            proxy.write("in", 1.0)
        with pytest.raises(UnavailableError):
            proxy.set_property("gain", 1.0)
        assert fake.calls["CallOperation"] == 1 and fake.calls["WritePort"] == 1
        assert fake.calls["SetProperty"] == 1
        with pytest.raises(UnavailableError):
            proxy.get_property("gain")
        assert fake.calls["GetProperty"] == 2  # safe to send twice


def test_subscribe_returns_only_once_connected(flaky) -> None:
    _, address = flaky
    with connect(address, timeout=1.0) as system:
        start = time.monotonic()
        with pytest.raises(RemoteTimeoutError, match="not connected"):
            system.component("x").subscribe("out", lambda e: None)
        assert time.monotonic() - start < 5.0


def test_private_plumbing() -> None:
    assert not hasattr(GrpcSystem, "stub") and not hasattr(GrpcSystem, "invoke")


# ---- 7. refused names on heartbeat are reported ----------------------------------------------
def test_heartbeat_reports_names_held_by_another_deployer(caplog) -> None:
    ns = serve_nameserver("127.0.0.1:0", default_lease=0.6)
    first, second = Deployer(), Deployer()
    _started(first, Pinger("x"))
    _started(second, Pinger("y"))
    one = first.serve(ns=ns.address, lease_seconds=0.6)
    two = second.serve(ns=ns.address, lease_seconds=0.6)
    try:
        caplog.set_level(logging.WARNING)
        _started(second, Pinger("x"))
        _started(second, Pinger("z"))
        wait_until(lambda: two.refused_names == ["x"], timeout=10, message="the refusal should be reported")
        text = " ".join(r.getMessage() for r in caplog.records)
        assert "x" in text and one.address in text
        with connect(ns.address) as system:
            assert system.resolve("x", fresh=True) == one.address
            wait_until(lambda: system.component_names() == ["x", "y", "z"], timeout=10)
            # the lease is lost (e.g. name service restarted): registering again keeps the free names
            lost = two._registration.lease_id
            ns.registry.unregister(lost)
            wait_until(lambda: two._registration.lease_id not in ("", lost), timeout=10)
            wait_until(lambda: system.component_names() == ["x", "y", "z"], timeout=10)
            assert two.refused_names == ["x"] and system.resolve("x", fresh=True) == one.address
    finally:
        two.stop()
        one.stop()
        ns.stop()
        first.stop_all()
        second.stop_all()


# ---- 8. scart deploy without --name -----------------------------------------------------------
@pytest.mark.parametrize(("spec", "name"), [("support.remote:Plain", "Plain"), ("driver:YouBotDriver", "youBotDriver")])
def test_deploy_without_name_uses_the_class_default(spec: str, name: str) -> None:
    proc, line = start_scart(["deploy", spec, "--period", "0.01", "--listen", f"127.0.0.1:{free_port()}"])
    try:
        assert f"serving {name} on" in line
    finally:
        assert stop_process(proc) == 0


# ---- 9. policies, decode errors ------------------------------------------------------------------
def test_bad_policy_is_invalid_argument_and_mandatory_travels(served) -> None:
    _, task, server = served
    with grpc.insecure_channel(server.address) as channel:
        stub = _proto.df_grpc.DeployerServiceStub(channel)
        for policy in (
            pb.ConnPolicy(type=99),
            pb.ConnPolicy(type=pb.ConnType.Value("CONN_TYPE_BUFFER"), size=4, lock_policy="BOGUS"),
            pb.ConnPolicy(type=pb.ConnType.Value("CONN_TYPE_BUFFER"), size=4, buffer_policy="NOPE"),
            pb.ConnPolicy(type=pb.ConnType.Value("CONN_TYPE_BUFFER"), size=0),
        ):
            with pytest.raises(grpc.RpcError) as info:
                stub.OpenWriter(pb.OpenWriterRequest(task="p", port="input", policy=policy), timeout=5)
            assert info.value.code() is grpc.StatusCode.INVALID_ARGUMENT, info.value.details()
            assert "policy" in info.value.details() or "size" in info.value.details()
    relaxed = ConnPolicy(ConnPolicy.buffer(1).type, 1, mandatory=False)
    assert cv.policy_from_msg(cv.policy_to_msg(relaxed)).mandatory is False
    assert cv.policy_from_msg(cv.policy_to_msg(ConnPolicy.buffer(1))).mandatory is True
    with connect(server.address, timeout=5.0) as system:
        proxy = system.component("p")
        strict = proxy.connect_input("input", ConnPolicy.buffer(1))
        loose = proxy.connect_input("samples", ConnPolicy(ConnPolicy.buffer(1).type, 1, mandatory=False))
        assert strict.write(1.0) is WriteStatus.WRITE_SUCCESS
        assert strict.write(2.0) is WriteStatus.WRITE_FAILURE  # full and mandatory
        assert loose.write([1.0]) is WriteStatus.WRITE_SUCCESS
        assert loose.write([2.0]) is WriteStatus.WRITE_SUCCESS  # full, not mandatory: only counted


def test_undecodable_sample_does_not_kill_the_subscription(served, monkeypatch) -> None:
    _, task, server = served
    real = codec.decode
    bad = {"count": 0}

    def decode(msg):
        value = real(msg)
        if value == 13.0:
            bad["count"] += 1
            raise ValueError("corrupt sample")
        return value

    monkeypatch.setattr(_subscription.codec, "decode", decode)
    got = []
    with connect(server.address, timeout=5.0) as system:
        sub = system.component("p").subscribe("output", lambda e: got.append(e.value), ConnPolicy.buffer(10))
        task.output.write(13.0)
        wait_until(lambda: bad["count"] == 1, timeout=5)
        task.output.write(14.0)
        wait_until(lambda: got == [14.0], timeout=5, message="the receiver died on a bad sample")
        assert sub.connected and sub.reconnects == 0 and sub.dropped == 1
