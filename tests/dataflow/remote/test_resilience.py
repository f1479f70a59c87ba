"""Stopping hurts: deployer processes killed and restarted, frozen (SIGSTOP) and resumed,
leases expiring — proxies and subscriptions recover by themselves and report the gap."""

from __future__ import annotations

import signal
import threading

import pytest

from dataflow import ConnPolicy
from dataflow.remote import RemoteTimeoutError, connect, serve_nameserver
from dataflow.remote.naming import NameClient
from support import free_port, wait_until
from support.remote import address_of, start_scart, stop_process

DEPLOY = ["deploy", "support.remote:Pinger", "--name", "p", "--period", "0.01", "--heartbeat-ms", "200"]


@pytest.fixture
def ns():
    server = serve_nameserver("127.0.0.1:0", default_lease=1.0)
    try:
        yield server
    finally:
        server.stop()


@pytest.fixture
def procs():
    started = []
    try:
        yield started
    finally:
        for proc in started:
            stop_process(proc, signal.SIGKILL)


def _deploy(procs, ns_address: str, *extra: str) -> str:
    proc, line = start_scart([*DEPLOY, "--ns", ns_address, "--lease", "1", *extra])
    procs.append(proc)
    return address_of(line)


class Recorder:
    def __init__(self) -> None:
        self.values: list[int] = []
        self.gaps = []
        self.cond = threading.Condition()

    def __call__(self, event) -> None:
        with self.cond:
            self.values.append(event.value)

    def on_gap(self, gap) -> None:
        self.gaps.append(gap)

    def count(self) -> int:
        with self.cond:
            return len(self.values)


def test_deployer_killed_and_restarted_subscription_resumes(ns, procs) -> None:
    first = _deploy(procs, ns.address)
    with connect(ns.address, timeout=2.0, heartbeat_ms=200) as system:
        proxy = system.component("p")
        rec = Recorder()
        sub = proxy.subscribe("ticks", rec, on_gap=rec.on_gap)
        wait_until(lambda: rec.count() >= 5, timeout=10)
        procs[0].send_signal(signal.SIGKILL)
        procs[0].wait(timeout=10)
        wait_until(lambda: not sub.connected, timeout=10, message="the loss should be noticed")
        second = _deploy(procs, ns.address)  # a new process, on a new port, re-registers at once
        assert second != first
        wait_until(lambda: sub.gaps, timeout=15, message="the subscription should resume by itself")
        mark = rec.count()
        wait_until(lambda: rec.count() >= mark + 5, timeout=10)
        gap = sub.gaps[0]
        assert gap.duration > 0 and rec.gaps == [gap] and gap.restarted  # a new process: a new boot id
        assert rec.values[-1] < 1000  # counting again from the new process
        assert proxy.call("add", 1.0, 2.0) == 3.0  # unary calls re-resolve too
        assert system.components()[0].address == second


def test_restart_on_same_address_with_embedded_name_service(procs) -> None:
    address = f"127.0.0.1:{free_port()}"
    proc, _ = start_scart([*DEPLOY, "--listen", address])
    procs.append(proc)
    with connect(address, timeout=2.0, heartbeat_ms=200) as system:
        proxy = system.component("p")
        rec = Recorder()
        sub = proxy.subscribe("ticks", rec, on_gap=rec.on_gap)
        wait_until(lambda: rec.count() >= 3, timeout=10)
        stop_process(proc, signal.SIGTERM)
        wait_until(lambda: not sub.connected, timeout=10)
        proc, _ = start_scart([*DEPLOY, "--listen", address])
        procs.append(proc)
        wait_until(lambda: sub.gaps, timeout=15)
        mark = rec.count()
        wait_until(lambda: rec.count() >= mark + 3, timeout=10)
        assert proxy.write("input", 2.0).name == "WRITE_SUCCESS"


def test_frozen_deployer_detected_by_heartbeat_then_resumes(ns, procs) -> None:
    _deploy(procs, ns.address)
    with connect(ns.address, timeout=1.0, heartbeat_ms=200) as system:
        proxy = system.component("p")
        rec = Recorder()
        sub = proxy.subscribe("ticks", rec, on_gap=rec.on_gap)
        wait_until(lambda: rec.count() >= 3, timeout=10)
        procs[0].send_signal(signal.SIGSTOP)
        try:
            wait_until(lambda: not sub.connected, timeout=5, message="a frozen peer must be detected")
            with pytest.raises(RemoteTimeoutError, match="did not answer in time"):
                proxy.get_property("gain")  # every call has a deadline
            # its lease runs out: the name disappears instead of going stale
            client = NameClient(ns.address)
            try:
                wait_until(lambda: client.entries() == [], timeout=5)
            finally:
                client.close()
        finally:
            procs[0].send_signal(signal.SIGCONT)
        wait_until(lambda: sub.gaps, timeout=15, message="the subscription should resume after SIGCONT")
        mark = rec.count()
        wait_until(lambda: rec.count() >= mark + 3, timeout=10)
        gap = sub.gaps[0]
        # the freeze was noticed by the missing heartbeats (not a TCP error), and the gap is real
        assert "no heartbeat" in gap.reason, gap.reason
        assert gap.duration > 0 and rec.gaps == [gap]


def test_samples_lost_in_a_freeze_are_counted_exactly(ns, procs) -> None:
    """Every sample carries its port's write number: what a gap lost is counted in
    ``dropped``, exactly (the ticks are the write numbers, so the holes can be checked)."""
    _deploy(procs, ns.address)
    with connect(ns.address, timeout=1.0, heartbeat_ms=200) as system:
        rec = Recorder()
        sub = system.component("p").subscribe("ticks", rec, policy=ConnPolicy.buffer(10_000), on_gap=rec.on_gap)
        wait_until(lambda: rec.count() >= 3, timeout=10)
        procs[0].send_signal(signal.SIGSTOP)
        try:
            wait_until(lambda: not sub.connected, timeout=5, message="a frozen peer must be detected")
        finally:
            procs[0].send_signal(signal.SIGCONT)
        wait_until(lambda: sub.gaps, timeout=15, message="the subscription should resume after SIGCONT")
        mark = rec.count()
        wait_until(lambda: rec.count() >= mark + 10, timeout=10)
        sub.close()
        values = list(rec.values)
    missing = (values[-1] - values[0] + 1) - len(values)
    assert values == sorted(set(values)) and missing > 0, values
    assert sub.dropped == missing and not sub.gaps[0].restarted


def test_writer_survives_restart(ns, procs) -> None:
    _deploy(procs, ns.address)
    with connect(ns.address, timeout=2.0) as system:
        writer = system.component("p").connect_input("input")
        assert writer.write(1.0).name == "WRITE_SUCCESS"
        procs[0].send_signal(signal.SIGKILL)
        procs[0].wait(timeout=10)
        _deploy(procs, ns.address)
        assert writer.write(2.0).name == "WRITE_SUCCESS"
        writer.close()


@pytest.mark.parametrize("transport", ["ipc", "grpc"])
def test_subscriptions_sharing_a_stream_survive_a_freeze_each_counting_exactly(ns, procs, transport) -> None:
    """Two subscriptions alike share one stream: a frozen deployer is noticed by both,
    both resume after it, and each counts exactly what it missed."""
    _deploy(procs, ns.address)
    with connect(ns.address, timeout=1.0, heartbeat_ms=200) as system:
        proxy = system.component("p")
        policy = ConnPolicy.buffer(10_000).with_(transport=transport)
        recs = [Recorder(), Recorder()]
        subs = [proxy.subscribe("ticks", rec, policy=policy, on_gap=rec.on_gap) for rec in recs]
        assert sum(s.source == "p.ticks" for s in system.subscriptions()) == 1  # one stream
        wait_until(lambda: min(r.count() for r in recs) >= 3, timeout=10)
        procs[0].send_signal(signal.SIGSTOP)
        try:
            wait_until(lambda: not any(s.connected for s in subs), timeout=5, message="a frozen peer must be detected")
        finally:
            procs[0].send_signal(signal.SIGCONT)
        wait_until(lambda: all(s.gaps for s in subs), timeout=15, message="both should resume after SIGCONT")
        wait_until(lambda: sum(s.source == "p.ticks" for s in system.subscriptions()) == 1, timeout=10,
                   message="back on one stream")
        marks = [r.count() for r in recs]
        wait_until(lambda: all(r.count() >= m + 10 for r, m in zip(recs, marks, strict=True)), timeout=10)
        for sub in subs:
            sub.close()
    for rec, sub in zip(recs, subs, strict=True):
        values = list(rec.values)
        missing = (values[-1] - values[0] + 1) - len(values)
        assert values == sorted(set(values)) and missing > 0, values
        assert sub.dropped == missing and "no heartbeat" in sub.gaps[0].reason
