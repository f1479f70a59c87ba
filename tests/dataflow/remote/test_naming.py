"""The name service: leases, heartbeats, expiry, re-registration, duplicate refusal."""

from __future__ import annotations

import pytest

from dataflow import Deployer, NotFoundError
from dataflow.remote import AlreadyRegisteredError, RemoteNotFoundError, UnavailableError, connect, serve_nameserver
from dataflow.remote.naming import NameClient, NameRegistry, Registration
from support import wait_until
from support.remote import Pinger


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_registry_lease_expires_without_heartbeat() -> None:
    clock = Clock()
    reg = NameRegistry(default_lease=2.0, clock=clock, probe=lambda a, b: True)
    lease, seconds = reg.register("127.0.0.1:1", ["a", "b"], boot_id="d1")
    assert seconds == 2.0
    assert reg.resolve("a").address == "127.0.0.1:1"
    clock.now += 1.5
    reg.heartbeat(lease)
    clock.now += 1.5
    assert [e.component for e in reg.entries()] == ["a", "b"]
    clock.now += 0.6
    assert reg.entries() == []
    with pytest.raises(NotFoundError, match="no component named 'a'"):
        reg.resolve("a")
    with pytest.raises(NotFoundError, match="register again"):
        reg.heartbeat(lease)


def test_registry_refuses_duplicate_of_live_deployer_and_replaces_dead_one() -> None:
    alive = {("127.0.0.1:1", "d1"): True}
    reg = NameRegistry(clock=Clock(), probe=lambda a, b: alive.get((a, b), False))
    reg.register("127.0.0.1:1", ["a"], boot_id="d1")
    with pytest.raises(AlreadyRegisteredError, match="a already registered by the deployer at 127.0.0.1:1"):
        reg.register("127.0.0.1:2", ["a"], boot_id="d2")
    alive[("127.0.0.1:1", "d1")] = False  # the holder died: a newcomer takes the name
    reg.register("127.0.0.1:2", ["a"], boot_id="d2")
    assert reg.resolve("a").boot_id == "d2"
    # a restarted deployer on the same address (a new process: d2 no longer answers there)
    reg.register("127.0.0.1:2", ["a"], boot_id="d3")
    assert reg.resolve("a").boot_id == "d3"


def test_registry_reregistration_by_the_lease_holder_changes_its_names() -> None:
    reg = NameRegistry(clock=Clock(), probe=lambda a, b: True)
    lease, _ = reg.register("127.0.0.1:1", ["a"], boot_id="d1")
    assert reg.register("127.0.0.1:1", ["a", "b"], boot_id="d1", lease_id=lease)[0] == lease
    assert [e.component for e in reg.entries()] == ["a", "b"]
    reg.register("127.0.0.1:1", ["b"], lease_id=lease)
    assert [e.component for e in reg.entries()] == ["b"]


def test_lease_expiry_over_grpc_and_heartbeats_keep_it() -> None:
    server = serve_nameserver("127.0.0.1:0", default_lease=0.3)
    client = NameClient(server.address)
    kept = Registration(server.address, "127.0.0.1:9", lambda: ["kept"], lease_seconds=0.3)
    try:
        kept.start()
        client.register("127.0.0.1:8", ["gone"], lease_seconds=0.3)
        assert {e.component for e in client.entries()} == {"kept", "gone"}
        wait_until(lambda: {e.component for e in client.entries()} == {"kept"}, timeout=5,
                   message="the lease without heartbeats should expire, the other stay")
        with pytest.raises(RemoteNotFoundError, match="known: kept"):
            client.resolve("gone")
    finally:
        kept.stop()
        client.close()
        server.stop()
    assert kept.lease_id == ""


def test_registration_survives_name_service_restart() -> None:
    from support import free_port

    address = f"127.0.0.1:{free_port()}"
    server = serve_nameserver(address, default_lease=0.3)
    reg = Registration(address, "127.0.0.1:9", lambda: ["comp"], lease_seconds=0.3)
    try:
        reg.start()
        server.stop()
        server = serve_nameserver(address, default_lease=0.3)  # empty table
        client = NameClient(address)
        try:
            wait_until(lambda: [e.component for e in client.entries()] == ["comp"], timeout=5)
        finally:
            client.close()
        assert reg.registrations >= 2
    finally:
        reg.stop()
        server.stop()


def test_deployers_joining_a_standalone_name_service_and_duplicate_refused() -> None:
    ns = serve_nameserver("127.0.0.1:0")
    d1, d2 = Deployer(), Deployer()
    d1.add(Pinger("a"))
    d2.add(Pinger("a"))
    s1 = d1.serve("127.0.0.1:0", ns=ns.address)
    try:
        with pytest.raises(AlreadyRegisteredError, match=f"already registered by the deployer at {s1.address}"):
            d2.serve("127.0.0.1:0", ns=ns.address)
        with connect(ns.address) as system:
            assert system.component_names() == ["a"]
            assert system.components()[0].address == s1.address
    finally:
        s1.stop()
        ns.stop()


def test_connect_to_nothing_names_the_address() -> None:
    from support import free_port

    address = f"127.0.0.1:{free_port()}"
    with pytest.raises(UnavailableError, match=address):
        connect(address, timeout=1.0)


def test_unregister_on_stop() -> None:
    ns = serve_nameserver("127.0.0.1:0")
    d = Deployer()
    d.add(Pinger("x"))
    server = d.serve("127.0.0.1:0", ns=ns.address)
    client = NameClient(ns.address)
    try:
        assert [e.component for e in client.entries()] == ["x"]
        server.stop()
        assert client.entries() == []
    finally:
        client.close()
        ns.stop()


def test_a_wildcard_listener_is_advertised_by_host_name_or_as_told() -> None:
    import socket

    from scart_wire.rpc import advertised_address

    host = socket.gethostname()
    assert advertised_address("127.0.0.1:5000") == "127.0.0.1:5000"
    assert advertised_address("0.0.0.0:5000") == advertised_address("[::]:5000") == f"{host}:5000"
    assert advertised_address("0.0.0.0:5000", "robot-7.lan") == "robot-7.lan:5000"
    assert advertised_address("0.0.0.0:5000", "10.0.0.2:6000") == "10.0.0.2:6000"
    assert advertised_address("0.0.0.0:5000", "[fe80::1]") == "[fe80::1]:5000"
    for bad in ("a b", "robot:", "robot:0", "robot:70000", "::1", "[::1]x", "-robot", "a:b:c", "x" * 300):
        with pytest.raises(ValueError, match="advertise"):
            advertised_address("0.0.0.0:5000", bad)


def test_the_name_service_gives_the_advertised_address_and_clients_reach_it() -> None:
    ns = serve_nameserver("127.0.0.1:0")
    deployer = Deployer()
    deployer.add(Pinger("p"))
    with pytest.raises(ValueError, match="advertise 'robot:'"):
        deployer.serve("127.0.0.1:0", ns=ns.address, advertise="robot:")  # before anything is bound
    server = deployer.serve("127.0.0.1:0", ns=ns.address, advertise="localhost")
    try:
        port = server.address.rpartition(":")[2]
        assert server.advertised == f"localhost:{port}"
        wait_until(lambda: [(e.component, e.address) for e in NameClient(ns.address).entries()]
                   == [("p", f"localhost:{port}")], timeout=10)
        with connect(ns.address, timeout=5.0) as system:  # dials localhost:PORT, as told
            assert system.component("p").state in ("PRE_OPERATIONAL", "STOPPED")
    finally:
        server.stop()
        ns.stop()
