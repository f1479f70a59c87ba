"""The small doors: a hard-linked ``@file``, faults that carried the server's traceback,
an auth-file line that printed its token, TLS mistakes reported as "nothing answers" or
"Failed to bind", and a composite path that is a FIFO. Each probe of the issue, as a test."""

from __future__ import annotations

import logging
import os
import secrets
import subprocess
import sys
from pathlib import Path

import pytest

import scart
from dataflow import Deployer
from dataflow.remote import connect, errors
from scart_wire.security import AuthTable, Security, SecurityError
from support import ROOT
from support.certs import Authority
from support.grpc_binding import gpy, grpc_reference, grpc_service, instance, provider_and_client
from support.remote import Pinger
from support.sca import composite, py, write


def _problems(path: Path) -> str:
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    return str(info.value)


def test_a_hard_link_to_a_file_outside_the_contribution_is_not_read(tmp_path: Path) -> None:
    secret = tmp_path / "outside" / "secret.txt"
    secret.parent.mkdir()
    secret.write_text("918273645\n")  # digits no temporary path holds
    folder = tmp_path / "contribution"
    path = write(folder, {"f.composite": composite(
        f'<component name="P">{py("Props")}<property name="number" file="n.txt"/></component>')})
    os.link(secret, folder / "n.txt")  # inside the folder by name, outside by content
    problems = _problems(path)
    assert "has 2 hard links" in problems and "918273645" not in problems


def test_a_fault_carries_a_code_and_a_reference_never_the_traceback(tmp_path: Path,
                                                                     caplog: pytest.LogCaptureFixture) -> None:
    provider = (f'<component name="G">{gpy("GeometryImpl")}<service name="Geometry">{grpc_service()}</service>'
                '</component>')

    def client(address: str) -> str:
        return f'<component name="C">{gpy("GeometryClient")}<reference name="geo">' \
               f'{grpc_reference(address, "G/Geometry")}</reference></component>'

    with caplog.at_level(logging.INFO, logger="scart.bindings.grpc"):
        with provider_and_client(tmp_path, provider, client) as (_, rt):
            with pytest.raises(scart.RemoteError) as info:
                instance(rt, "C").geo.fail("no")
    fault = info.value
    assert fault.remote_code == "FAILED" and len(fault.reference) == 12
    assert f"reference {fault.reference}" in str(fault) and "Rejected" in str(fault)
    assert "Traceback" not in str(fault) and str(tmp_path) not in str(fault) and ".py" not in str(fault)
    assert not hasattr(fault, "remote_traceback")
    logged = [r for r in caplog.records if fault.reference in r.getMessage()]
    assert logged and logged[0].exc_info is not None  # the traceback stays in the server's log


def test_an_auth_file_line_never_prints_its_token(tmp_path: Path) -> None:
    token = "SUPERSECRET-" + secrets.token_hex(8)
    path = tmp_path / "swapped.auth"
    path.write_text(f"{token} admin\n")
    path.chmod(0o600)
    with pytest.raises(SecurityError) as info:
        AuthTable.load(path)
    assert token not in str(info.value) and "role and token swapped?" in str(info.value)
    done = subprocess.run([sys.executable, "-m", "scart", "deploy", "support.remote:Pinger", "--ns", "127.0.0.1:0",
                           "--auth-file", str(path)], capture_output=True, text=True, timeout=60, cwd=ROOT,
                          env={**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "tests"), str(ROOT)])})
    assert done.returncode != 0 and token not in done.stdout + done.stderr


@pytest.fixture
def pki(tmp_path: Path) -> tuple[Authority, object, object]:
    ca = Authority(tmp_path / "pki")
    return ca, ca.issue("server", server=True), ca.issue("other", server=True)


def _served(security: Security) -> tuple[Deployer, object]:
    deployer = Deployer()
    deployer.add(Pinger("p"))
    return deployer, deployer.serve("127.0.0.1:0", security=security)


def test_a_key_that_does_not_match_its_certificate_is_named(pki) -> None:  # type: ignore[no-untyped-def]
    _, server, other = pki
    with pytest.raises(SecurityError) as info:
        _served(Security(cert=server.cert, key=other.key))
    message = str(info.value)
    assert "--tls-key" in message and "not the private key of --tls-cert" in message and "\n" not in message


def test_tls_on_one_end_only_is_said_with_the_flag_that_fixes_it(pki) -> None:  # type: ignore[no-untyped-def]
    ca, server_pem, _ = pki
    _, tls_server = _served(Security(cert=server_pem.cert, key=server_pem.key))
    _, plain_server = _served(Security())
    try:
        with pytest.raises(errors.TlsMismatchError, match=r"speaks TLS and this client does not: give --tls-ca"):
            connect(tls_server.address, timeout=3.0)  # type: ignore[attr-defined]
        with pytest.raises(errors.TlsMismatchError, match=r"does not speak TLS: drop --tls-ca"):
            connect(plain_server.address, timeout=3.0, security=Security(ca=ca.ca))  # type: ignore[attr-defined]
        address = tls_server.address  # type: ignore[attr-defined]
        done = subprocess.run([sys.executable, "-m", "scart", "ls", "--ns", address], capture_output=True, text=True,
                              timeout=60, cwd=ROOT,
                              env={k: v for k, v in os.environ.items() if not k.startswith("SCART_")})
        assert done.returncode == 1 and "--tls-ca" in done.stderr
        assert "nameserver" not in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    finally:
        tls_server.stop()  # type: ignore[attr-defined]
        plain_server.stop()  # type: ignore[attr-defined]


def test_a_composite_path_that_is_no_regular_file_is_refused_at_once(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.composite"
    os.mkfifo(fifo)
    done = subprocess.run([sys.executable, "-m", "scart", "validate", str(fifo)], capture_output=True, text=True,
                          timeout=20, cwd=ROOT)  # reading the FIFO would block: never
    assert done.returncode == 2 and "not a regular file" in done.stderr and "Traceback" not in done.stderr
