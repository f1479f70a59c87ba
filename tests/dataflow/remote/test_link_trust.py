"""Links between processes you can trust: every write delivered or counted (the sink's
buffer included), a link refused before anything is linked when its ends do not fit,
what holds said when a pair is connected again, a closing link delivering what waits,
and a link surviving either of its deployers restarting, with the writes missed across
the restart counted."""

from __future__ import annotations

import signal

import pytest
from support import wait_until
from support.remote import start_scart, stop_process

from dataflow import ConnPolicy, Deployer, OutputPort, TaskContext
from dataflow.remote import connect

SLOW = ["deploy", "support.remote:Slow", "--name", "slow", "--period", "0.01"]


class Source(TaskContext):
    out = OutputPort(int)


@pytest.fixture
def source():
    d = Deployer()
    src = d.add(Source("src"))
    server = d.serve("127.0.0.1:0")
    try:
        yield d, src, server
    finally:
        server.stop()


@pytest.mark.parametrize("transport", ["ipc", "grpc"])
def test_every_write_is_delivered_or_counted_with_a_slow_sink_in_another_process(source, transport) -> None:
    _, src, server = source
    sink, _ = start_scart([*SLOW, "--ns", server.address])
    try:
        with connect(server.address, timeout=5.0) as system:
            system.connect_ports("src.out", "slow.inp", ConnPolicy.buffer(20).with_(transport=transport), name="l")
            assert _link(system).transport == transport
            statuses = [src.out.write(k).name for k in range(608)]  # a burst: the sink's buffer overflows
            assert set(statuses) <= {"WRITE_SUCCESS", "WRITE_FAILURE"}  # a full buffer:20 refuses, as in one process
            slow = system.component("slow")
            wait_until(lambda: slow.call("seen") + _link(system).dropped == 608, timeout=20,
                       message=f"read {slow.call('seen')}, counted {_link(system)}")
            assert _link(system).dropped > 500  # the sink's buffer overflowed, and that shows at the source
            assert _link(system).dropped >= statuses.count("WRITE_FAILURE")
            assert system.disconnect_link("l")
    finally:
        stop_process(sink, signal.SIGKILL)


def _link(system, name: str = "l"):
    return next(lk for lk in system.links() if lk.name == name)


def test_a_link_whose_ends_do_not_fit_is_refused_with_the_composite_s_code(source) -> None:
    from support.cli import run

    _, _, server = source
    sink, _ = start_scart([*SLOW, "--ns", server.address])
    try:
        result = run("connect", "src.out", "slow.nope", "--ns", server.address)
        assert result.returncode == 1 and "slow has no port 'nope'" in result.stderr, result.stderr
        result = run("connect", "src.out", "slow.seen", "--ns", server.address)
        assert result.returncode == 1 and "slow has no port 'seen'" in result.stderr, result.stderr
        with connect(server.address, timeout=5.0) as system:
            assert system.links() == []  # nothing was linked
    finally:
        stop_process(sink, signal.SIGKILL)


def test_connecting_a_pair_again_says_what_holds(source) -> None:
    _, _, server = source
    sink, _ = start_scart([*SLOW, "--ns", server.address])
    try:
        with connect(server.address, timeout=5.0) as system:
            assert system.connect_ports("src.out", "slow.inp", ConnPolicy.buffer(8), name="first") == ""
            assert system.connect_ports("src.out", "slow.inp", ConnPolicy.buffer(8)) == "connected already"
            note = system.connect_ports("src.out", "slow.inp", ConnPolicy.circular_buffer(4))
            assert note == "policy changed from buffer:8 to circular:4"
            assert [(lk.name, lk.policy) for lk in system.links()] == [("first", "circular:4")]
            assert system.connect_ports("src.out", "slow.inp", ConnPolicy.circular_buffer(4), name="second") == \
                "renamed from first to second"
            assert [lk.name for lk in system.links()] == ["second"]
    finally:
        stop_process(sink, signal.SIGKILL)


def test_a_link_survives_its_sink_and_its_source_restarting_and_counts_the_gap() -> None:
    """The sink's deployer restarts: the source's link finds the new process. The source's
    restarts: the sink remembers the link and has the new source make it again; the writes
    the new source made before the link was back are counted as lost, not hidden."""
    from support.remote import address_of

    ns, line = start_scart(["nameserver", "--listen", "127.0.0.1:0"])
    address = address_of(line)
    source = ["deploy", "support.remote:Pinger", "--name", "src", "--period", "0.005", "--ns", address]
    sink = ["deploy", "support.remote:Tally", "--name", "tally", "--ns", address]
    procs = [ns]
    try:
        procs.append(start_scart(sink)[0])
        procs.append(start_scart(source)[0])
        with connect(address, timeout=5.0) as system:
            system.connect_ports("src.ticks", "tally.inp", ConnPolicy.buffer(1000), name="kept")
            tally = system.component("tally")
            wait_until(lambda: tally.call("seen") > 10, timeout=15, message="nothing crossed")
            procs[1].kill()  # the sink dies and comes back
            procs[1].wait(timeout=10)
            procs[1] = start_scart(sink)[0]
            wait_until(lambda: _count(system) > 10, timeout=20, message="the link never came back to the new sink")
            procs[2].kill()  # the source dies and comes back
            procs[2].wait(timeout=10)
            before = _count(system)
            procs[2] = start_scart(source)[0]
            wait_until(lambda: _count(system) > before + 10, timeout=20,
                       message="the sink never had the new source make the link again")
            link = wait_until(lambda: next((lk for lk in system.links() if lk.name == "kept" and lk.dropped), None),
                              timeout=10, message=f"the writes before the link was back were not counted: "
                                                  f"{system.links()}")
            assert link.transport == "ipc" and link.source == "src.ticks"
    finally:
        for proc in reversed(procs):
            stop_process(proc, signal.SIGKILL)


def _count(system) -> int:
    try:
        return system.component("tally").call("seen")
    except Exception:  # noqa: BLE001 - a process between its death and its return
        return -1
