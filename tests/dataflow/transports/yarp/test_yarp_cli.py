"""The yarp transport as a user drives it from a shell: ``scart deploy --yarp-server``, then
``scart stream COMP.PORT yarp:/name`` against it, YARP's own tools on the other side,
``scart links`` / ``scart describe`` showing what crossed and what was refused, and a
SIGTERM that withdraws every name."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from support import free_port, wait_until
from support.remote import start_scart, stop_process, subprocess_env
from support.yarp import YarpServer, yarpserver

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]


def scart(*args: str, ns: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args, "--ns", ns], capture_output=True, text=True,
                          timeout=60, env=subprocess_env())


@pytest.fixture
def yarp(tmp_path: Path) -> Iterator[YarpServer]:
    with yarpserver(tmp_path / "yarp") as server:
        yield server


def links(ns: str) -> dict[str, dict]:
    done = scart("links", "--json", ns=ns)
    assert done.returncode == 0, done.stderr
    return {row["name"]: row for row in json.loads(done.stdout)}


def test_scart_stream_against_a_deployer_speaks_yarp(yarp: YarpServer) -> None:
    ns = f"127.0.0.1:{free_port()}"
    proc, _ = start_scart(["deploy", "support.yarp_tasks:Arm", "--period", "0.02", "--ns", ns,
                           "--yarp-server", yarp.address])
    reader = yarp.spawn("read", "/viewer")
    try:
        reader.read_until("active", timeout=15)
        made = scart("stream", "arm.armState", "yarp:/arm/state", "--option", "connect=/viewer", ns=ns)
        assert made.returncode == 0, made.stderr
        assert made.stdout.startswith("streaming arm.armState -> yarp:/arm/state (data)")
        made = scart("stream", "arm.gain", "yarp:/arm/gain", "--policy", "buffer:10", "--name", "gain-in", ns=ns)
        assert made.returncode == 0, made.stderr
        wait_until(lambda: all(row["state"] == "connected" for row in links(ns).values()), timeout=20,
                   message=f"{links(ns)}")
        reader.read_until("arm (0.0 0.0)", timeout=15)  # name (joints) stamp ok seq
        assert yarp.registered("/arm/state") and yarp.registered("/arm/gain")
        assert yarp.tool("write", "/w", "/arm/gain", stdin="0.5\n11\n").returncode == 0  # 11: over the bound
        wait_until(lambda: links(ns)["gain-in"]["samples"] == 2, timeout=10, message=f"{links(ns)}")
        assert links(ns)["gain-in"]["dropped"] == 1
        described = scart("describe", "arm", ns=ns)
        line = next(x for x in described.stdout.splitlines() if "stream gain-in" in x)
        assert "yarp:/arm/gain" in line and "UNAUTHENTICATED" in line and "1 refused, last: arm.gain: 11.0" in line
        refused = scart("stream", "arm.cmd", "yarp:/arm/cmd", "--option", "carrier=mcast", ns=ns)
        assert refused.returncode == 1 and "carrier='mcast'" in refused.stderr
    finally:
        reader.stop()
        assert stop_process(proc) == 0
    assert not yarp.registered("/arm/state") and not yarp.registered("/arm/gain")  # withdrawn at the stop


def test_a_bad_yarp_server_address_is_one_line_and_nothing_starts() -> None:
    done = subprocess.run([sys.executable, "-m", "scart", "deploy", "support.yarp_tasks:Arm", "--yarp-server",
                           "nowhere", "--ns", f"127.0.0.1:{free_port()}"], capture_output=True, text=True, timeout=60,
                          env=subprocess_env())
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert "a YARP name server address is HOST:PORT, got 'nowhere'" in done.stderr


def test_yarp_ports_stay_on_loopback_unless_insecure() -> None:
    from scart_yarp import Network

    with pytest.raises(ValueError, match="YARP authenticates no one; ports listen on loopback unless insecure"):
        Network(("127.0.0.1", 1), host="0.0.0.0")
    net = Network(("127.0.0.1", 1))
    try:
        with pytest.raises(OSError, match="is not loopback: scart's YARP connects to other hosts only when insecure"):
            net.connect_to("192.0.2.1", 10000)  # TEST-NET: never reached, refused before any packet
        with pytest.raises(OSError, match="is not loopback"):
            net.datagram_to("192.0.2.1", 10000)
    finally:
        net.close()
