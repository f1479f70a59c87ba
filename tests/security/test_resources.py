"""Bounded resources: idle streams cannot starve health checks and lookups, streams are
budgeted per server and per peer, and a client stream that never speaks is cancelled.
Real servers on 127.0.0.1:0; every wait has a deadline."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import grpc
import pytest

from dataflow import Deployer, OutputPort
from scart_wire import rpc
from dataflow.remote._proto import df as pb
from dataflow.remote._proto import df_grpc
from dataflow.remote.naming import NameClient
from support import wait_until
from support.remote import Pinger


def _silent(stop: threading.Event) -> Iterator[object]:
    """A request stream that never sends its first message (until ``stop``)."""
    stop.wait(30)
    return
    yield  # a generator


def test_idle_streams_cannot_starve_health_and_lookups(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(rpc, "FIRST_MESSAGE_S", 1.0)
    deployer = Deployer()
    deployer.add(Pinger("p"))
    server = deployer.serve("127.0.0.1:0", max_workers=16)  # 8 streams at most, 8 workers kept
    stop = threading.Event()
    calls = []
    channel = grpc.insecure_channel(server.address)
    names = NameClient(server.address, timeout=2.0)
    try:
        stub = df_grpc.DeployerServiceStub(channel)
        calls = [stub.Link(_silent(stop)) for _ in range(40)]
        wait_until(lambda: sum(1 for c in calls if c.done() and c.code() == grpc.StatusCode.RESOURCE_EXHAUSTED) >= 32,
                   timeout=10, message="streams beyond the budget were not refused")
        for _ in range(20):  # health and lookups still answer, promptly, while 8 streams sit idle
            start = time.monotonic()
            assert rpc.health_ok(server.address, timeout=1.0)
            assert names.resolve("p").address == server.address
            assert time.monotonic() - start < 0.5
        # a stream that never sends its first message is cancelled: the idle ones go
        wait_until(lambda: all(c.done() for c in calls), timeout=10, message="silent streams were never cancelled")
        with pytest.raises(grpc.RpcError):
            calls[0].result()
        assert stub.ListTasks(pb.ListTasksRequest(), timeout=2).tasks[0].name == "p"
    finally:
        stop.set()
        for call in calls:
            call.cancel()
        names.close()
        channel.close()
        server.stop()


def test_one_peer_cannot_take_every_stream() -> None:
    budget = rpc.StreamBudget(total=8, per_peer=6)
    assert [budget._take("a") for _ in range(6)] == [None] * 6
    assert budget._take("a") == "at most 6 streams from one peer"
    assert budget._take("b") is None and budget._take("b") is None
    assert budget._take("c") == "this server carries at most 8 streams at once"
    budget._give("a")
    assert budget._take("c") is None and budget.open == 8


@pytest.fixture
def served_pinger() -> Iterator[tuple[Pinger, object]]:
    deployer = Deployer()
    task = Pinger("p")
    deployer.add(task)
    server = deployer.serve("127.0.0.1:0")
    try:
        yield task, server
    finally:
        server.stop()  # type: ignore[attr-defined]


def _open(stub: df_grpc.DeployerServiceStub) -> str:
    return stub.OpenWriter(pb.OpenWriterRequest(task="p", port="input"), timeout=5).writer


def test_a_writer_has_a_secret_id_only_its_peer_may_use(served_pinger: tuple[Pinger, object]) -> None:
    task, server = served_pinger
    address = server.address  # type: ignore[attr-defined]
    separate = [("grpc.use_local_subchannel_pool", 1)]  # a connection of its own: another peer
    with grpc.insecure_channel(address) as mine, grpc.insecure_channel(address, options=separate) as theirs:
        wid = _open(df_grpc.DeployerServiceStub(mine))
        assert len(wid) == 32 and wid != _open(df_grpc.DeployerServiceStub(mine))
        value = pb.WritePortRequest(writer=wid, json="1.5")
        with pytest.raises(grpc.RpcError) as info:  # another connection: another peer
            df_grpc.DeployerServiceStub(theirs).WritePort(value, timeout=5)
        assert info.value.code() == grpc.StatusCode.NOT_FOUND
        df_grpc.DeployerServiceStub(theirs).CloseWriter(pb.CloseWriterRequest(writer=wid), timeout=5)  # ignored
        assert df_grpc.DeployerServiceStub(mine).WritePort(value, timeout=5).status == pb.WRITE_STATUS_WRITE_SUCCESS
        assert task.input.connection_count() == 2


def test_the_writers_of_a_client_that_went_away_are_reclaimed(monkeypatch: pytest.MonkeyPatch) -> None:
    from dataflow.remote import _servicer

    monkeypatch.setattr(_servicer, "WRITER_IDLE_S", 0.4)
    deployer = Deployer()
    task = Pinger("p")
    deployer.add(task)
    server = deployer.serve("127.0.0.1:0")
    try:
        with grpc.insecure_channel(server.address) as channel:  # a client that opens and then vanishes
            for _ in range(5):
                _open(df_grpc.DeployerServiceStub(channel))
        assert task.input.connection_count() == 5
        wait_until(lambda: task.input.connection_count() == 0, timeout=5, message="dead client's writers kept")
    finally:
        server.stop()


def test_writers_are_bounded_per_port(monkeypatch: pytest.MonkeyPatch) -> None:
    from dataflow.remote import _servicer

    monkeypatch.setattr(_servicer, "WRITERS_PER_PORT", 3)
    deployer = Deployer()
    deployer.add(Pinger("p"))
    server = deployer.serve("127.0.0.1:0")
    try:
        with grpc.insecure_channel(server.address) as channel:
            stub = df_grpc.DeployerServiceStub(channel)
            ids = [_open(stub) for _ in range(3)]
            with pytest.raises(grpc.RpcError) as info:
                _open(stub)
            assert info.value.code() == grpc.StatusCode.RESOURCE_EXHAUSTED and "p.input has 3" in info.value.details()
            stub.CloseWriter(pb.CloseWriterRequest(writer=ids[0]), timeout=5)
            _open(stub)  # a closed one frees its place
    finally:
        server.stop()


def test_two_thousand_writers_come_and_go(served_pinger: tuple[Pinger, object]) -> None:
    task, server = served_pinger
    with grpc.insecure_channel(server.address) as channel:  # type: ignore[attr-defined]
        stub = df_grpc.DeployerServiceStub(channel)
        ids = [_open(stub) for _ in range(2000)]
        assert task.input.connection_count() == 2000 and len(set(ids)) == 2000
        for wid in ids[:1000]:
            stub.CloseWriter(pb.CloseWriterRequest(writer=wid), timeout=5)
        assert task.input.connection_count() == 1000
    # a deployer still holding writers stops promptly (it took minutes with 3000) and frees them
    stopper = threading.Thread(target=server.stop)  # type: ignore[attr-defined]
    stopper.start()
    stopper.join(timeout=20)
    assert not stopper.is_alive(), "a deployer holding 1000 writers did not stop within 20 s"
    assert task.input.connection_count() == 0


class _Big(Pinger):
    """Pinger plus a port of large samples (20 000 doubles, about 160 kB encoded)."""

    big = OutputPort(list[float], doc="large samples")


def test_a_remote_buffer_is_capped_and_a_stuck_subscriber_is_bounded_in_bytes() -> None:
    """The same buffer limit holds in one process and across processes (a policy over it
    is refused where it is made, and on the wire), and a subscriber that stops reading
    costs the deployer a bounded number of bytes, its losses counted."""
    from dataflow import ConnPolicy
    from dataflow.policy import MAX_BUFFER
    from dataflow.remote import connect
    from dataflow.remote._convert import policy_to_msg
    from dataflow.transports.grpc import ROOM_BYTES
    from dataflow.transports.served import BYTE_BUDGET

    with pytest.raises(ValueError, match="over the limit MAX_BUFFER \\(100000 samples\\)"):
        ConnPolicy.buffer(MAX_BUFFER + 1)
    deployer = Deployer()
    task = _Big("p")
    deployer.add(task)
    server = deployer.serve("127.0.0.1:0")
    try:
        too_big = policy_to_msg(ConnPolicy.buffer(10))
        too_big.size = MAX_BUFFER + 1
        with connect(server.address) as system, pytest.raises(grpc.RpcError, match="over the limit MAX_BUFFER"):
            system._stub(server.address).Subscribe(pb.SubscribeRequest(task="p", port="big", policy=too_big),
                                                   timeout=5).next()
        with grpc.insecure_channel(server.address) as channel:  # a subscriber that stops reading
            stream = df_grpc.DeployerServiceStub(channel).Subscribe(pb.SubscribeRequest(
                task="p", port="big", policy=policy_to_msg(ConnPolicy.buffer(10_000))))
            assert next(stream).heartbeat
            (served,) = server._servicer.channels.served.all()
            for i in range(400):  # 64 MB written; the deployer may hold a few MB of it
                task.big.write([float(i)] * 20_000)
            wait_until(lambda: served.dropped > 0, timeout=10, message="nothing dropped: unbounded")
            assert 0 < served.end.pending * 160_000 <= BYTE_BUDGET * 1.1, served.end.pending
            assert ROOM_BYTES <= 4 * 1024 * 1024
            stream.cancel()
    finally:
        server.stop()


def test_with_tokens_a_caller_is_its_token_not_its_connections(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Health Watch (a stream) needs a token, and the per-peer stream quota counts a token
    as one peer however many connections it opens (on loopback, connections are free)."""
    from grpc_health.v1 import health_pb2, health_pb2_grpc

    from scart_wire.security import Security

    tokens = {"read": "read-" + "a" * 24, "other": "read-" + "b" * 24}
    auth = tmp_path / "tokens.auth"
    auth.write_text("".join(f"read {t}\n" for t in tokens.values()))
    auth.chmod(0o600)
    deployer = Deployer()
    deployer.add(Pinger("p"))
    server = deployer.serve("127.0.0.1:0", max_workers=16, security=Security(auth_file=str(auth)))  # 8 streams
    channels = [grpc.insecure_channel(server.address, options=[("grpc.use_local_subchannel_pool", 1)])
                for _ in range(4)]
    calls = []
    try:
        anonymous = health_pb2_grpc.HealthStub(channels[0])
        assert anonymous.Check(health_pb2.HealthCheckRequest(), timeout=2).status == health_pb2.HealthCheckResponse.SERVING
        with pytest.raises(grpc.RpcError) as info:
            next(iter(anonymous.Watch(health_pb2.HealthCheckRequest(), timeout=2)))
        assert info.value.code() == grpc.StatusCode.UNAUTHENTICATED

        def watch(channel: grpc.Channel, token: str) -> object:
            call = health_pb2_grpc.HealthStub(channel).Watch(
                health_pb2.HealthCheckRequest(), metadata=[("authorization", f"Bearer {token}")], timeout=20)
            calls.append(call)
            return call

        opened = []
        for i in range(12):  # one token, spread over four connections
            call = watch(channels[i % 4], tokens["read"])
            try:
                next(call)  # type: ignore[call-overload]
                opened.append(call)
            except grpc.RpcError as exc:
                assert exc.code() == grpc.StatusCode.RESOURCE_EXHAUSTED and "from one peer" in exc.details()
                break
        assert len(opened) == 6  # three quarters of the 8 streams, not all of them
        assert next(watch(channels[0], tokens["other"])).status  # type: ignore[call-overload]  # another token: room
    finally:
        for call in calls:
            call.cancel()  # type: ignore[attr-defined]
        for channel in channels:
            channel.close()
        server.stop()
