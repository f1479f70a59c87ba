"""A name service that cannot be hijacked: secret leases, no published deployer ids,
finite leases, bounded tables, pages. Each test is a probe that worked before."""

from __future__ import annotations

import math
import socket
import threading

import grpc
import pytest

from dataflow import Deployer, NotFoundError
from dataflow.remote import AlreadyRegisteredError, RemoteError, connect, serve_nameserver
from dataflow.remote._proto import ns as pb
from dataflow.remote._proto import ns_grpc
from scart_wire import rpc
from dataflow.remote.naming import Limits, NameClient, NameRegistry
from scart_wire.security import Security
from support.remote import Pinger


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def robot() -> tuple[object, object, str]:
    """A standalone name service and a live deployer serving "driver" registered in it."""
    ns = serve_nameserver("127.0.0.1:0")
    deployer = Deployer()
    deployer.add(Pinger("driver"))
    server = deployer.serve("127.0.0.1:0", ns=ns.address)
    try:
        yield ns, server, ns.address
    finally:
        server.stop()  # type: ignore[attr-defined]
        ns.stop()


def test_no_entry_publishes_anything_to_impersonate_with(robot: tuple[object, object, str]) -> None:
    _, server, address = robot
    with grpc.insecure_channel(address) as channel:
        reply = ns_grpc.NamingServiceStub(channel).ListEntries(pb.ListEntriesRequest(), timeout=5)
    (entry,) = reply.entries
    assert not hasattr(entry, "deployer_id") and entry.boot_id == server.boot_id  # type: ignore[attr-defined]
    assert "lease" not in str(reply).lower()


def test_a_live_name_cannot_be_repointed_not_even_by_claiming_its_address(robot: tuple[object, object, str]) -> None:
    _, server, address = robot
    attacker = NameClient(address)
    try:
        for claimed in ("127.0.0.1:6666", server.address):  # type: ignore[attr-defined]
            for boot_id in ("", server.boot_id):  # type: ignore[attr-defined]  # even its public boot id
                with pytest.raises(AlreadyRegisteredError):
                    attacker.register(claimed, ["driver"], boot_id=boot_id)
        with pytest.raises(RemoteError, match="NOT_FOUND|lease unknown"):
            attacker.register("127.0.0.1:6666", ["driver"], lease_id="0" * 32)  # a guessed lease
        attacker.unregister("0" * 32)  # a guessed lease: nothing happens
        attacker.register("127.0.0.1:6666", [])  # an empty registration deletes nothing
        with connect(address) as system:
            assert system.components()[0].address == server.address  # type: ignore[attr-defined]
    finally:
        attacker.close()


def test_leases_are_secret_and_only_their_holder_changes_them() -> None:
    reg = NameRegistry(clock=Clock(), probe=lambda a, b: False)
    one, _ = reg.register("127.0.0.1:1", ["a"], boot_id="x")
    two, _ = reg.register("127.0.0.1:2", ["b"], boot_id="y")
    assert len(one) == 32 and int(one, 16) >= 0 and one != two  # 128 random bits, hex
    reg.unregister(two[:-1] + ("0" if two[-1] != "0" else "1"))
    assert [e.component for e in reg.entries()] == ["a", "b"]
    with pytest.raises(NotFoundError):
        reg.heartbeat("f" * 32)


@pytest.mark.parametrize("lease", [math.nan, math.inf, -1.0, -math.inf])
def test_a_lease_must_be_finite_and_positive(robot: tuple[object, object, str], lease: float) -> None:
    _, _, address = robot
    client = NameClient(address)
    try:
        with pytest.raises(RemoteError) as info:
            client.register("127.0.0.1:7", ["other"], lease_seconds=lease)
        assert info.value.code == "INVALID_ARGUMENT" and "finite" in str(info.value)
    finally:
        client.close()


def test_a_long_lease_is_shortened_to_the_maximum() -> None:
    reg = NameRegistry(clock=Clock(), limits=Limits(max_lease=60.0))
    assert reg.register("127.0.0.1:1", ["a"], 1e9)[1] == 60.0


def test_registrations_are_bounded_per_lease_per_peer_and_in_total() -> None:
    reg = NameRegistry(clock=Clock(), limits=Limits(names_per_lease=3, leases_per_peer=2, leases=3, names=5))
    with pytest.raises(RemoteError, match="4 names in one registration; at most 3"):
        reg.register("h:1", ["a", "b", "c", "d"], peer="p1")
    reg.register("h:1", ["a"], peer="p1")
    reg.register("h:2", ["b"], peer="p1")
    with pytest.raises(RemoteError, match="p1 holds 2 leases already"):
        reg.register("h:3", ["c"], peer="p1")
    reg.register("h:3", ["c", "d", "e"], peer="p2")
    with pytest.raises(RemoteError, match="3 leases already"):
        reg.register("h:4", ["f"], peer="p3")
    with pytest.raises(ValueError, match="printable"):
        NameRegistry().register("h:1", ["bad\nname"])


def test_entries_come_in_pages_and_errors_list_a_bounded_few() -> None:
    ns = serve_nameserver("127.0.0.1:0")
    client = NameClient(ns.address)
    try:
        names = [f"task{i:04d}" for i in range(1200)]
        for start in range(0, 1200, 400):
            client.register(f"127.0.0.1:{9000 + start}", names[start:start + 400])
        with grpc.insecure_channel(ns.address) as channel:
            page = ns_grpc.NamingServiceStub(channel).ListEntries(pb.ListEntriesRequest(page_size=10), timeout=5)
        assert len(page.entries) == 10 and page.next_page_token == "task0009"
        assert [e.component for e in client.entries()] == names  # every page, in order
        with pytest.raises(RemoteError) as info:
            client.resolve("nope")
        assert "and 1180 more" in str(info.value) and len(str(info.value)) < 600
    finally:
        client.close()
        ns.stop()


def _tarpit() -> socket.socket:
    """A listening socket that never answers: a holder that looks busy, forever."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(512)
    return sock


def test_a_silent_holder_keeps_its_names_and_claims_cannot_starve_the_server() -> None:
    """A probe that times out is no proof the holder is gone; and a flood of claims that
    make the registry probe cannot take the server's workers (health, lookups) nor, by
    making the deployer's own health look down, its names."""
    deployer = Deployer()
    deployer.add(Pinger("p"))
    server = deployer.serve("127.0.0.1:0")
    tarpit = _tarpit()
    silent = f"127.0.0.1:{tarpit.getsockname()[1]}"
    names = NameClient(server.address, timeout=5)
    outcomes: list[str] = []
    try:
        names.register(silent, ["t"], 60.0, boot_id="b" * 16)

        def claim(name: str) -> None:
            client = NameClient(server.address, timeout=10)
            try:
                client.register("127.0.0.1:1", [name], 60.0, boot_id="c" * 16)
                outcomes.append("taken")
            except RemoteError as exc:
                outcomes.append(exc.code)
            finally:
                client.close()

        threads = [threading.Thread(target=claim, args=("t" if i % 2 else "p",)) for i in range(60)]
        for thread in threads:
            thread.start()
        for _ in range(10):  # while they run: health and lookups answer
            assert rpc.health_ok(server.address, timeout=2.0)
            assert names.resolve("p").address == server.address
        for thread in threads:
            thread.join(timeout=30)
        assert not any(t.is_alive() for t in threads)
        assert len(outcomes) == 60 and "taken" not in outcomes
        assert set(outcomes) <= {"ALREADY_EXISTS", "RESOURCE_EXHAUSTED"}
        assert names.resolve("t").address == silent and names.resolve("p").address == server.address
    finally:
        names.close()
        tarpit.close()
        server.stop()


def test_the_liveness_probe_never_carries_the_server_s_token() -> None:
    """The registry checks a holder at the address the registrant chose: it must not hand
    that address the token this runtime uses for its own calls."""
    from concurrent import futures

    from grpc_health.v1 import health, health_pb2_grpc

    seen: list[tuple[tuple[str, str], ...]] = []

    class Recorder(grpc.ServerInterceptor):
        def intercept_service(self, continuation, details):  # type: ignore[no-untyped-def]
            seen.append(tuple(details.invocation_metadata or ()))
            return continuation(details)

    pool = futures.ThreadPoolExecutor(2)
    decoy = grpc.server(pool, interceptors=[Recorder()])
    health_pb2_grpc.add_HealthServicer_to_server(health.HealthServicer(), decoy)
    decoy_address = f"127.0.0.1:{decoy.add_insecure_port('127.0.0.1:0')}"
    decoy.start()
    deployer = Deployer()
    deployer.add(Pinger("p"))
    server = deployer.serve("127.0.0.1:0", security=Security(token="the-robot-s-own-secret-token"))
    names = NameClient(server.address, timeout=5)
    try:
        names.register(decoy_address, ["x"], 60.0, boot_id="d" * 16)
        # the registry probes the holder; the decoy does not serve that boot id: gone
        names.register("127.0.0.1:1", ["x"], 60.0, boot_id="e" * 16)
    finally:
        names.close()
        server.stop()
        decoy.stop(None)
        pool.shutdown()
    assert seen, "the registry never probed the holder"
    assert all(key != "authorization" for metadata in seen for key, _ in metadata)
