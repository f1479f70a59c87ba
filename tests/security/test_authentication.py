"""Authentication and roles on every gRPC surface: the deployer, the name service and
binding.grpc, with TLS, mTLS and bearer tokens — and the safe default (loopback only).
Real servers on 127.0.0.1:0; certificates made by :mod:`support.certs`."""

from __future__ import annotations

import logging
import secrets
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

import scart
from dataflow import Deployer, WriteStatus
from dataflow.remote import (
    AuthenticationError, PermissionDeniedError, Security, SecurityError, connect, serve_nameserver,
)
from scart_wire.rpc import health_ok
from dataflow.remote.errors import TlsMismatchError
from scart_wire.security import AuthTable, Role
from support import ROOT
from support.certs import Authority, Pem
from support.remote import Pinger
from support.sca import composite, py, write

TOKENS = {role: f"{role}-{secrets.token_hex(16)}" for role in ("read", "operate", "admin")}


@pytest.fixture
def auth_file(tmp_path: Path) -> str:
    path = tmp_path / "tokens.auth"
    path.write_text("# roles of the robot's users\n" + "".join(f"{r} {t}\n" for r, t in TOKENS.items()))
    path.chmod(0o600)
    return str(path)


def token_file(folder: Path, role: str) -> str:
    path = folder / f"{role}.token"
    path.write_text(f"# the {role} token\n{TOKENS[role]}\n")
    path.chmod(0o600)
    return str(path)


@pytest.fixture
def pki(tmp_path: Path) -> Iterator[tuple[Authority, Pem, Pem, Pem]]:
    """A CA, its server and client certificates, and a client certificate of a rogue CA."""
    ca = Authority(tmp_path / "pki")
    rogue = Authority(tmp_path / "rogue", name="rogue CA")
    yield ca, ca.issue("server", server=True), ca.issue("client", server=False), rogue.issue("intruder", server=False)


def serve(security: Security, address: str = "127.0.0.1:0", ns: str | None = None) -> tuple[Deployer, object]:
    deployer = Deployer()
    deployer.add(Pinger("p"))
    deployer.configure_all()
    return deployer, deployer.serve(address, ns=ns, security=security)


@pytest.fixture
def guarded(auth_file: str) -> Iterator[str]:
    """A deployer (with its embedded name service) that checks tokens; yields its address."""
    _, server = serve(Security(auth_file=auth_file))
    try:
        yield server.address  # type: ignore[attr-defined]
    finally:
        server.stop()  # type: ignore[attr-defined]


def test_no_valid_token_is_unauthenticated(guarded: str) -> None:
    for security in (Security(), Security(token="not-a-token-of-this-robot")):
        with pytest.raises(AuthenticationError, match="no valid token"):
            connect(guarded, security=security)


def test_each_role_may_do_what_it_allows_and_no_more(guarded: str) -> None:
    with connect(guarded, security=Security(token=TOKENS["read"])) as system:
        pinger = system.component("p")
        assert "input" in pinger.ports() and pinger.get_property("gain") == 1.0
        with pytest.raises(PermissionDeniedError, match="WritePort needs the 'operate' role; this token has 'read'"):
            pinger.write("input", 1.0)
        with pytest.raises(PermissionDeniedError, match="SetProperty needs the 'operate' role"):
            pinger.set_property("gain", float("-inf"))
        with pytest.raises(PermissionDeniedError, match="ChangeState needs the 'operate' role"):
            pinger.change_state("stop")
    with connect(guarded, security=Security(token=TOKENS["operate"])) as system:
        pinger = system.component("p")
        assert pinger.write("input", 1.0) is WriteStatus.WRITE_SUCCESS
        pinger.set_property("gain", 2.0)
        assert pinger.get_property("gain") == 2.0


def test_health_stays_open(guarded: str) -> None:
    assert health_ok(guarded)


def test_registering_names_with_a_name_service_needs_admin(auth_file: str) -> None:
    ns = serve_nameserver("127.0.0.1:0", security=Security(auth_file=auth_file))
    try:
        with pytest.raises(PermissionDeniedError, match="Register needs the 'admin' role; this token has 'operate'"):
            serve(Security(token=TOKENS["operate"]), ns=ns.address)
        _, server = serve(Security(token=TOKENS["admin"]), ns=ns.address)
        try:
            with connect(ns.address, security=Security(token=TOKENS["read"])) as system:
                assert system.component_names() == ["p"]
        finally:
            server.stop()  # type: ignore[attr-defined]
    finally:
        ns.stop()


def test_tls(pki: tuple[Authority, Pem, Pem, Pem]) -> None:
    ca, server_pem, _, _ = pki
    _, server = serve(Security(cert=server_pem.cert, key=server_pem.key))
    address = server.address  # type: ignore[attr-defined]
    try:
        with connect(address, security=Security(ca=ca.ca)) as system:
            assert system.component_names() == ["p"]
        with pytest.raises(TlsMismatchError, match="speaks TLS and this client does not: give --tls-ca"):
            connect(address, timeout=1.0, security=Security())  # plaintext to a TLS server
        rogue = Authority(Path(ca.folder).parent / "other", name="other CA")
        with pytest.raises(TlsMismatchError, match="--tls-ca does not trust"):  # a server this client cannot verify
            connect(address, timeout=1.0, security=Security(ca=rogue.ca))
    finally:
        server.stop()  # type: ignore[attr-defined]


def test_mtls(pki: tuple[Authority, Pem, Pem, Pem]) -> None:
    ca, server_pem, client_pem, intruder = pki
    _, server = serve(Security(cert=server_pem.cert, key=server_pem.key, ca=ca.ca))
    address = server.address  # type: ignore[attr-defined]
    try:
        with connect(address, security=Security(ca=ca.ca, cert=client_pem.cert, key=client_pem.key)) as system:
            assert system.component_names() == ["p"]
        for refused in (Security(ca=ca.ca), Security(ca=ca.ca, cert=intruder.cert, key=intruder.key)):
            with pytest.raises(TlsMismatchError, match=r"wants a client certificate \(mTLS\): give --tls-cert"):
                connect(address, timeout=1.0, security=refused)
    finally:
        server.stop()  # type: ignore[attr-defined]


def test_a_non_loopback_bind_without_tls_and_tokens_is_refused(
        auth_file: str, pki: tuple[Authority, Pem, Pem, Pem], caplog: pytest.LogCaptureFixture) -> None:
    with pytest.raises(SecurityError, match=r"refusing to listen on 0\.0\.0\.0:0 without TLS .* and tokens"):
        serve(Security(), address="0.0.0.0:0")
    with pytest.raises(SecurityError, match="without TLS"):
        serve(Security(auth_file=auth_file), address="0.0.0.0:0")
    _, server_pem, _, _ = pki
    _, server = serve(Security(cert=server_pem.cert, key=server_pem.key, auth_file=auth_file), address="0.0.0.0:0")
    server.stop()  # type: ignore[attr-defined]
    with caplog.at_level(logging.WARNING):
        _, server = serve(Security(insecure=True), address="0.0.0.0:0")
    try:
        assert "WITHOUT TLS" in caplog.text and server.listen_address.startswith("0.0.0.0:")  # type: ignore[attr-defined]
    finally:
        server.stop()  # type: ignore[attr-defined]


def test_tokens_are_never_logged_nor_echoed(guarded: str, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    wrong = "wrong-" + secrets.token_hex(8)
    with caplog.at_level(logging.DEBUG):
        with pytest.raises(AuthenticationError) as info:
            connect(guarded, security=Security(token=wrong))
        bad = tmp_path / "bad.auth"
        bad.write_text(f"superuser {TOKENS['admin']}\n")
        with pytest.raises(SecurityError) as parse:
            AuthTable.load(bad)
    for secret in (wrong, TOKENS["admin"]):
        assert secret not in caplog.text and secret not in str(info.value) and secret not in str(parse.value)
    assert f"{bad}:1: the first word is not a role" in str(parse.value)  # never echoed: it may be the token
    assert wrong not in repr(Security(token=wrong))


def test_auth_files_are_checked_line_by_line(tmp_path: Path) -> None:
    path = tmp_path / "t.auth"
    for text, message in [("read\n", ":1: expected 'ROLE TOKEN'"), ("read short\n", ":1: token too short"),
                          ("# nothing\n", "no token"), ("read abcdefghij\nadmin abcdefghij\n", ":2: this token is given two roles")]:
        path.write_text(text)
        with pytest.raises(SecurityError, match=message):
            AuthTable.load(path)
    path.write_text("read  aaaaaaaaaa  # the dashboard\n\nOPERATE bbbbbbbbbb\n")
    table = AuthTable.load(path)
    assert table.role_of("aaaaaaaaaa") is Role.READ and table.role_of("bbbbbbbbbb") is Role.OPERATE
    assert table.role_of("aaaaaaaaa") is None and table.role_of(None) is None


# ---- the command line ------------------------------------------------------------------

def scart_cli(*args: str, env_token: str | None = None) -> subprocess.CompletedProcess[str]:
    import os

    env = {k: v for k, v in os.environ.items() if not k.startswith("SCART_")}
    if env_token:
        env["SCART_TOKEN"] = env_token
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True, timeout=60,
                          env=env, cwd=ROOT)


@pytest.mark.subprocess
def test_the_cli_says_what_is_refused_in_one_line(guarded: str, tmp_path: Path) -> None:
    out = scart_cli("ls", "--ns", guarded, "--sample", "0")
    assert out.returncode == 1 and out.stderr.count("\n") == 1 and "no valid token" in out.stderr
    out = scart_cli("write", "p.input", "1.0", "--ns", guarded, "--token-file", token_file(tmp_path, "read"))
    assert out.returncode == 1 and out.stderr.count("\n") == 1
    assert "WritePort needs the 'operate' role" in out.stderr and TOKENS["read"] not in out.stderr
    out = scart_cli("write", "p.input", "1.0", "--ns", guarded, env_token=TOKENS["operate"])
    assert out.returncode == 0 and out.stdout.startswith("WRITE_SUCCESS: the port took it")


@pytest.mark.subprocess
def test_secrets_exposed_to_other_local_users_are_warned_about(guarded: str, tmp_path: Path) -> None:
    out = scart_cli("ls", "--ns", guarded, "--sample", "0", "--token", TOKENS["read"])
    assert out.returncode == 0 and "--token on the command line is visible to other local users" in out.stderr
    assert TOKENS["read"] not in out.stderr
    loose = tmp_path / "loose.token"
    loose.write_text(TOKENS["read"])
    loose.chmod(0o644)
    out = scart_cli("ls", "--ns", guarded, "--sample", "0", "--token-file", str(loose))
    assert out.returncode == 0 and "can be read by other users: chmod 600 it" in out.stderr
    both = scart_cli("ls", "--ns", guarded, "--token", "x" * 8, "--token-file", str(loose))
    assert both.returncode == 1 and "not both" in both.stderr


@pytest.mark.subprocess
def test_the_cli_refuses_a_non_loopback_bind() -> None:
    out = scart_cli("nameserver", "--listen", "0.0.0.0:0")
    assert out.returncode == 1 and "refusing to listen on 0.0.0.0:0" in out.stderr and "--insecure" in out.stderr


# ---- binding.grpc ----------------------------------------------------------------------

def test_binding_grpc_checks_tokens_and_roles(tmp_path: Path, auth_file: str) -> None:
    provider_path = write(tmp_path / "p", {"p.composite": composite(
        f'<component name="A">{py("GreeterImpl")}<service name="Greeter"><scart:binding.grpc/></service></component>')})
    with scart.Runtime.from_file(str(provider_path), settings=scart.Settings(
            security=Security(auth_file=auth_file))) as provider:
        address = next(iter(provider.addresses().values()))

        def client(token: str | None) -> scart.Runtime:
            path = write(tmp_path / f"c{token is None}{len(token or '')}", {"c.composite": composite(
                f'<component name="S">{py("Single")}<reference name="one"><scart:binding.grpc address="{address}" '
                f'service="A/Greeter" timeout="2"/></reference></component>')})
            return scart.Runtime.from_file(str(path), settings=scart.Settings(security=Security(token=token)))

        with client(None) as rt, pytest.raises(scart.InvocationError, match="greet: UNAUTHENTICATED: Call: no valid token"):
            rt.service("S").call("x")
        with client(TOKENS["read"]) as rt, pytest.raises(scart.InvocationError, match="needs the 'operate' role"):
            rt.service("S").call("x")
        with client(TOKENS["operate"]) as rt:
            assert rt.service("S").call("x") == "Hello, x"


@pytest.mark.subprocess
def test_scart_run_serves_its_tasks_with_tokens(auth_file: str) -> None:
    """The flags reach the runtime's settings: its data-flow server checks tokens, and the
    runtime's own calls carry --token."""
    from support import free_port
    from support.cli import finish, read_until

    import os
    import signal

    ns = f"127.0.0.1:{free_port()}"
    env = {k: v for k, v in os.environ.items() if not k.startswith("SCART_")}
    env["SCART_TOKEN_FILE"] = token_file(Path(auth_file).parent, "admin")
    proc = subprocess.Popen([sys.executable, "-m", "scart", "run", str(ROOT / "composites/bridge/thermostat.composite"),
                             "--ns", ns, "--auth-file", auth_file],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0, env=env, cwd=ROOT)
    try:
        read_until(proc, "started")
        refused = scart_cli("ls", "--ns", ns, "--sample", "0")
        assert refused.returncode == 1 and "no valid token" in refused.stderr
        listed = scart_cli("ls", "--ns", ns, "--sample", "0", "--json", env_token=TOKENS["read"])
        assert listed.returncode == 0 and '"name": "thermostat"' in listed.stdout
    finally:
        proc.send_signal(signal.SIGINT)
        finish(proc)
    assert proc.returncode == 0
