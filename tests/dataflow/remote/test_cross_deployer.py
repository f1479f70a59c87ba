"""Ports connected across deployers (through the name service), at run time, and disconnected."""

from __future__ import annotations

import pytest

from dataflow import ConnPolicy, Deployer, PeriodicActivity, PortTypeError
from dataflow.remote import connect, serve_nameserver
from support import wait_until
from support.remote import Pinger


@pytest.fixture
def two_deployers():
    ns = serve_nameserver("127.0.0.1:0")
    d1, d2 = Deployer(), Deployer()
    src, dst = d1.add(Pinger("src")), d2.add(Pinger("dst"))
    for t in (src, dst):
        t.set_activity(PeriodicActivity(0.005))
    servers = []
    try:
        for d in (d1, d2):
            d.configure_all()
            d.start_all()
            servers.append(d.serve("127.0.0.1:0", ns=ns.address))
        yield ns, src, dst, servers
    finally:
        for s in servers:
            s.stop()
        for d in (d1, d2):
            d.stop_all()
            d.cleanup_all()
        ns.stop()


def test_connect_across_deployers_and_disconnect(two_deployers) -> None:
    ns, src, dst, servers = two_deployers
    with connect(ns.address, heartbeat_ms=200) as system:
        assert system.component_names() == ["dst", "src"]
        system.connect_ports("src.output", "dst.input", ConnPolicy.buffer(50))
        system.connect_ports("src.output", "dst.input", ConnPolicy.buffer(50))  # idempotent
        proxy = system.component("src")
        for i in range(10):
            proxy.write("input", float(i))
            wait_until(lambda i=i: float(i) in src.received, timeout=5)
        wait_until(lambda: dst.received[-1:] == [9.0], timeout=5, message=f"dst got {dst.received}")
        assert dst.received == sorted(dst.received)
        assert system.disconnect_ports("src.output", "dst.input")
        assert not system.disconnect_ports("src.output", "dst.input")
        count = len(dst.received)
        proxy.write("input", 100.0)
        wait_until(lambda: 100.0 in src.received, timeout=5)
        # the link is gone: the source's output has no remote reader any more
        assert src.output.connection_count() == 0
        assert len(dst.received) == count


def test_connect_within_one_deployer_and_type_mismatch(two_deployers) -> None:
    ns, src, _dst, _servers = two_deployers
    with connect(ns.address) as system:
        system.connect_ports("src.output", "src.input", ConnPolicy.data())
        assert src.output.connection_count() >= 1
        assert system.disconnect_ports("src.output", "src.input")
        with pytest.raises(PortTypeError):
            system.connect_ports("src.ticks", "src.samples")


def test_deployer_processes_connected_at_start_in_any_order() -> None:
    """`scart deploy --connect` before the sink's deployer exists: the link waits for it."""
    import signal

    from support import free_port
    from support.remote import start_scart, stop_process

    ns = f"127.0.0.1:{free_port()}"
    procs = []
    try:
        proc, _ = start_scart(["deploy", "support.remote:Pinger@src", "--period", "0.01", "--listen", ns,
                               "--connect", "src.output", "dst.input", "--policy", "buffer:8"])
        procs.append(proc)
        proc, _ = start_scart(["deploy", "support.remote:Pinger@dst", "--period", "0.01", "--ns", ns])
        procs.append(proc)
        with connect(ns, heartbeat_ms=200) as system:
            got: list[float] = []
            sub = system.component("dst").subscribe("output", lambda e: got.append(e.value), policy=ConnPolicy.buffer(50))
            src = system.component("src")

            def arrived() -> bool:
                src.write("input", 5.0)  # the link may still be waiting for dst's registration
                return 5.0 in got

            wait_until(arrived, timeout=15, interval=0.2)
            sub.close()
    finally:
        for proc in procs:
            stop_process(proc, signal.SIGTERM)
