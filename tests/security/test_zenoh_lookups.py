"""Zenoh lookups (``connect_zenoh``, ``binding.dataflow`` with Zenoh) cannot be spoofed:
a resolver holding a token uses only announcements their deployer proves for that token
(``scart-proof``, answered with the auth file), so a peer of a lower role can neither
lure the token to an address of its own nor make a live component unresolvable.

The probe of the issue: a peer holding an ``operate`` token announced a component at an
address of its own; a client using ``connect_zenoh(...)`` with the admin token resolved
it and sent ``authorization: Bearer <admin token>`` there; and announcing a real
component a second time made it unresolvable."""

from __future__ import annotations

import secrets
from collections.abc import Iterator
from concurrent import futures
from dataclasses import dataclass
from pathlib import Path

import grpc
import pytest

from dataflow import Deployer
from dataflow.remote import errors
from scart_wire.security import AuthTable, Security
from support import wait_until
from support.remote import Pinger

zenoh_transport = pytest.importorskip("dataflow.transports.zenoh")
pytest.importorskip("zenoh")


class Recorder(grpc.GenericRpcHandler):
    """A fake deployer: records the metadata of every call it gets, answers none."""

    def __init__(self) -> None:
        self.metadata: list[tuple[str, str]] = []

    def service(self, handler_call_details: grpc.HandlerCallDetails) -> None:
        self.metadata.extend(handler_call_details.invocation_metadata or ())
        return None  # UNIMPLEMENTED


@dataclass
class Fleet:
    tokens: dict[str, str]
    address: str  # the real deployer's
    endpoint: str  # its Zenoh session's
    fake: Recorder
    fake_address: str
    open: object  # open_session, closed at the end


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[Fleet]:
    tokens = {role: secrets.token_hex(16) for role in ("read", "operate", "admin")}
    auth = tmp_path / "tokens.auth"
    auth.write_text("".join(f"{role} {token}\n" for role, token in tokens.items()))
    auth.chmod(0o600)
    security = Security(auth_file=str(auth))
    deployer = Deployer()
    deployer.add(Pinger("arm"))
    deployer.configure_all()
    server = deployer.serve("127.0.0.1:0", security=security)
    fake = Recorder()
    pool = futures.ThreadPoolExecutor(2)
    fake_server = grpc.server(pool, handlers=[fake])
    fake_port = fake_server.add_insecure_port("127.0.0.1:0")
    fake_server.start()
    opened: list = []

    def open_(*args, **kwargs):
        opened.append(zenoh_transport.open_session(*args, **kwargs))
        return opened[-1]

    endpoint = f"unixsock-stream/{tmp_path}/deployer.sock"
    publisher = None
    try:
        session = open_(listen=[endpoint], security=security)
        publisher = zenoh_transport.ZenohPublisher(deployer, session, "lab", served=(server.advertised, server.boot_id),
                                                   auth=AuthTable.load(auth))
        yield Fleet(tokens, server.advertised, endpoint, fake, f"127.0.0.1:{fake_port}", open_)
    finally:
        if publisher is not None:
            publisher.close()
        for each in reversed(opened):
            each.close()
        fake_server.stop(None).wait(5)
        pool.shutdown()
        server.stop()


def spoof(fleet: Fleet, component: str) -> object:
    """A peer holding an operate token announces ``component`` at the fake deployer."""
    peer = fleet.open(connect=[fleet.endpoint], mode="client", security=Security(token=fleet.tokens["operate"]))
    return peer.liveliness().declare_token(zenoh_transport.served_key("lab", component, fleet.fake_address, "spoof"))


def announced(fleet: Fleet, component: str, count: int) -> None:
    """Wait until ``component`` is announced ``count`` times (unproved lookups see them all)."""
    watcher = fleet.open(connect=[fleet.endpoint], mode="client", security=Security(token=fleet.tokens["admin"]))
    key = f"{zenoh_transport.SERVED}/lab/{component}/*/*"
    wait_until(lambda: sum(r.ok is not None for r in watcher.liveliness().get(key, timeout=2.0)) == count,
               timeout=15, message=f"{component} not announced {count} time(s)")


def test_a_token_never_goes_where_a_lower_role_peer_pointed(fleet: Fleet) -> None:
    token = spoof(fleet, "ghost")
    announced(fleet, "ghost", 1)
    client = fleet.open(connect=[fleet.endpoint], mode="client", security=Security(token=fleet.tokens["admin"]))
    with zenoh_transport.connect_zenoh(client, "lab", timeout=3.0, security=Security(token=fleet.tokens["admin"])) \
            as system:
        with pytest.raises(errors.RemoteNotFoundError):
            system.component("ghost").call("add", 1.0, 2.0)
        assert system.component_names() == ["arm"]  # the proved one only
    token.undeclare()  # type: ignore[attr-defined]
    assert not [v for k, v in fleet.fake.metadata if k == "authorization"], "a token reached the spoofed address"


def test_a_lower_role_peer_cannot_make_a_live_component_unresolvable(fleet: Fleet) -> None:
    token = spoof(fleet, "arm")
    announced(fleet, "arm", 2)
    for role in ("admin", "operate"):  # whatever the resolver's role: the auth file holds its token
        client = fleet.open(connect=[fleet.endpoint], mode="client", security=Security(token=fleet.tokens[role]))
        names = zenoh_transport.ZenohNames(client, "lab", timeout=3.0, token=fleet.tokens[role])
        assert names.resolve("arm").address == fleet.address
    with zenoh_transport.connect_zenoh(client, "lab", timeout=3.0, security=Security(token=fleet.tokens["operate"])) \
            as system:
        assert system.component("arm").call("add", 1.0, 2.0) == 3.0
    token.undeclare()  # type: ignore[attr-defined]
    assert not fleet.fake.metadata


def test_a_proof_is_bound_to_its_nonce_address_and_token(fleet: Fleet) -> None:
    proof = zenoh_transport.proof_of
    args = ("n" * 32, "lab", "arm", fleet.address, "boot")
    assert proof(fleet.tokens["admin"], *args) == proof(fleet.tokens["admin"], *args)
    assert proof(fleet.tokens["operate"], *args) != proof(fleet.tokens["admin"], *args)
    assert proof(fleet.tokens["admin"], *args[:3], fleet.fake_address, "boot") != proof(fleet.tokens["admin"], *args)
    assert fleet.tokens["admin"] not in zenoh_transport.token_id(fleet.tokens["admin"])
    assert fleet.tokens["admin"] not in repr(zenoh_transport.ZenohNames(object(), "lab", token=fleet.tokens["admin"]))
